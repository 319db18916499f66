"""The detail screen of one instrument or controller: identity and state, the settings form
(live parameters sent as set-points in a worker), and a live plot of each scalar stream."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from textual.app import ComposeResult
from textual.binding import Binding
from textual.screen import Screen
from textual.widgets import Header, Input, Static
from textual_plotext import PlotextPlot

from .forms import ParameterForm
from .ticks import set_ticks
from .widgets import KeysFooter

if TYPE_CHECKING:
    from .app import MirrorlabApp

#: Live plot refreshes per second (plotext redraws the whole plot).
PLOT_HZ = 4
#: Seconds of history shown in a live plot.
PLOT_SECONDS = 10.0


class StreamPlot(PlotextPlot):
    """The last :data:`PLOT_SECONDS` of one scalar stream (session time, s; the stream's unit)."""

    DEFAULT_CSS = "StreamPlot { height: 1fr; min-height: 6; }"

    def __init__(self, source: str, stream: str) -> None:
        super().__init__()
        self.source, self.stream = source, stream

    def redraw(self, times: list[float], values: list[float], unit: str) -> None:
        plt = self.plt
        plt.clear_data()
        plt.title(f"{self.source}/{self.stream}")
        plt.xlabel("session time (s)")
        plt.ylabel(unit or "value")
        if times:
            plt.plot(times, values, marker="braille", label=self.stream)
            set_ticks(plt, [times], [values])
        self.refresh()


class SourceScreen(Screen[None]):
    """``enter`` on a dashboard row: one instrument or controller in detail; esc goes back."""

    BINDINGS = [Binding("ctrl+o", "connection", "Connect/disconnect"), Binding("escape", "back", "Back")]
    DEFAULT_CSS = """
    #head { height: 2; padding: 0 1; background: $boost; }
    """

    app: MirrorlabApp

    def __init__(self, source: str) -> None:
        super().__init__()
        self.source = source

    def compose(self) -> ComposeResult:
        model = self.app.model
        session = model.session
        yield Header()
        yield Static(id="head", markup=False)
        inst = session.instruments.get(self.source)
        if inst is not None:
            yield ParameterForm(inst.parameters, inst.settings, set(inst.parameters.setpoints), id="form")
        else:
            controller = session.controllers[self.source].controller
            yield ParameterForm(controller.parameters, controller.settings, set(), id="form")
        for live_stream in model.source_streams(self.source):
            if live_stream.scalar:
                yield StreamPlot(self.source, live_stream.spec.name)
        yield KeysFooter()

    def on_mount(self) -> None:
        self.sub_title = self.source
        self.refresh_head()
        self.set_interval(1 / PLOT_HZ, self.refresh_plots)
        self.set_interval(0.25, self.refresh_head)
        self.refresh_plots()

    def refresh_head(self) -> None:
        snap = self.app.snapshot
        state = ""
        if snap is not None:
            item: Any = snap.instruments.get(self.source) or snap.controllers.get(self.source)
            state = f"state {item.state}" if item is not None else ""
        hint = ("enter on a live parameter sends it as a set-point, ctrl+o connects / disconnects"
                if self.app.model.live else "read-only")
        self.query_one("#head", Static).update(f"{self.source}: {self.app.model.identity(self.source)}\n"
                                               f"{state}   ({hint}; esc back)")

    def refresh_plots(self) -> None:
        for plot in self.query(StreamPlot):
            live = self.app.model.streams[(self.source, plot.stream)]
            times, values = list(live.times), list(live.values)
            if times:
                start = next((i for i, t in enumerate(times) if t >= times[-1] - PLOT_SECONDS), 0)
                times, values = times[start:], values[start:]
            plot.redraw(times, values, live.spec.unit)

    def on_input_submitted(self, event: Input.Submitted) -> None:
        name = (event.input.id or "").removeprefix("param-")
        if event.validation_result is not None and not event.validation_result.is_valid:
            self.app.notify("; ".join(event.validation_result.failure_descriptions), severity="error")
            return
        if not self.app.model.live:
            return
        value = event.value
        self.app.in_worker(f"set {self.source}.{name}",
                           lambda: self.app.model.set_parameter(self.source, name, value).wait(),
                           lambda applied: self.app.notify(f"{self.source}.{name} = {applied:g} acknowledged"
                                                           if isinstance(applied, float) else
                                                           f"{self.source}.{name} = {applied} acknowledged"))

    def action_connection(self) -> None:
        """Disconnect the instrument (it stops, its device is released), or connect it again."""
        if not self.app.model.live or self.source not in self.app.model.session.instruments:
            self.app.notify("Only an instrument of a live session connects and disconnects.", severity="warning")
        elif self.source in self.app.model.disconnected:
            self.app.action_connect(self.source)
        else:
            self.app.action_disconnect(self.source)

    def action_back(self) -> None:
        self.app.pop_screen()
