"""The plots screen: trajectories, velocities, joint angles and tracker angles of the session,
found by their units and shapes (never by the plugin that wrote them), drawn with
textual-plotext. The file is read in a worker thread.

Units: millimetres, radians shown in degrees, seconds (a recorded stream's session time) or
frames (an algorithm's output).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
from rich.text import Text
from textual.app import ComposeResult
from textual.binding import Binding
from textual.screen import Screen
from textual.widgets import Header, Select, Static
from textual_plotext import PlotextPlot

from . import browse
from .ticks import set_ticks
from .widgets import KeysFooter

if TYPE_CHECKING:
    from textual_plotext.plot import Plot

    from ..session import Session
    from .app import MirrorlabApp

#: The kinds of plot, in the order the screen lists them, and what makes each appear.
KINDS = {
    "trajectories": "run a reconstruction (a result in mm, (frames, markers, 3))",
    "velocities": "run derivatives on positions or angles (a result in mm/s or rad/s)",
    "joint angles": "run an angle algorithm (a result in rad)",
    "tracker angles": "record a tracker (a stream in rad)",
}
#: Points drawn per line (longer series are decimated evenly).
MAX_POINTS = 400
#: Lines drawn per plot (markers or components).
MAX_LINES = 6


@dataclass
class Series:
    """One plot: its kind, the dataset, axis labels and the lines (x, y, label)."""

    kind: str
    path: str
    xlabel: str
    ylabel: str
    lines: list[tuple[np.ndarray, np.ndarray, str]] = field(default_factory=list)


def kind_of(node: browse.Node) -> str | None:
    """Which kind of plot a dataset makes, from its path, unit and shape (``None``: none)."""
    shape, unit = node.shape, node.unit
    if len(shape) == 0 or shape[0] < 2:
        return None
    if node.path.startswith("/instruments/") and node.path.endswith("/data") and unit in ("rad", "deg"):
        return "tracker angles"
    if not node.path.startswith("/results/"):
        return None
    if unit == "mm" and len(shape) in (2, 3) and shape[-1] == 3:
        return "trajectories"
    if unit in ("mm/s", "rad/s"):
        return "velocities"
    if unit in ("rad", "deg") and len(shape) <= 2:
        return "joint angles"
    return None


def _thin(n: int) -> np.ndarray:
    return np.unique(np.linspace(0, n - 1, min(n, MAX_POINTS)).astype(int))


def load(session: Session, node: browse.Node, kind: str) -> Series:
    """The lines of one plot of ``kind`` from dataset ``node`` (reads the file)."""
    data = np.asarray(session.read(node.path), dtype=float)
    idx = _thin(data.shape[0])
    frames = idx.astype(float)
    if kind == "trajectories":  # the path of each marker in the x-y plane
        points = data[idx] if data.ndim == 3 else data[idx][:, None, :]
        series = Series(kind, node.path, "x (mm)", "y (mm)")
        for m in range(min(points.shape[1], MAX_LINES)):
            series.lines.append((points[:, m, 0], points[:, m, 1], f"marker {m}"))
        return series
    if kind == "tracker angles":
        times = np.asarray(session.read(node.path.rsplit("/", 1)[0] + "/time"), dtype=float)[: data.shape[0]]
        x, xlabel = times[idx], "session time (s)"
    else:
        x, xlabel = frames, "frame"
    values = data[idx].reshape(len(idx), -1)
    if kind == "velocities" and data.ndim == 3:  # (T, M, 3): the speed of each marker
        values = np.linalg.norm(data[idx], axis=-1)
    unit = node.unit
    if unit.startswith("rad"):
        values, unit = np.degrees(values), unit.replace("rad", "deg")
    series = Series(kind, node.path, xlabel, f"{node.name} ({unit})")
    for c in range(min(values.shape[1], MAX_LINES)):
        series.lines.append((x, values[:, c], f"{node.name}[{c}]" if values.shape[1] > 1 else node.name))
    return series


def draw(plt: Plot, series: Series) -> None:
    """Draw ``series`` on the plotext figure ``plt``, replacing what it showed (ticks: :mod:`.ticks`)."""
    plt.clear_data()
    plt.clear_figure()
    plt.title(f"{series.kind}: {series.path}")
    plt.xlabel(series.xlabel)
    plt.ylabel(series.ylabel)
    shown = []
    for x, y, label in series.lines:
        finite = np.isfinite(x) & np.isfinite(y)
        plt.plot(x[finite].tolist(), y[finite].tolist(), marker="braille", label=label)
        shown.append((x[finite], y[finite]))
    if shown:
        set_ticks(plt, [x for x, _ in shown], [y for _, y in shown])


class PlotsScreen(Screen[None]):
    """``g`` on the dashboard: pick a dataset in the list (by kind), see its plot; esc goes back."""

    BINDINGS = [Binding("f5", "reload", "Reload"), Binding("escape", "back", "Back")]
    DEFAULT_CSS = """
    PlotsScreen #status { height: 1; padding: 0 1; background: $boost; }
    PlotsScreen #plot { height: 1fr; }
    """

    app: MirrorlabApp

    def __init__(self) -> None:
        super().__init__()
        self.nodes: dict[str, tuple[browse.Node, str]] = {}
        self.shown: Series | None = None  # the plot on screen

    def compose(self) -> ComposeResult:
        yield Header()
        yield Static("reading the file…", id="status", markup=False)
        yield Select([], id="what", compact=True, prompt="(nothing to plot yet)")
        yield PlotextPlot(id="plot")
        yield KeysFooter()

    def on_mount(self) -> None:
        self.sub_title = "plots"
        self.action_reload()

    def action_reload(self) -> None:
        self.app.in_worker("read the session file", lambda: browse.datasets(self.app.model.session), self._fill, owner=self)

    def _fill(self, nodes: object) -> None:
        self.nodes = {}
        for node in nodes:  # type: ignore[attr-defined]
            kind = kind_of(node)
            if kind is not None:
                self.nodes[node.path] = (node, kind)
        order = list(KINDS)
        # by kind, then the longest series first (a reconstruction before a handful of surveyed points)
        found = sorted(self.nodes.items(), key=lambda item: (order.index(item[1][1]), -item[1][0].shape[0], item[0]))
        select = self.query_one("#what", Select)
        select.set_options([(f"{kind}: {path}", path) for path, (_, kind) in found])
        missing = [k for k in KINDS if k not in {kind for _, kind in self.nodes.values()}]
        status = "choose a dataset (enter)" if found else "nothing to plot yet"
        if missing:
            status += " · no " + "; no ".join(f"{k}: {KINDS[k]}" for k in missing)
        self.query_one("#status", Static).update(Text(status, overflow="ellipsis", no_wrap=True))
        if found:
            select.value = found[0][0]
        select.focus()

    def on_select_changed(self, event: Select.Changed) -> None:
        if isinstance(event.value, str) and event.value in self.nodes:
            node, kind = self.nodes[event.value]
            self.app.in_worker(f"read {node.path}", lambda: load(self.app.model.session, node, kind), self._draw, owner=self)

    def _draw(self, series: object) -> None:
        assert isinstance(series, Series)
        plot = self.query_one("#plot", PlotextPlot)
        draw(plot.plt, series)
        plot.refresh()
        self.shown = series

    def action_back(self) -> None:
        self.app.pop_screen()
