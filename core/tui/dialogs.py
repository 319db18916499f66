"""Modal screens: help, errors that say what to do, and the device-fault dialog with its countdown."""

from __future__ import annotations

from collections.abc import Callable

from rich.markup import escape
from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Vertical
from textual.screen import ModalScreen
from textual.widgets import Static

from ..devices import InstrumentState
from ..snapshot import InstrumentSnapshot

#: The dashboard's own keys, as the help shows them (the screens' keys are added by the app).
KEYS = (
    ("p", "preview: acquire, record nothing"),
    ("r", "start / stop recording"),
    ("s", "stop acquiring (a recording is written to the end)"),
    ("enter", "the selected instrument: settings, set-points, plots, connect"),
)
FOOTNOTE = """\
[b]esc[/b] back / close · [b]d[/b] light / dark theme · [b]ctrl+p[/b] every action
[b]ctrl+q[/b] quit: stops acquiring and closes the session file.
A device that drops out reconnects by itself; a dialog counts down."""


def help_text(screens: list[tuple[str, str]]) -> str:
    """The help: one line per key (the dashboard's and the screens'), then the common keys."""
    lines = ["[b]mirrorlab operator console[/b]", ""]
    lines += [f"[b]{escape(key):6s}[/b] {escape(what)}" for key, what in (*KEYS, *screens)]
    return "\n".join([*lines, "", FOOTNOTE])


class _Dialog(ModalScreen[None]):
    """A centred box with a title and a body; esc or enter closes it."""

    DEFAULT_CSS = """
    _Dialog { align: center middle; }
    _Dialog > Vertical { width: 72; max-width: 100%; height: auto; max-height: 100%;
                         border: thick $primary; background: $surface; padding: 0 1; }
    _Dialog .title { text-style: bold; margin-bottom: 1; }
    _Dialog.error > Vertical { border: thick $error; }
    _Dialog.warning > Vertical { border: thick $warning; }
    """
    BINDINGS = [Binding("escape", "close", "Close"), Binding("enter", "close", "Close", show=False)]

    def __init__(self, title: str, body: str, kind: str = "") -> None:
        super().__init__(classes=kind)
        self.title_text, self.body = title, body

    def compose(self) -> ComposeResult:
        with Vertical():
            yield Static(self.title_text, classes="title", markup=False)
            yield Static(self.body, id="body", markup=self.markup)

    markup = False

    def action_close(self) -> None:
        self.dismiss(None)


class HelpScreen(_Dialog):
    """The keys, on ``?``."""

    markup = True
    BINDINGS = [*_Dialog.BINDINGS, Binding("question_mark", "close", "Close", show=False)]

    def __init__(self, screens: list[tuple[str, str]]) -> None:
        super().__init__("Help", help_text(screens))


class ErrorDialog(_Dialog):
    """An error in plain words: what happened and what to do (never a traceback)."""

    def __init__(self, title: str, message: str, advice: str = "") -> None:
        super().__init__(title, message + (f"\n\n{advice}" if advice else "") + "\n\n(esc to close)", "error")


class FaultDialog(_Dialog):
    """A device that dropped out: its reconnect countdown, live, until it is back or has failed.

    ``watch()`` returns the instrument's newest snapshot; the dialog closes itself when the
    instrument acquires again.
    """

    def __init__(self, label: str, watch: Callable[[], InstrumentSnapshot | None]) -> None:
        super().__init__(f"{label}: connection lost", "", "warning")
        # not self.watch: that is Textual's DOMNode.watch, which this would hide
        self.label, self.newest = label, watch

    def on_mount(self) -> None:
        self.refresh_text()
        self.set_interval(0.25, self.refresh_text)

    def refresh_text(self) -> None:
        snap = self.newest()
        if snap is None or snap.state == InstrumentState.ACQUIRING:
            self.app.notify(f"{self.label} is back: reconnected, acquiring again")
            self.dismiss(None)
            return
        self.query_one("#body", Static).update(fault_text(snap))


def fault_text(snap: InstrumentSnapshot) -> str:
    """What the fault dialog says about an instrument that dropped out (or failed)."""
    if snap.state == InstrumentState.FAILED:
        return (f"{snap.label} ({snap.plugin}) has failed: {snap.error or 'no reason given'}.\n\n"
                "Check the cable and the power of the device, then press p to acquire again.\n\n(esc to close)")
    left = snap.reconnect_seconds_left
    budget = "trying until it answers" if left is None else f"{left:.0f} s left of its reconnect budget"
    return (f"{snap.label} ({snap.plugin}) stopped answering. Reconnecting: {budget}.\n\n"
            "Check the cable and the power of the device. It resumes by itself when it answers; "
            "the other instruments keep going.\n\n(esc to hide)")
