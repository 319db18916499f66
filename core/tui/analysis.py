"""The analysis screen: choose any registered algorithm, fill its generated form (inputs picked
from the session's datasets), run it in a worker with a progress bar, cancel it, and read the
stored result's datasets and provenance.

Algorithms come from the session's registry (every plugin, built-in or third-party, by itself);
the file is read and written only in worker threads.
"""

from __future__ import annotations

import json
from typing import TYPE_CHECKING, Any, cast

from rich.text import Text
from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Horizontal, VerticalScroll
from textual.screen import Screen
from textual.widgets import Header, Input, OptionList, ProgressBar, Select, Static
from textual.widgets.option_list import Option

from ..algorithms import Algorithm, Port, ResultRef
from . import browse
from .forms import ParameterForm, shown
from .widgets import KeysFooter

if TYPE_CHECKING:
    from ..recipes import Recipe
    from ..session import ResultData
    from .app import MirrorlabApp


#: Option ids of analysis recipes in the list start with this (algorithm names cannot contain it).
RECIPE = "recipe:"


def guess_input(port: Port, paths: list[str]) -> str | None:
    """The dataset an input most likely means: the newest result output of the same name, else a
    recorded stream of that name (``/instruments/<label>/<name>/data``), else none."""
    outputs = [p for p in paths if p.startswith("/results/") and p.rsplit("/", 1)[-1] == port.name]
    streams = [p for p in paths if p.endswith(f"/{port.name}/data")]
    found = outputs or streams
    return found[-1] if found else None


def result_text(result: ResultData) -> str:
    """A stored run as the operator reads it: status, outputs (shape, unit), provenance."""
    a = result.attrs
    lines = [f"{result.ref.path}: {a['status']}" + (f" — {a['error']}" if a.get("error") else ""), "", "outputs:"]
    lines += [f"  {name}  {value.shape} {value.dtype}" for name, value in result.outputs.items()] or ["  (none)"]
    lines += ["", f"provenance: {a.get('algorithm', '')} {a.get('plugin_version', '')}, "
                  f"{a.get('started_utc', '')} → {a.get('finished_utc', '')}",
              "inputs: " + json.dumps(a.get("inputs", {}), indent=1, sort_keys=True),
              "parameters: " + json.dumps(a.get("parameters", {}), indent=1, sort_keys=True, default=str)]
    return "\n".join(lines)


class AnalysisScreen(Screen[None]):
    """``a`` on the dashboard: enter picks an algorithm (or, at the end of the list, a bundled analysis
    recipe), ctrl+r runs it, x cancels, esc goes back."""

    BINDINGS = [Binding("ctrl+r", "run", "Run"), Binding("x", "cancel", "Cancel"), Binding("escape", "back", "Back")]
    DEFAULT_CSS = """
    AnalysisScreen #status { height: 1; padding: 0 1; background: $boost; }
    AnalysisScreen #progress { height: 1; padding: 0 1; }
    AnalysisScreen #algorithms { width: 26; height: 1fr; }
    AnalysisScreen #pane { width: 1fr; height: 1fr; padding: 0 1; }
    AnalysisScreen #about, AnalysisScreen #result { height: auto; }
    AnalysisScreen .port { color: $text-muted; }
    AnalysisScreen Select { margin-bottom: 0; }
    """

    app: MirrorlabApp

    def __init__(self) -> None:
        super().__init__()
        self.algorithm: type[Algorithm] | None = None  # the algorithm whose form is shown, or
        self.recipe: Recipe | None = None  # the analysis recipe chosen
        self.recipes: dict[str, Recipe] = {}  # option id → bundled analysis recipe
        self.paths: list[str] = []

    def compose(self) -> ComposeResult:
        registry = self.app.model.session.registry
        yield Header()
        yield Static(id="status", markup=False)
        yield ProgressBar(id="progress", show_eta=False)
        with Horizontal():
            yield OptionList(*(Option(name, id=name) for name in registry.names("algorithm")), id="algorithms")
            with VerticalScroll(id="pane"):
                yield Static("Choose an algorithm (↑ ↓, enter).", id="about", markup=False)
                yield Static(id="result", markup=False)
        yield KeysFooter()

    def on_mount(self) -> None:
        self.sub_title = "analysis"
        self.query_one("#algorithms", OptionList).focus()
        self.app.in_worker("read the session's datasets", self._datasets, self._got_datasets, owner=self)
        self.app.in_worker("read the analysis recipes", self.app.model.analysis_recipes, self._got_recipes, owner=self)
        self.refresh_status()
        self.set_interval(0.2, self.refresh_status)

    def _datasets(self) -> list[str]:
        return [n.path for n in browse.datasets(self.app.model.session)]

    def _got_datasets(self, paths: object) -> None:
        self.paths = list(paths)  # type: ignore[call-overload]

    def _got_recipes(self, recipes: object) -> None:
        self.recipes = {f"{RECIPE}{r.path.name}": r for r in recipes}  # type: ignore[attr-defined]
        self.query_one("#algorithms", OptionList).add_options(
            [Option(f"▸ {r.path.name}", id=key) for key, r in self.recipes.items()])

    # -- the form --------------------------------------------------------------------------------
    def on_option_list_option_highlighted(self, event: OptionList.OptionHighlighted) -> None:
        if self.algorithm is None and self.recipe is None:
            self.query_one("#about", Static).update(self.about(str(event.option.id)))

    def about(self, option: str) -> str:
        """What an entry of the list is: an algorithm's description, or a recipe's and its steps."""
        if option in self.recipes:
            recipe = self.recipes[option]
            steps = ", ".join(str(s.values.get("algorithm") or s.action) for s in recipe.steps)
            return (f"analysis recipe {recipe.path.name}: {recipe.description or '(no description)'}\n"
                    f"{len(recipe.steps)} steps: {steps}")
        cls = self.app.model.session.registry.algorithm(option)
        return f"{cls.name} {cls.version}: {cls.description}"

    async def on_option_list_option_selected(self, event: OptionList.OptionSelected) -> None:
        option = str(event.option.id)
        if option in self.recipes:
            await self.query_one("#pane", VerticalScroll).remove_children("Select, .port, ParameterForm")
            self.algorithm, self.recipe = None, self.recipes[option]
            self.query_one("#about", Static).update(self.about(option) + "\n\nctrl+r runs its steps on this session")
            self.query_one("#result", Static).update("")
        else:
            await self.show_form(option)

    async def show_form(self, name: str) -> None:
        """Replace the pane with the form of algorithm ``name``: one select per input, its parameters."""
        cls = self.app.model.session.registry.algorithm(name)
        self.algorithm, self.recipe = cls, None
        pane = self.query_one("#pane", VerticalScroll)
        await pane.remove_children("Select, .port, ParameterForm")
        self.query_one("#about", Static).update(f"{cls.name} {cls.version}: {cls.description}\n"
                                                 "inputs (datasets of the session), then parameters; ctrl+r runs")
        self.query_one("#result", Static).update("")
        widgets: list[Any] = []
        for port in cls.inputs:
            options = [(p, p) for p in self.paths]
            guess = guess_input(port, self.paths)
            widgets.append(Static(f"{port.name}{' (optional)' if port.optional else ''}: {port.description}",
                                  classes="port", markup=False))
            widgets.append(Select(options, id=f"input-{port.name}", compact=True, prompt="(none)",
                                  value=guess if guess is not None else Select.NULL))
        if len(cls.parameters):
            widgets.append(ParameterForm(cls.parameters, {}, {p.name for p in cls.parameters}, id="params"))
        await pane.mount_all(widgets, before=self.query_one("#result"))
        first = pane.query("Select, Input").first() if widgets else None
        if first is not None:
            first.focus()

    def form_values(self) -> tuple[dict[str, str], dict[str, Any]] | None:
        """The chosen inputs and the parameters the operator changed, or ``None`` after saying what is wrong."""
        assert self.algorithm is not None
        inputs: dict[str, str] = {}
        for port in self.algorithm.inputs:
            value = self.query_one(f"#input-{port.name}", Select).value
            if isinstance(value, str):
                inputs[port.name] = value
            elif not port.optional:
                self.app.notify(f"Choose a dataset for the input {port.name!r} ({port.description}).",
                                severity="error")
                return None
        params: dict[str, Any] = {}
        for p in self.algorithm.parameters:
            text = self.query_one(f"#param-{p.name}", Input).value
            if text == shown(p.default):
                continue  # untouched: the algorithm's default, stored as such
            value, reason = p.check(text)
            if reason is not None:
                self.app.notify(f"{p.name}: {reason}", severity="error")
                return None
            params[p.name] = value
        return inputs, params

    # -- running ---------------------------------------------------------------------------------
    def action_run(self) -> None:
        model = self.app.model
        if model.running is not None:
            self.app.notify(f"{model.running} is running; x cancels it.", severity="warning")
            return
        if self.recipe is not None:
            self.run_recipe(self.recipe)
            return
        if self.algorithm is None:
            self.app.notify("Choose an algorithm first (↑ ↓ and enter in the list).", severity="warning")
            return
        values = self.form_values()
        if values is None:
            return
        name = self.algorithm.name
        self.query_one("#result", Static).update(f"running {name}…")
        self.query_one("#algorithms", OptionList).focus()  # out of the form: x now cancels, not types
        self.app.in_worker(f"run {name}", lambda: self._run(name, *values), self._show_result, owner=self)

    def _run(self, name: str, inputs: dict[str, str], params: dict[str, Any]) -> tuple[ResultRef, str]:
        model = self.app.model
        ref = model.run_algorithm(name, inputs, params)
        return ref, result_text(model.session.result(ref))

    def run_recipe(self, recipe: Recipe) -> None:
        """Run an analysis recipe's steps in a worker; then list the results they stored."""
        model = self.app.model

        def work() -> str:
            before = {r.path for r in model.session.results()}
            model.run_recipe(recipe)
            new = [r for r in model.session.results() if r.path not in before]
            cancelled = " (cancelled: no later step ran)" if model.session.stop_requested else ""
            return "\n".join([f"{recipe.path.name}: {len(new)} results stored{cancelled}", "",
                              *(f"  {r.path}: {r.status}" for r in new),
                              "", "g shows their plots, b the file"])

        self.query_one("#result", Static).update(f"running {recipe.path.name}…")
        self.query_one("#algorithms", OptionList).focus()
        self.app.in_worker(f"run {recipe.path.name}", work, self._show_recipe_result, owner=self)

    def _show_recipe_result(self, text: object) -> None:
        result = self.query_one("#result", Static)
        result.update(str(text))
        result.scroll_visible()
        self.app.notify(str(text).splitlines()[0])
        self.app.in_worker("read the session's datasets", self._datasets, self._got_datasets, owner=self)

    def _show_result(self, outcome: object) -> None:
        ref, text = cast(tuple[ResultRef, str], outcome)  # what _run returns
        result = self.query_one("#result", Static)
        result.update(text)
        result.scroll_visible()
        self.app.notify(f"{ref.path}: {ref.status}", severity="information" if ref.status == "ok" else "warning")
        self.app.in_worker("read the session's datasets", self._datasets, self._got_datasets, owner=self)

    def refresh_status(self) -> None:
        model, bar = self.app.model, self.query_one("#progress", ProgressBar)
        if model.running is None:
            text = "enter: choose · ctrl+r: run · x: cancel · esc: back"
            bar.update(total=1, progress=0)  # still, until a run reports
        else:
            step = model.current_step
            text = f"running {model.running}" + (f" step {step.index}: {step.action}" if step else "") + " (x cancels)"
            progress = model.progress
            if progress is not None and (progress.source == model.running or step is not None):
                total = progress.data.get("total")
                bar.update(total=total if total else None, progress=float(progress.data.get("done", 0)))
                text += f": {progress.message}" if progress.message else ""
        self.query_one("#status", Static).update(Text(text, overflow="ellipsis", no_wrap=True))

    def action_cancel(self) -> None:
        if self.app.model.running is not None:
            self.app.model.cancel()
            self.app.notify("cancelling: the run stops at its next progress report and is stored as cancelled")

    def action_back(self) -> None:
        self.app.pop_screen()
