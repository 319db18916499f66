"""Typed parameters: the one declaration from which CLI options, recipe validation and TUI forms
are generated.

Every instrument setting, algorithm parameter and recipe-step option is a :class:`Parameter`.
A plugin declares them once::

    PARAMETERS = ParameterSet(
        Parameter("fps", float, default=30.0, unit="Hz", bounds=(0.1, 1000.0),
                  help="frames per second"),
        Parameter("source", str, default="fscan", choices=("fscan", "folder")),
    )

and :meth:`ParameterSet.validate` turns user input (TOML values, ``--set`` strings, form fields)
into typed values or a list of :class:`~mirrorlab.core.errors.Problem`.

Quantities with a unit accept a bare number (taken in the declared unit) or a string
``"<number> <unit>"`` in any unit of the same dimension (``"250 ms"`` for a parameter in ``s``).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from .errors import Problem, ValidationError

# Unit -> (dimension, factor to the dimension's base unit). Base units are mirrorlab's API units:
# mm, s, rad, Hz. Kept deliberately small: these are the units our instruments and recipes use.
_UNITS: dict[str, tuple[str, float]] = {
    "mm": ("length", 1.0),
    "um": ("length", 1e-3),
    "µm": ("length", 1e-3),
    "cm": ("length", 10.0),
    "m": ("length", 1000.0),
    "s": ("time", 1.0),
    "ms": ("time", 1e-3),
    "us": ("time", 1e-6),
    "min": ("time", 60.0),
    "rad": ("angle", 1.0),
    "deg": ("angle", math.pi / 180.0),
    "Hz": ("frequency", 1.0),
    "kHz": ("frequency", 1e3),
    "MHz": ("frequency", 1e6),
    "rad/s": ("angular_velocity", 1.0),
    "deg/s": ("angular_velocity", math.pi / 180.0),
}

_TYPE_NAMES = {int: "int", float: "float", bool: "bool", str: "str", Path: "path"}


def convert_unit(value: float, from_unit: str, to_unit: str) -> float:
    """Convert ``value`` from ``from_unit`` to ``to_unit`` (same dimension).

    Examples
    --------
    >>> convert_unit(250, "ms", "s")
    0.25
    """
    try:
        dim_a, fa = _UNITS[from_unit]
        dim_b, fb = _UNITS[to_unit]
    except KeyError as exc:
        raise ValueError(f"unknown unit {exc.args[0]!r}; known units: {', '.join(_UNITS)}") from None
    if dim_a != dim_b:
        raise ValueError(f"cannot convert {from_unit} ({dim_a}) to {to_unit} ({dim_b})")
    return value * fa / fb


@dataclass(frozen=True)
class Parameter:
    """Declaration of one typed parameter.

    Parameters
    ----------
    name
        Identifier (``snake_case``); also the recipe key and the CLI option ``--name``.
    type
        One of ``int``, ``float``, ``bool``, ``str``, ``pathlib.Path``.
    default
        Default value; ``None`` makes the parameter required.
    unit
        Unit of the value (``"mm"``, ``"s"``, ``"rad"``, ``"Hz"`` ...); ``""`` for dimensionless.
    bounds
        Inclusive ``(low, high)`` for numbers; either end may be ``None``.
    choices
        Allowed values (for ``str`` or ``int``).
    help
        One line shown in ``--help``, ``mirrorlab plugins show`` and TUI forms.
    live
        Settable while the instrument acquires, one value at a time, through
        :meth:`mirrorlab.core.devices.Instrument.set` (a set-point: a target angle, a gain);
        other settings change only through a full ``configure``.
    """

    name: str
    type: type = float
    default: Any = None
    unit: str = ""
    bounds: tuple[float | None, float | None] | None = None
    choices: tuple[Any, ...] | None = None
    help: str = ""
    live: bool = False

    def __post_init__(self) -> None:
        if self.type not in _TYPE_NAMES:
            raise TypeError(f"parameter {self.name!r}: unsupported type {self.type!r}")
        if self.unit and self.unit not in _UNITS:
            raise ValueError(f"parameter {self.name!r}: unknown unit {self.unit!r}")
        if self.default is not None:
            problem = self.check(self.default)[1]
            if problem:
                raise ValueError(f"parameter {self.name!r}: default {self.default!r} {problem}")

    @property
    def required(self) -> bool:
        return self.default is None

    @property
    def type_name(self) -> str:
        return _TYPE_NAMES[self.type]

    def check(self, value: Any) -> tuple[Any, str | None]:
        """Coerce ``value`` to this parameter's type and unit.

        Returns ``(value, None)`` on success or ``(None, reason)``.
        """
        try:
            coerced = self._coerce(value)
        except (TypeError, ValueError) as exc:
            return None, str(exc)
        if self.choices is not None and coerced not in self.choices:
            return None, f"must be one of {', '.join(map(str, self.choices))} (got {coerced!r})"
        if self.bounds is not None and self.type in (int, float):
            lo, hi = self.bounds
            unit = f" {self.unit}" if self.unit else ""
            if lo is not None and coerced < lo:
                return None, f"{coerced}{unit} is below the minimum {lo}{unit}"
            if hi is not None and coerced > hi:
                return None, f"{coerced}{unit} is above the maximum {hi}{unit}"
        return coerced, None

    def _coerce(self, value: Any) -> Any:
        t = self.type
        if t is bool:
            if isinstance(value, bool):
                return value
            if isinstance(value, str) and value.lower() in ("true", "yes", "on", "1"):
                return True
            if isinstance(value, str) and value.lower() in ("false", "no", "off", "0"):
                return False
            raise TypeError(f"expected true or false, got {value!r}")
        if t is str:
            if not isinstance(value, str):
                raise TypeError(f"expected a string, got {type(value).__name__} {value!r}")
            return value
        if t is Path:
            if not isinstance(value, (str, Path)):
                raise TypeError(f"expected a path, got {type(value).__name__} {value!r}")
            return Path(value)
        # Numbers: bare number in the declared unit, or "<number> <unit>".
        if isinstance(value, bool):
            raise TypeError(f"expected a number, got the boolean {value!r}")
        if isinstance(value, str):
            number = self._parse_quantity(value)
        elif isinstance(value, (int, float)):
            number = value
        else:
            raise TypeError(f"expected a number, got {type(value).__name__} {value!r}")
        if t is int:
            if isinstance(number, float) and not number.is_integer():
                raise TypeError(f"expected a whole number, got {number!r}")
            return int(number)
        if not math.isfinite(float(number)):
            raise ValueError(f"expected a finite number, got {number!r}")
        return float(number)

    def _parse_quantity(self, text: str) -> float:
        parts = text.split()
        try:
            number = float(parts[0]) if parts else float("nan")
        except ValueError:
            raise TypeError(f"expected a number, got {text!r}") from None
        if len(parts) == 1:
            return number
        if len(parts) != 2:
            raise TypeError(f"expected '<number> <unit>', got {text!r}")
        if not self.unit:
            raise ValueError(f"is dimensionless but was given the unit {parts[1]!r}")
        try:
            return convert_unit(number, parts[1], self.unit)
        except ValueError as exc:
            raise ValueError(f"wrong unit: {exc}") from None

    def describe(self) -> dict[str, Any]:
        """JSON-ready description (for ``mirrorlab plugins --json`` and TUI forms)."""
        return {
            "name": self.name,
            "type": self.type_name,
            "default": str(self.default) if isinstance(self.default, Path) else self.default,
            "unit": self.unit,
            "bounds": list(self.bounds) if self.bounds else None,
            "choices": list(self.choices) if self.choices else None,
            "help": self.help,
            "required": self.required,
            "live": self.live,
        }


@dataclass(frozen=True)
class ParameterSet:
    """An ordered, named collection of :class:`Parameter` declarations."""

    parameters: tuple[Parameter, ...] = field(default_factory=tuple)

    def __init__(self, *parameters: Parameter) -> None:
        names = [p.name for p in parameters]
        dupes = {n for n in names if names.count(n) > 1}
        if dupes:
            raise ValueError(f"parameter names declared twice: {', '.join(sorted(dupes))}")
        object.__setattr__(self, "parameters", tuple(parameters))

    def __iter__(self) -> Iterator[Parameter]:
        return iter(self.parameters)

    def __len__(self) -> int:
        return len(self.parameters)

    def __contains__(self, name: object) -> bool:
        return any(p.name == name for p in self.parameters)

    def __getitem__(self, name: str) -> Parameter:
        for p in self.parameters:
            if p.name == name:
                return p
        raise KeyError(name)

    def defaults(self) -> dict[str, Any]:
        return {p.name: p.default for p in self.parameters if not p.required}

    def problems(self, values: Mapping[str, Any], where: str = "",
                 file: str | None = None) -> tuple[dict[str, Any], list[Problem]]:
        """Validate ``values``; return the typed values (defaults filled in) and every problem.

        ``where`` is the key path prefix used in problem reports (``"instruments.cam.settings"``).
        """
        prefix = f"{where}." if where else ""
        out: dict[str, Any] = {}
        problems: list[Problem] = []
        known = {p.name for p in self.parameters}
        for key in values:
            if key not in known:
                hint = f"; known: {', '.join(sorted(known))}" if known else "; it takes none"
                problems.append(Problem(prefix + key, f"unknown parameter{hint}", file))
        for p in self.parameters:
            if p.name in values:
                value, reason = p.check(values[p.name])
                if reason:
                    problems.append(Problem(prefix + p.name, reason, file))
                else:
                    out[p.name] = value
            elif p.required:
                problems.append(Problem(prefix + p.name, f"required ({p.help or p.type_name})", file))
            else:
                out[p.name] = p.default
        return out, problems

    def validate(self, values: Mapping[str, Any], where: str = "", file: str | None = None) -> dict[str, Any]:
        """Like :meth:`problems` but raise :class:`~mirrorlab.core.errors.ValidationError`."""
        out, problems = self.problems(values, where, file)
        if problems:
            raise ValidationError(problems)
        return out

    def describe(self) -> list[dict[str, Any]]:
        return [p.describe() for p in self.parameters]

    def merged(self, other: Iterable[Parameter]) -> ParameterSet:
        """A new set with ``other``'s parameters appended (used to add common options)."""
        return ParameterSet(*self.parameters, *other)


def to_jsonable(values: Mapping[str, Any]) -> dict[str, Any]:
    """Parameter values with paths as strings, ready for ``json.dumps``."""
    return {k: str(v) if isinstance(v, Path) else v for k, v in values.items()}
