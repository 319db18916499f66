"""The console's dexterity task (``m``) of thesis §6.2.1 (spec ``analysis.md`` §5): move a segment
from vertical to horizontal with its end B on the x axis, sweeping as little area as possible.

The segment AB (length ``l``) starts vertical, A = (0, l), B = (0, 0); the task ends with A at the
origin and B = (−l, 0). The keys move B along the x axis and tilt the segment; every position is
added to the motion, and the area swept so far (the exact union of the regions between successive
positions, :func:`.swept.segment_swept_area`) is computed in a worker thread. For comparison: the
vertical wall's (astroid) area 3πl²/32 and the optimal wall's (:func:`.walls.optimal_wall`, computed
in a worker when the screen opens, on a coarse grid). Units: mm, mm².
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cache

import numpy as np
from mirrorlab.core.tui import LatestOnly
from rich.text import Text
from textual.app import ComposeResult
from textual.binding import Binding
from textual.screen import Screen
from textual.widgets import Footer, Header, Static
from textual_plotext import PlotextPlot

from .swept import segment_swept_area
from .walls import optimal_wall, wall_motion

#: Segment length, mm.
LENGTH = 300.0
#: One key press moves B by LENGTH / MOVES along x, or tilts the segment by TILT rad.
MOVES = 30
TILT = math.radians(3.0)
#: Optimal-wall solve for the comparison (thesis l = 3; areas scale with l²): grid, final grid, iterations.
OPTIMUM_GRID = (200, 400)
OPTIMUM_FINAL = (2000, 2000)
OPTIMUM_ITER = 100
#: Rod positions of the optimal motion drawn for comparison.
OPTIMUM_DRAWN = 13


@dataclass(frozen=True)
class Optimum:
    """The optimal wall's motion (positions of A and B, mm) and its swept area, mm²."""

    a: np.ndarray
    b: np.ndarray
    area: float


@cache
def optimum(length: float = LENGTH) -> Optimum:
    """The optimal wall of spec §6 on a coarse grid, scaled from the thesis's l = 3 to ``length`` mm
    (areas scale with the square: the problem is similar under scaling); computed once per process."""
    best = optimal_wall(grid=OPTIMUM_GRID, final=OPTIMUM_FINAL, maxiter=OPTIMUM_ITER)
    a, b = wall_motion(best.w, 3.0, OPTIMUM_DRAWN)
    s = length / 3.0
    return Optimum(a * s, b * s, best.area * s * s)


def swept(item: tuple[int, int, np.ndarray, np.ndarray]) -> tuple[int, int, float]:
    """``(motion, positions, area mm²)`` for ``(motion, positions, a, b)``: the area swept through the
    positions ``a``, ``b`` (k, 2) mm of a motion (numbered, so that a restarted motion is told apart)."""
    motion, k, a, b = item
    return motion, k, (segment_swept_area(a, b) if len(a) > 1 else 0.0)


class SweepPlot(PlotextPlot):
    """Every position of the segment so far, the present one, and the optimal motion's (mm)."""

    DEFAULT_CSS = "SweepPlot { height: 1fr; min-height: 8; }"

    def draw(self, a: np.ndarray, b: np.ndarray, best: Optimum | None, length: float) -> None:
        plt = self.plt
        plt.clear_data()
        plt.title("segment positions (B on the x axis)")
        plt.xlabel("x (mm)")
        plt.ylabel("y (mm)")
        plt.xlim(-1.2 * length, 0.4 * length)
        plt.ylim(-0.05 * length, 1.05 * length)
        if best is not None:
            for k in range(len(best.a)):
                plt.plot([best.b[k, 0], best.a[k, 0]], [best.b[k, 1], best.a[k, 1]], marker="braille", color="gray",
                         label="optimal wall's motion" if k == 0 else None)
        for k in range(len(a) - 1):
            plt.plot([b[k, 0], a[k, 0]], [b[k, 1], a[k, 1]], marker="braille", color="cyan",
                     label="your positions" if k == 0 else None)
        plt.plot([b[-1, 0], a[-1, 0]], [b[-1, 1], a[-1, 1]], marker="braille", color="red", label="segment now")
        self.refresh()


class DexterityScreen(Screen[None]):
    """``m`` on the dashboard: the swept-area dexterity task (thesis §6.2.1)."""

    BINDINGS = [
        Binding("left", "move(-1)", "B ←"),
        Binding("right", "move(1)", "B →"),
        Binding("down", "tilt(1)", "Lower A"),
        Binding("up", "tilt(-1)", "Raise A"),
        Binding("0", "restart", "Restart"),
        Binding("escape", "back", "Back"),
    ]
    DEFAULT_CSS = "#dex-status { height: 3; padding: 0 1; background: $boost; }"

    def __init__(self, length: float = LENGTH) -> None:
        super().__init__()
        self.length = length
        self.area_of: LatestOnly[tuple[int, int, np.ndarray, np.ndarray], tuple[int, int, float]] = LatestOnly(swept)
        self.best: Optimum | None = None
        self.motion = 0
        self._start()

    def _start(self) -> None:
        self.motion += 1
        self.area, self.area_positions = 0.0, 1   # the area of the first positions of this motion
        self.bx, self.phi = 0.0, 0.0          # B's abscissa, mm; the segment's angle from the vertical, rad
        self.a: list[tuple[float, float]] = []
        self.b: list[tuple[float, float]] = []
        self._add()

    def compose(self) -> ComposeResult:
        yield Header()
        yield Static(id="dex-status")
        yield SweepPlot(id="dex-plot")
        yield Footer()

    def on_mount(self) -> None:
        self.sub_title = "dexterity task (thesis §6.2.1)"
        self.run_worker(self._optimum, thread=True, group="optimum")
        self._redraw()

    # -- motion ----------------------------------------------------------------------------------
    @property
    def astroid_area(self) -> float:
        """Area of the vertical wall's motion, 3πl²/32, mm²."""
        return 3 * math.pi * self.length ** 2 / 32

    @property
    def done(self) -> bool:
        """A at the origin and B at (−l, 0): the task's end."""
        a = self.a[-1]
        return math.isclose(self.phi, math.pi / 2) and math.hypot(*a) < 1e-6 * self.length

    def _add(self) -> None:
        self.a.append((self.bx + self.length * math.sin(self.phi), self.length * math.cos(self.phi)))
        self.b.append((self.bx, 0.0))

    def action_move(self, sign: int) -> None:
        self.bx = round(self.bx / self.length * MOVES + sign) * self.length / MOVES
        self._step()

    def action_tilt(self, sign: int) -> None:
        self.phi = min(max(self.phi + sign * TILT, 0.0), math.pi / 2)
        self._step()

    def action_restart(self) -> None:
        self._start()
        self._redraw()

    def action_back(self) -> None:
        self.app.pop_screen()

    def _step(self) -> None:
        self._add()
        self.area_of.submit((self.motion, len(self.a), np.array(self.a), np.array(self.b)))
        self.run_worker(self._area, thread=True, group="swept")
        self._redraw()

    # -- workers ---------------------------------------------------------------------------------
    def _area(self) -> None:
        result = self.area_of.run_pending()
        if result is not None:
            self.app.call_from_thread(self._area_done, *result)

    def _area_done(self, motion: int, positions: int, area: float) -> None:
        if self.is_attached and motion == self.motion and positions >= self.area_positions:   # not a restarted motion's
            self.area, self.area_positions = area, positions
            self._show()

    def _optimum(self) -> None:
        best = optimum(self.length)
        self.app.call_from_thread(self._optimum_done, best)

    def _optimum_done(self, best: Optimum) -> None:
        self.best = best
        if self.is_attached:                   # not left meanwhile
            self._redraw()

    # -- display ---------------------------------------------------------------------------------
    def _redraw(self) -> None:
        self.query_one(SweepPlot).draw(np.array(self.a), np.array(self.b), self.best, self.length)
        self._show()

    def _show(self) -> None:
        a = self.a[-1]
        text = Text(no_wrap=True, overflow="ellipsis")
        text.append(f"A ({a[0]:6.1f}, {a[1]:6.1f}) mm  B ({self.bx:6.1f}, 0) mm  tilt {math.degrees(self.phi):4.1f}°  "
                    f"{len(self.a)} positions")
        pending = "" if self.area_positions == len(self.a) else " …"
        text.append(f"\nswept {self.area:9.0f} mm²{pending}", style="bold green" if self.done else "bold")
        best = f"{self.best.area:.0f}" if self.best is not None else "(computing…)"
        text.append(f"   vertical wall {self.astroid_area:.0f}   optimal wall {best} mm²")
        goal = "done: A at the origin, B at (−l, 0)" if self.done else "goal: A to the origin, B to (−l, 0)"
        text.append(f"\n{goal}   ←/→ move B, ↓/↑ lower/raise A, 0 restart")
        self.query_one("#dex-status", Static).update(text)
