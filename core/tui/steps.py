"""The recipe runner: the recipe's steps as a list; run from the selected one, see the running
step and its progress, cancel (``Session.request_stop``: the step ends cleanly, no later one runs)."""

from __future__ import annotations

from typing import TYPE_CHECKING

from rich.text import Text
from textual.app import ComposeResult
from textual.binding import Binding
from textual.screen import Screen
from textual.widgets import DataTable, Header, ProgressBar, Static

from .widgets import KeysFooter

if TYPE_CHECKING:
    from .app import MirrorlabApp
    from .model import Console


def step_summary(values: dict) -> str:
    """The step's table in one line: ``seconds=3``, ``algorithm=detect_markers``."""
    return ", ".join(f"{k}={v}" for k, v in values.items() if v not in ("", None, {}) and k != "parameters")


class StepsScreen(Screen[None]):
    """``t`` on the dashboard: the recipe's steps; enter runs from the selected one, x cancels."""

    BINDINGS = [Binding("enter", "run", "Run from here", priority=True), Binding("x", "cancel", "Cancel"),
                Binding("escape", "back", "Back")]
    DEFAULT_CSS = """
    #status { height: 2; padding: 0 1; background: $boost; }
    #steps { height: 1fr; }
    #progress { height: 1; padding: 0 1; }
    """

    app: MirrorlabApp

    @staticmethod
    def unavailable(model: Console) -> str:
        return "" if model.recipe is not None else "A session file has no recipe steps; open a recipe to run them."

    def compose(self) -> ComposeResult:
        yield Header()
        yield Static(id="status", markup=False)
        yield ProgressBar(id="progress", show_eta=False)
        yield DataTable(id="steps", cursor_type="row")
        yield KeysFooter()

    def on_mount(self) -> None:
        self.sub_title = "recipe steps"
        table = self.query_one("#steps", DataTable)
        table.add_column("#", width=3)
        table.add_column("action", width=14)
        table.add_column("what", width=54)
        recipe = self.app.model.recipe
        for step in recipe.steps if recipe is not None else []:
            table.add_row(str(step.index), step.action, step_summary(step.values), key=str(step.index))
        self.refresh_status()
        self.set_interval(0.2, self.refresh_status)

    def refresh_status(self) -> None:
        model = self.app.model
        step, progress = model.current_step, model.progress
        bar = self.query_one("#progress", ProgressBar)
        if step is None:
            text = "enter: run the steps from the selected one · x: cancel a running step · esc: back"
            bar.update(total=None, progress=0)
        else:
            text = f"running step {step.index}: {step.action} ({step_summary(step.values)})"
            if progress is not None:
                total = progress.data.get("total")
                bar.update(total=total if total else None, progress=float(progress.data.get("done", 0)))
        self.query_one("#status", Static).update(Text(text, overflow="ellipsis", no_wrap=True))

    def action_run(self) -> None:
        model = self.app.model
        if model.recipe is None or model.current_step is not None:
            return
        start = self.query_one("#steps", DataTable).cursor_row
        self.app.in_worker("run the recipe's steps", lambda: model.run_steps(start),
                           lambda _: self.app.notify("steps stopped on request" if model.session.stop_requested
                                                     else "steps done"))

    def action_cancel(self) -> None:
        if self.app.model.current_step is not None:
            self.app.model.cancel()
            self.app.notify("cancelling: the running step ends cleanly, no later step runs")

    def action_back(self) -> None:
        self.app.pop_screen()
