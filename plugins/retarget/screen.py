"""The console's virtual input chain (``v``; the retargeting paper's own input, spec §7).

The operator turns the joints of a planar n-DOF input chain with the keyboard; the retargeting
filter's compute module (:class:`.stream.Compute`, warm-started from the previous pose, multistart
on the first) approximates it by an m-DOF output chain in a worker thread,
the newest pose first (a pose overtaken while the worker computes is skipped, as the filter's input
buffer does). The plot shows both chains and the evaluation function f. Units: mm, rad; f in mm².
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from mirrorlab.core.tui import LatestOnly
from rich.text import Text
from textual.app import ComposeResult
from textual.binding import Binding
from textual.screen import Screen
from textual.widgets import Footer, Header, Static
from textual_plotext import PlotextPlot

from .chain import Chain
from .stream import Compute

#: Input chain: link lengths (mm); output chain: link lengths (mm). Planar chains (all axes z).
INPUT_LINKS = (100.0, 100.0, 100.0, 100.0)
OUTPUT_LINKS = (200.0, 200.0)
#: One key press turns the selected joint by this angle, rad.
STEP = math.radians(5.0)
#: Initial input angles, rad: a gentle curl, so the first pose is not a straight line.
START = (0.3, 0.4, 0.4, 0.4)


@dataclass(frozen=True)
class Retargeted:
    """One computed pose: its number, input angles (rad), input and output joints (mm), q (rad), f (mm²)."""

    pose: int
    angles: tuple[float, ...]
    inputs: np.ndarray
    outputs: np.ndarray
    q: np.ndarray
    f: float


class Retargeter:
    """The compute module behind the screen: one call per input pose, with the filter's state.

    Parameters
    ----------
    input_links, output_links : link lengths, mm (planar chains, axes z).
    """

    def __init__(self, input_links: tuple[float, ...] = INPUT_LINKS,
                 output_links: tuple[float, ...] = OUTPUT_LINKS) -> None:
        self.input = Chain(list(input_links), ["z"] * len(input_links))
        self.output = Chain(list(output_links), ["z"] * len(output_links))
        self.compute = Compute(self.output, self.input.lengths)

    def __call__(self, item: tuple[int, tuple[float, ...]]) -> Retargeted:
        """Retarget pose number ``item[0]`` with input angles ``item[1]`` (rad)."""
        pose, angles = item
        X = self.input.forward(np.asarray(angles)[None])[0]
        q, f, *_ = self.compute(X)
        return Retargeted(pose, angles, X, self.output.forward(q[None])[0] + X[0], q, f)


class ChainPlot(PlotextPlot):
    """The input chain and the retargeted output chain in the plane (mm)."""

    DEFAULT_CSS = "ChainPlot { height: 1fr; min-height: 8; }"

    def draw(self, result: Retargeted | None, reach: float) -> None:
        plt = self.plt
        plt.clear_data()
        plt.title("input chain and retargeted chain")
        plt.xlabel("x (mm)")
        plt.ylabel("y (mm)")
        plt.xlim(-reach, reach)
        plt.ylim(-reach, reach)
        if result is not None:
            plt.plot(result.inputs[:, 0].tolist(), result.inputs[:, 1].tolist(), marker="braille", color="cyan",
                     label=f"input ({len(result.angles)} DOF)")
            plt.plot(result.outputs[:, 0].tolist(), result.outputs[:, 1].tolist(), marker="braille", color="red",
                     label=f"output ({len(result.q)} DOF)")
            plt.scatter(result.inputs[:, 0].tolist(), result.inputs[:, 1].tolist(), marker="o", color="cyan")
            plt.scatter(result.outputs[:, 0].tolist(), result.outputs[:, 1].tolist(), marker="x", color="red")
        self.refresh()


class ChainScreen(Screen[None]):
    """``v`` on the dashboard: turn the joints of a virtual input chain, see it retargeted live."""

    BINDINGS = [
        Binding("left", "select(-1)", "Joint −"),
        Binding("right", "select(1)", "Joint +"),
        Binding("up", "turn(1)", "Turn +"),
        Binding("down", "turn(-1)", "Turn −"),
        Binding("0", "reset", "Reset"),
        Binding("escape", "back", "Back"),
    ]
    DEFAULT_CSS = "#chain-status { height: 3; padding: 0 1; background: $boost; }"

    def __init__(self, input_links: tuple[float, ...] = INPUT_LINKS,
                 output_links: tuple[float, ...] = OUTPUT_LINKS) -> None:
        super().__init__()
        self.retargeter = Retargeter(input_links, output_links)
        self.latest: LatestOnly[tuple[int, tuple[float, ...]], Retargeted] = LatestOnly(self.retargeter)
        self.reach = float(sum(input_links))
        self.angles = list(START[:len(input_links)]) + [0.0] * (len(input_links) - len(START))
        self.joint = 0
        self.pose = 0
        self.result: Retargeted | None = None

    def compose(self) -> ComposeResult:
        yield Header()
        yield Static(id="chain-status")
        yield ChainPlot(id="chain-plot")
        yield Footer()

    def on_mount(self) -> None:
        self.sub_title = "virtual input chain → retargeted chain"
        self._submit()

    # -- input -----------------------------------------------------------------------------------
    def action_select(self, step: int) -> None:
        self.joint = (self.joint + step) % len(self.angles)
        self._show()

    def action_turn(self, sign: int) -> None:
        self.angles[self.joint] += sign * STEP
        self._submit()

    def action_reset(self) -> None:
        self.angles = list(START[:len(self.angles)]) + [0.0] * (len(self.angles) - len(START))
        self._submit()

    def action_back(self) -> None:
        self.app.pop_screen()

    def _submit(self) -> None:
        self.pose += 1
        self.latest.submit((self.pose, tuple(self.angles)))
        self.run_worker(self._compute, thread=True, group="retarget", exclusive=False)
        self._show()

    # -- compute (worker thread) -----------------------------------------------------------------
    def _compute(self) -> None:
        result = self.latest.run_pending()
        if result is not None:
            self.app.call_from_thread(self._computed, result)

    def _computed(self, result: Retargeted) -> None:
        if self.is_attached and (self.result is None or result.pose > self.result.pose):
            self.result = result
            self.query_one(ChainPlot).draw(result, self.reach)
            self._show()

    def _show(self) -> None:
        text = Text(no_wrap=True, overflow="ellipsis")
        text.append("input angles (deg): ")
        for k, a in enumerate(self.angles):
            text.append(f"{math.degrees(a):6.1f}", style="bold reverse" if k == self.joint else "")
        r = self.result
        if r is None:
            text.append("\ncomputing…")
        else:
            text.append("\noutput q (deg):     " + "".join(f"{math.degrees(v):6.1f}" for v in r.q))
            lag = " …" if r.pose != self.pose else ""
            text.append(f"\nf = {r.f:.4g} mm²{lag}   ←/→ joint, ↑/↓ turn it 5°, 0 reset")
        self.query_one("#chain-status", Static).update(text)
