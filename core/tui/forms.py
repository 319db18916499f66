"""Forms generated from a :class:`~mirrorlab.core.params.ParameterSet`: one input per parameter,
labelled with its type, unit, bounds and help, validated by the parameter itself as the operator
types (so the form, the CLI and recipes never disagree)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from textual.app import ComposeResult
from textual.containers import VerticalScroll
from textual.validation import ValidationResult, Validator
from textual.widgets import Input, Static

from ..params import Parameter, ParameterSet


class ParameterValidator(Validator):
    """Validates an input's text with :meth:`Parameter.check` (units such as ``"5 deg"`` accepted)."""

    def __init__(self, parameter: Parameter) -> None:
        super().__init__()
        self.parameter = parameter

    def validate(self, value: str) -> ValidationResult:
        _, reason = self.parameter.check(value)
        return self.success() if reason is None else self.failure(f"{self.parameter.name}: {reason}")


def describe(parameter: Parameter) -> str:
    """``target · float rad · −3.14 … 3.14 · live — angle to move to`` (one label line)."""
    parts = [parameter.name, f"{parameter.type_name} {parameter.unit}".strip()]
    if parameter.bounds is not None:
        lo, hi = parameter.bounds
        parts.append(f"{'' if lo is None else f'{lo:g}'} … {'' if hi is None else f'{hi:g}'}".strip())
    if parameter.choices:
        parts.append("one of " + ", ".join(map(str, parameter.choices)))
    if parameter.live:
        parts.append("live")
    return " · ".join(parts) + (f" — {parameter.help}" if parameter.help else "")


def shown(value: Any) -> str:
    """A value as the form shows it (``""`` for none; floats to 6 significant digits)."""
    return "" if value is None else f"{value:.6g}" if isinstance(value, float) else str(value)


class ParameterForm(VerticalScroll):
    """One labelled input per parameter; only ``editable`` ones (e.g. the live ones) can be changed.

    Each input has the id ``param-<name>``; submitting a valid editable input posts
    :class:`Input.Submitted`, which the screen turns into an action (a set-point).
    """

    DEFAULT_CSS = """
    ParameterForm { height: auto; max-height: 12; }
    ParameterForm .label { color: $text-muted; }
    ParameterForm .problem { color: $error; height: auto; }
    ParameterForm Input { margin-bottom: 0; }
    """

    def __init__(self, parameters: ParameterSet, values: Mapping[str, Any], editable: set[str], **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self.parameters, self.values, self.editable = parameters, dict(values), editable

    def compose(self) -> ComposeResult:
        for p in self.parameters:
            yield Static(describe(p), classes="label", markup=False)
            yield Input(shown(self.values.get(p.name, p.default)), id=f"param-{p.name}", compact=True,
                        validators=[ParameterValidator(p)], disabled=p.name not in self.editable,
                        validate_on=["changed", "submitted"])
            yield Static("", id=f"problem-{p.name}", classes="problem", markup=False)

    def on_input_changed(self, event: Input.Changed) -> None:
        name = (event.input.id or "").removeprefix("param-")
        if name in self.parameters and event.validation_result is not None:
            problems = event.validation_result.failure_descriptions
            self.query_one(f"#problem-{name}", Static).update("; ".join(problems))
