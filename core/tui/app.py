"""The operator console: a Textual app over one :class:`~mirrorlab.core.tui.model.Console`.

The dashboard is the app's main screen. A timer polls the console at :data:`POLL_HZ` (a snapshot
and the live subscriptions, never a device or the file); actions that wait on devices or the
disk run in worker threads, and their errors become dialogs that say what to do. Every key's
action is also in the command palette (ctrl+p). The screens it opens are the core's
(:data:`~.screens.SCREENS`) and those the session's plugins register (``mirrorlab_register_screens``).
"""

from __future__ import annotations

import asyncio
from collections.abc import Callable, Iterable
from functools import partial
from typing import Any

from rich.text import Text
from textual.app import App, ComposeResult, SystemCommand
from textual.binding import Binding
from textual.renderables.sparkline import Sparkline
from textual.screen import Screen
from textual.widget import Widget
from textual.widgets import DataTable, Header, RichLog, Static

from ..cli.outputs import escaped
from ..errors import MirrorlabError
from ..events import Event
from ..registry import Registry
from ..snapshot import InstrumentSnapshot, SessionSnapshot
from .dialogs import ErrorDialog, FaultDialog, HelpScreen
from .model import Console
from .screens import SCREENS, ScreenEntry
from .widgets import KeysFooter

#: Dashboard refreshes per second.
POLL_HZ = 10
#: Redraws of the values, counters and sparklines per second (a poll is cheap, a redraw is not).
VIEW_HZ = 2
#: Samples a sparkline shows.
TREND_SAMPLES = 60
COLUMNS = ("source", "state", "value", "trend", "samples", "drops", "rec")
STATE_STYLE = {"acquiring": "green", "running": "green", "reconnecting": "bold yellow", "failed": "bold red",
               "connecting": "yellow"}
LEVEL_STYLE = {"warning": "bold yellow", "error": "bold red", "debug": "dim"}
#: What to do after an action failed, by the action's name.
ADVICE = {
    "record": "Nothing was lost: what was recorded is in the file. Check the instruments' states, then press r again.",
    "preview": "Check the instrument named above (cable, power, port), then press p again.",
    "stop": "Press s again; if an instrument does not stop, power-cycle it before using it again.",
}
#: The two built-in themes the ``d`` key switches between.
THEMES = ("textual-dark", "textual-light")


def plugin_screens(registry: Registry) -> tuple[list[ScreenEntry], list[str]]:
    """The screens the plugins register, by name, and why any could not be had (a broken plugin, a
    name two plugins register), one line each."""
    entries, problems = [], []
    for name in registry.names("screen"):
        try:
            entries.append(registry.get("screen", name))
        except MirrorlabError as exc:
            problems.append(f"screen {name!r}: {exc}")
    return entries, problems


def bound_keys(*classes: type) -> dict[str, str]:
    """Every key the ``BINDINGS`` of ``classes`` and their bases bind -> its description (or action)."""
    return {b.key: b.description or b.action for cls in classes for base in cls.__mro__
            for b in Binding.make_bindings(getattr(base, "BINDINGS", ()))}


def human_bytes(n: int) -> str:
    """``1536`` → ``1.5 kB`` (powers of 1000, as disk tools print)."""
    value = float(n)
    for unit in ("B", "kB", "MB", "GB"):
        if value < 1000 or unit == "GB":
            return f"{value:.0f} {unit}" if unit == "B" else f"{value:.1f} {unit}"
        value /= 1000
    return f"{value:.1f} TB"


class MirrorlabApp(App[int]):
    """``mirrorlab tui``: the dashboard of one session, and the screens it opens."""

    TITLE = "mirrorlab"
    CSS = """
    #info { height: 2; padding: 0 1; background: $boost; text-wrap: nowrap; text-overflow: ellipsis; }
    #sources { height: 1fr; min-height: 4; }
    #identity { height: 1; padding: 0 1; color: $text-muted; }
    #log { height: 7; border-top: solid $primary; }
    """
    BINDINGS = [
        Binding("question_mark", "help", "Help"),
        Binding("p", "preview", "Preview"),
        Binding("r", "record", "Record"),
        Binding("s", "stop", "Stop"),
        *(Binding(e.key, f"open_screen({e.name!r})", e.title) for e in SCREENS),  # the plugins' in __init__
        Binding("d", "toggle_theme", "Light / dark", show=False),
        Binding("ctrl+q", "quit", "Quit", priority=True),
    ]

    def __init__(self, model: Console, poll_hz: float = POLL_HZ) -> None:
        super().__init__()
        self.model = model
        self.poll_hz = poll_hz
        self.snapshot: SessionSnapshot | None = None
        self.close_error = ""
        self._quitting = False
        self._log_seen = 0
        self._faults: set[str] = set()  # instruments whose current fault has been shown
        self._recorder_error = ""
        self._polls = 0
        # the description and status of the file (a recipe's description is known without reading it)
        self._file_info = (model.recipe.description if model.recipe is not None else "(reading the session file…)", "")
        self._shown: dict[object, object] = {}  # what each Static / table cell shows now
        self.sub_title = model.session.path.name
        added, self.screen_problems = plugin_screens(model.session.registry)
        #: Every screen the dashboard opens: the core's, then the plugins' (by name).
        self.screens: list[ScreenEntry] = [*SCREENS, *added]
        #: The screens opened by a key (the others only from the palette).
        self.keyed: set[str] = {e.name for e in SCREENS}
        taken = bound_keys(type(self), DataTable)  # the sources table has the focus: its keys come first
        taken[self.COMMAND_PALETTE_BINDING] = "palette"
        for entry in added:
            if entry.key in taken:
                self.screen_problems.append(f"screen {entry.title!r}: the key {entry.key!r} is taken by "
                                            f"{taken[entry.key]!r}; open it from the palette (ctrl+p)")
            else:
                self.bind(entry.key, f"open_screen({entry.name!r})", description=entry.title)
                self.keyed.add(entry.name)
                taken[entry.key] = entry.title

    # -- layout ----------------------------------------------------------------------------------
    def compose(self) -> ComposeResult:
        yield Header()
        yield Static(id="info")
        table: DataTable = DataTable(id="sources", cursor_type="row", zebra_stripes=True)
        yield table
        yield Static(id="identity", markup=False)
        yield RichLog(id="log", max_lines=200, wrap=False, markup=False)
        yield KeysFooter()

    def on_mount(self) -> None:
        table = self.query_one("#sources", DataTable)
        for name, width in zip(COLUMNS, (10, 12, 12, 12, 7, 5, 3)):
            table.add_column(name, width=width, key=name)
        for source in self.model.sources:
            table.add_row(source, *[""] * (len(COLUMNS) - 1), key=source)
        self.in_worker("read the session file", self.model.session.describe, self._show_file_summary,
                       owner=self.screen)
        for problem in self.screen_problems:
            self.notify(problem, severity="warning", timeout=10)
        self.refresh_view()
        self.set_interval(1 / self.poll_hz, self.refresh_view)

    def _show_file_summary(self, info: object) -> None:
        """The file's description and status for the header; for a session file opened for
        browsing, its recorded streams and results in the log pane."""
        assert isinstance(info, dict)
        summary: dict[str, Any] = escaped(info)  # text of a file from another lab may hold terminal escapes
        attributes = summary["attributes"]
        self._file_info = (str(attributes.get("description", "")), str(attributes.get("status", "")))
        self._show("#info", self._info_text(self.snapshot))
        if self.model.live:
            return
        log = self.query_one("#log", RichLog)
        for label, inst in [*summary["instruments"].items(), *summary["controllers"].items()]:
            for name, st in inst["streams"].items():
                log.write(f"{label}/{name}: {st['samples']} samples {st['unit']}".rstrip())
        for r in summary["results"]:
            log.write(f"{r['path']}: {r['status']}")

    # -- refreshing ------------------------------------------------------------------------------
    def refresh_view(self) -> None:
        """Poll the console and update what changed (the timer calls this at ``poll_hz``).

        Faults are checked on every poll; values, counters and sparklines are redrawn at
        :data:`VIEW_HZ`, and only the cells and lines whose text changed, without a layout pass:
        redrawing the whole screen ten times a second kept the event loop from answering keys."""
        if self._quitting or self.query_one_optional("#sources") is None:  # quitting, or shutting down
            return
        snap = self.model.poll() if self.model.live else None
        self.snapshot = snap
        self._polls += 1
        if snap is not None:
            self._check_faults(snap)
        if self._polls % max(1, round(self.poll_hz / VIEW_HZ)) != 1 and self._polls > 1:
            return
        self._show("#info", self._info_text(snap))
        if snap is not None:
            self._update_table(snap)
        self._update_identity()
        self._update_log()

    def _show(self, selector: str, text: Text | str) -> None:
        """Update a fixed-size Static only if its text changed (no layout: its size does not change)."""
        if self._shown.get(selector) != text:
            self._shown[selector] = text
            self.query_one(selector, Static).update(text, layout=False)

    def _info_text(self, snap: SessionSnapshot | None) -> Text:
        description, status = self._file_info  # read once, in a worker: the loop never waits on the file
        text = Text(f"{description or '(no description)'}\n", overflow="ellipsis", no_wrap=True)
        if snap is None:
            text.append(f"session file, status {status}: a analysis, b browse, g plots", style="bold")
            return text
        if snap.recording:
            text.append(f"● RECORDING {snap.recording_seconds:5.1f} s", style="bold red")
        elif snap.acquiring:
            text.append("▶ acquiring (preview, not recorded)", style="bold green")
        else:
            text.append("■ idle: p preview, r record", style="bold")
        rec = snap.recorder
        text.append(f"   queue {rec.queue}/{rec.capacity}   written {human_bytes(rec.bytes_written)}")
        return text

    def _update_table(self, snap: SessionSnapshot) -> None:
        table = self.query_one("#sources", DataTable)
        for source in self.model.sources:
            inst = snap.instruments.get(source)
            ctrl = snap.controllers.get(source)
            state = inst.state if inst is not None else ctrl.state if ctrl is not None else "?"
            live = next(iter(self.model.source_streams(source)), None)
            if inst is not None:
                counts = (str(inst.samples), str(inst.dropped), str(inst.reconnects))
            else:
                counts = (str(ctrl.commands), str(ctrl.failed_commands), "") if ctrl is not None else ("", "", "")
            recent = tuple(live.values)[-TREND_SAMPLES:] if live is not None else ()
            cells = dict(zip(COLUMNS[1:], (Text(state, style=STATE_STYLE.get(state, "")),
                                           live.describe_latest() if live else "–",
                                           recent if len(recent) > 1 else (), *counts)))
            for column, value in cells.items():
                if self._shown.get((source, column)) == value:
                    continue
                self._shown[(source, column)] = value
                shown: object = value
                if column == "trend":  # value is recent, or () for fewer than two samples
                    shown = Sparkline(list(recent), width=12) if value else ""
                table.update_cell(source, column, shown)

    def _update_identity(self) -> None:
        table = self.query_one("#sources", DataTable)
        source = self.selected_source()
        line = "" if source is None else f"{source}: {self.model.identity(source)}"
        if source is not None and self.snapshot is not None:
            ctrl = self.snapshot.controllers.get(source)
            if ctrl is not None and ctrl.latency is not None:
                line += f" · latency p99 {1000 * ctrl.latency.p99:.1f} ms"
        if table.row_count:
            self._show("#identity", line)

    def _update_log(self) -> None:
        events, self._log_seen = self.model.events_since(self._log_seen)
        if events:
            log = self.query_one("#log", RichLog)
            for event in events:
                log.write(log_line(event))

    def _check_faults(self, snap: SessionSnapshot) -> None:
        """Open the fault dialog once per drop-out; the recorder's error once per recording."""
        for label, inst in snap.instruments.items():
            if inst.state in ("reconnecting", "failed") and label not in self._faults:
                self._faults.add(label)
                self.push_screen(FaultDialog(label, partial(self._instrument_snapshot, label)))
            elif inst.state == "acquiring":
                self._faults.discard(label)
        error = snap.recorder.error
        if error and error != self._recorder_error:
            self._recorder_error = error
            self.show_error("Recording failed", f"The recorder could not write the file: {error}",
                            "What was written before is kept. Free disk space (or choose another --out), "
                            "then press r to record again.")

    def _instrument_snapshot(self, label: str) -> InstrumentSnapshot | None:
        return None if self.snapshot is None else self.snapshot.instruments.get(label)

    def selected_source(self) -> str | None:
        table = self.query_one("#sources", DataTable)
        if not table.row_count:
            return None
        return self.model.sources[min(table.cursor_row, table.row_count - 1)]

    # -- actions ---------------------------------------------------------------------------------
    def show_error(self, title: str, message: str, advice: str = "") -> None:
        self.push_screen(ErrorDialog(title, message, advice))

    def in_worker(self, what: str, fn: Callable[[], object], done: Callable[[object], None] | None = None,
                  owner: Widget | None = None) -> None:
        """Run ``fn`` in a worker thread; an error becomes a dialog naming ``what`` failed.

        ``done(result)`` runs on the event loop after success, unless ``owner`` (the screen that
        asked) has been closed meanwhile."""
        def work() -> None:
            try:
                result = fn()
            except MirrorlabError as exc:
                self.call_from_thread(self.show_error, f"Could not {what}", str(exc), ADVICE.get(what, ""))
            except Exception as exc:  # a driver bug: still a message, never a traceback on screen
                self.call_from_thread(self.show_error, f"Could not {what}", f"{type(exc).__name__}: {exc}",
                                      ADVICE.get(what, ""))
            else:
                if done is not None:
                    self.call_from_thread(self._done, done, result, owner)
        self.run_worker(work, thread=True, group="actions", name=what)

    @staticmethod
    def _done(done: Callable[[object], None], result: object, owner: Widget | None) -> None:
        if owner is None or owner.is_attached:
            done(result)

    def _require_live(self) -> bool:
        if not self.model.live:
            self.notify("This session file is open for browsing; open a recipe to acquire and record.",
                        severity="warning")
        return self.model.live

    def action_help(self) -> None:
        self.push_screen(HelpScreen([(e.key if e.name in self.keyed else "ctrl+p", e.help) for e in self.screens]))

    def action_preview(self) -> None:
        if self._require_live():
            self.in_worker("preview", self.model.preview)

    def action_record(self) -> None:
        if self._require_live():
            self.in_worker("record", self.model.toggle_recording,
                           lambda recording: self.notify("recording" if recording else "recording stopped and written"))

    def action_stop(self) -> None:
        if self._require_live():
            self.in_worker("stop", self.model.stop)

    def action_open_screen(self, name: str) -> None:
        """Open one of :attr:`screens` (by name), or say why it cannot open now."""
        entry = next(e for e in self.screens if e.name == name)
        try:
            cls = entry.load()
        except Exception as exc:  # the plugin's screen module is broken: a message, the console goes on
            self.show_error(f"Could not open {entry.title}", f"{entry.target}: {type(exc).__name__}: {exc}",
                            "The plugin that provides this screen is broken; `mirrorlab plugins doctor` says more.")
            return
        unavailable = getattr(cls, "unavailable", None)
        reason = unavailable(self.model) if unavailable is not None else ""
        if reason:
            self.notify(reason, severity="warning")
        else:
            self.push_screen(cls())

    def action_connect(self, source: str) -> None:
        if self._require_live():
            self.in_worker(f"connect {source}", partial(self.model.connect, source),
                           lambda _: self.notify(f"{source} connected; p starts it acquiring"))

    def action_disconnect(self, source: str) -> None:
        if self._require_live():
            self.in_worker(f"disconnect {source}", partial(self.model.disconnect, source),
                           lambda _: self.notify(f"{source} disconnected; ctrl+o in its detail connects it again"))

    def action_toggle_theme(self) -> None:
        """Switch between the light and the dark theme."""
        self.theme = THEMES[1] if self.theme == THEMES[0] else THEMES[0]
        self.notify(f"theme {self.theme}")

    def action_open_source(self, source: str) -> None:
        from .detail import SourceScreen

        self.push_screen(SourceScreen(source))

    def on_data_table_row_highlighted(self, event: DataTable.RowHighlighted) -> None:
        if event.data_table.id == "sources" and event.data_table.is_attached:  # not another screen's table
            self._update_identity()

    def on_data_table_row_selected(self, event: DataTable.RowSelected) -> None:
        if event.data_table.id == "sources" and event.row_key.value is not None:
            self.action_open_source(str(event.row_key.value))

    def quit_on_signal(self, name: str) -> None:
        """SIGTERM or SIGHUP (``kill``, a closed terminal or SSH session): quit as ctrl+q does, the session
        file closed cleanly. Called in the signal handler, in the thread of the app's event loop."""
        try:
            loop = asyncio.get_running_loop()
        except RuntimeError:  # the console is not running (yet, or any more): its caller closes the session
            raise KeyboardInterrupt from None
        loop.call_soon_threadsafe(self.call_later, self.action_quit)

    async def action_quit(self) -> None:
        """Stop acquiring and close the session file (in a thread: the screen stays alive), then exit."""
        if self._quitting:
            return
        self._quitting = True
        self.notify("closing the session…")
        try:
            await asyncio.to_thread(self.model.close)
        except Exception as exc:  # e.g. the recorder failed: the file is closed aborted
            self.close_error = str(exc) if isinstance(exc, MirrorlabError) else f"{type(exc).__name__}: {exc}"
        self.exit(1 if self.close_error else 0)

    def get_system_commands(self, screen: Screen) -> Iterable[SystemCommand]:
        yield SystemCommand("Help", "the keys and what they do (?)", self.action_help)
        yield SystemCommand("Preview", "acquire without recording (p)", self.action_preview)
        yield SystemCommand("Record", "start or stop recording every instrument (r)", self.action_record)
        yield SystemCommand("Stop", "stop acquiring; a recording is written to the end (s)", self.action_stop)
        for source in self.model.session.instruments if self.model.live else ():
            yield SystemCommand(f"Connect {source}", f"connect {source} again (ctrl+o in its detail)",
                                partial(self.action_connect, source))
            yield SystemCommand(f"Disconnect {source}", f"stop {source} and release its device (ctrl+o in its detail)",
                                partial(self.action_disconnect, source))
        for e in self.screens:
            keyed = f" ({e.key})" if e.name in self.keyed else ""
            yield SystemCommand(e.title, f"{e.help}{keyed}", partial(self.action_open_screen, e.name))
        yield SystemCommand("Light / dark", "switch between the light and the dark theme (d)", self.action_toggle_theme)
        for source in self.model.sources:
            yield SystemCommand(f"Open {source}", f"settings, set-points and live plots of {source} (enter)",
                                partial(self.action_open_source, source))
        yield SystemCommand("Quit", "stop acquiring, close the session file and leave (ctrl+q)", self.action_quit)
        yield from (c for c in super().get_system_commands(screen) if c.title not in ("Quit",))


def log_line(event: Event) -> Text:
    """One log tail line: session time, source, message; warnings and errors highlighted."""
    return Text(f"{event.t:8.2f}  {event.source}: {event.message}", style=LEVEL_STYLE.get(event.level, ""))
