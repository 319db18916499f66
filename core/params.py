"""Typed parameters: the one declaration from which CLI options, recipe validation and TUI forms
are generated.

Every instrument setting, algorithm parameter and recipe-step option is a :class:`Parameter`.
A plugin declares them once::

    PARAMETERS = ParameterSet(
        Parameter("fps", float, default=30.0, unit="Hz", bounds=(0.1, 1000.0),
                  help="frames per second"),
        Parameter("source", str, default="fscan", choices=("fscan", "folder")),
        Parameter("camera_center", float, shape=(3,), unit="mm", help="camera centre x, y, z"),
    )

and :meth:`ParameterSet.validate` turns user input (TOML values, ``--set`` strings, form fields)
into typed values or a list of :class:`~mirrorlab.core.errors.Problem`.

**Units.** A unit is any unit `pint <https://pint.readthedocs.io>`_ understands (``"m/s"``,
``"dB"``, ``"V"``, ``"%"``, ``"degC"``); mirrorlab's API units are mm, s, rad and Hz. Quantities
accept a bare number (taken in the declared unit) or a string ``"<number> <unit>"`` in any unit of
the same dimension (``"250 ms"`` for a parameter in ``s``, ``"68 degF"`` for one in ``degC``), and
the plugin always receives the value in its declared unit. Conversions between the common units
(:data:`_UNITS`) need no import; pint is imported on first use of any other unit.

**Vectors.** ``shape=(3,)`` makes a parameter an array of ``int`` or ``float`` (``None`` in a shape
is any length: ``shape=(None, 3)`` for a list of points). It accepts a TOML array
(``[435.7, 202.6, 1442.0]``, elements may carry units: ``["0.4 m", "0.2 m", "1.4 m"]``) or a string
(``"435.7, 202.6, 1442.0"``; rows separated by ``;``; one unit for all in brackets:
``"[0.4, 0.2, 1.4] m"``). The value is a tuple (of tuples), bounds apply to every element, and a
wrong length is a problem naming the key, found when a recipe is loaded.
"""

from __future__ import annotations

import functools
import math
import re
from collections.abc import Iterable, Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from .errors import Problem, ValidationError

# Unit -> (dimension, factor to the dimension's base unit). Base units are mirrorlab's API units:
# mm, s, rad, Hz. The units our instruments and recipes use most, converted without importing pint
# (whose import and unit registry cost about a second, too much for CLI start-up).
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

#: What a label that becomes an HDF5 group name (an instrument's, a controller's, an imported marker
#: set's) must be: one path component, never ``/``, ``.``, ``..``, empty or with control characters.
IDENTIFIER = re.compile(r"[A-Za-z_][A-Za-z0-9_-]*")
#: C0 and C1 control characters (ESC, NUL, newline, DEL...): never in text a user types for the file.
_CONTROL = re.compile(r"[\x00-\x1f\x7f-\x9f]")


def identifier_problem(text: object) -> str | None:
    """Why ``text`` cannot name an HDF5 group of the session (``None`` if it can).

    >>> identifier_problem("cam_1") is None
    True
    >>> identifier_problem("/truth/fake")
    "'/truth/fake' is not a label: use a letter or '_', then letters, digits, '_' or '-' (e.g. 'cam_1')"
    """
    if isinstance(text, str) and IDENTIFIER.fullmatch(text):
        return None
    return f"{text!r} is not a label: use a letter or '_', then letters, digits, '_' or '-' (e.g. 'cam_1')"


def control_problem(text: str) -> str | None:
    """Why ``text`` cannot be stored as free text (``None`` if it can): a control character, which
    would move the cursor or recolour the terminal of whoever prints it.

    >>> control_problem("ana") is None
    True
    >>> print(control_problem("a" + chr(27) + "[2Jb"))
    holds the control character '\\x1b' at character 2; write plain text
    """
    found = _CONTROL.search(text)
    if found is None:
        return None
    return f"holds the control character {found.group()!r} at character {found.start() + 1}; write plain text"


@functools.cache
def _pint() -> Any:
    """The one pint unit registry of the process (imported on first use)."""
    import pint

    return pint.UnitRegistry(autoconvert_offset_to_baseunit=True)


def check_unit(unit: str) -> None:
    """Raise ``ValueError`` unless ``unit`` is ``""`` (dimensionless) or a unit pint understands.

    Examples
    --------
    >>> check_unit("m/s")
    >>> check_unit("bogons/s")
    Traceback (most recent call last):
    ...
    ValueError: unknown unit 'bogons/s' (pint: 'bogons' is not defined in the unit registry)
    """
    if not unit or unit in _UNITS:
        return
    try:
        _pint().parse_units(unit)
    except Exception as exc:  # pint's parser raises many kinds on malformed text (even AssertionError)
        raise ValueError(f"unknown unit {unit!r} (pint: {exc or 'not a unit expression'})") from None


def convert_unit(value: float, from_unit: str, to_unit: str) -> float:
    """Convert ``value`` from ``from_unit`` to ``to_unit`` (same dimension; offsets such as degC included).

    Examples
    --------
    >>> convert_unit(250, "ms", "s")
    0.25
    >>> round(convert_unit(68, "degF", "degC"), 9)
    20.0
    """
    if from_unit in _UNITS and to_unit in _UNITS:
        (dim_a, fa), (dim_b, fb) = _UNITS[from_unit], _UNITS[to_unit]
        if dim_a != dim_b:
            raise ValueError(f"cannot convert {from_unit} ({dim_a}) to {to_unit} ({dim_b})")
        return value * fa / fb
    check_unit(from_unit)
    check_unit(to_unit)
    import pint

    ureg = _pint()
    try:
        return float(ureg.Quantity(value, from_unit).to(to_unit).magnitude)
    except pint.errors.DimensionalityError:
        dim_a, dim_b = (ureg.parse_units(u).dimensionality for u in (from_unit, to_unit))
        raise ValueError(f"cannot convert {from_unit} ({dim_a}) to {to_unit} ({dim_b})") from None


@dataclass(frozen=True)
class Parameter:
    """Declaration of one typed parameter.

    Parameters
    ----------
    name
        Identifier (``snake_case``); also the recipe key and the CLI option ``--name``.
    type
        One of ``int``, ``float``, ``bool``, ``str``, ``pathlib.Path``; the element type of a vector.
    default
        Default value; ``None`` makes the parameter required.
    unit
        Unit of the value, any unit pint understands (``"mm"``, ``"s"``, ``"rad"``, ``"Hz"``,
        ``"m/s"``, ``"degC"`` ...); ``""`` for dimensionless. Values given in another unit of the
        same dimension are converted into this one.
    bounds
        Inclusive ``(low, high)`` for numbers (every element of a vector); either end may be ``None``.
    choices
        Allowed values (for ``str`` or ``int``).
    help
        One line shown in ``--help``, ``mirrorlab plugins show`` and TUI forms.
    live
        Settable while the instrument acquires, one value at a time, through
        :meth:`mirrorlab.core.devices.Instrument.set` (a set-point: a target angle, a gain);
        other settings change only through a full ``configure``.
    shape
        Makes the parameter an array of ``int`` or ``float`` of this shape (``(3,)``: a point;
        ``(None, 3)``: any number of points); the value is a tuple (of tuples).
    path
        The value names a file or folder (a ``str``; type ``pathlib.Path`` implies it): a recipe
        resolves a relative one against the recipe's own folder, whatever the working folder
        (:func:`mirrorlab.core.recipes.load_recipe`); elsewhere it is used as given.
    output
        ``"file"`` or ``"folder"`` if the value names a file or folder written to (implies ``path``):
        a recipe may name one only inside its own folder or the session file's, and an existing
        file (a folder holding files) only with ``--overwrite``
        (:func:`mirrorlab.core.recipes.output_problems`).

    Examples
    --------
    >>> centre = Parameter("camera_center", float, shape=(3,), unit="mm")
    >>> centre.check("[0.4, 0.2, 1.4] m")
    ((400.0, 200.0, 1400.0), None)
    >>> centre.check([1, 2])[1]
    'expected 3 values (float[3] in mm), got 2: [1, 2]'
    """

    name: str
    type: type = float
    default: Any = None
    unit: str = ""
    bounds: tuple[float | None, float | None] | None = None
    choices: tuple[Any, ...] | None = None
    help: str = ""
    live: bool = False
    shape: tuple[int | None, ...] | None = None
    path: bool = False
    output: str = ""

    def __post_init__(self) -> None:
        if self.type not in _TYPE_NAMES:
            raise TypeError(f"parameter {self.name!r}: unsupported type {self.type!r}")
        if self.output not in ("", "file", "folder"):
            raise ValueError(f"parameter {self.name!r}: output must be 'file' or 'folder', not {self.output!r}")
        if self.output:
            object.__setattr__(self, "path", True)
        if self.type is Path:
            object.__setattr__(self, "path", True)
        elif self.path and self.type is not str:
            raise TypeError(f"parameter {self.name!r}: path=True needs type str or pathlib.Path, not {self.type_name}")
        if self.shape is not None:
            object.__setattr__(self, "shape", tuple(self.shape))
            if self.type not in (int, float):
                raise TypeError(f"parameter {self.name!r}: a shape needs type int or float, not {self.type_name}")
            if not self.shape or not all(n is None or (isinstance(n, int) and n > 0) for n in self.shape):
                raise ValueError(f"parameter {self.name!r}: shape must be positive lengths or None, got {self.shape!r}")
            if self.choices is not None:
                raise ValueError(f"parameter {self.name!r}: choices do not apply to a vector")
        try:
            check_unit(self.unit)
        except ValueError as exc:
            raise ValueError(f"parameter {self.name!r}: {exc}") from None
        if self.default is not None:
            value, problem = self.check(self.default)
            if problem:
                raise ValueError(f"parameter {self.name!r}: default {self.default!r} {problem}")
            if self.shape is not None:  # a list default becomes the (hashable) tuple every value is
                object.__setattr__(self, "default", value)

    @property
    def required(self) -> bool:
        return self.default is None

    @property
    def type_name(self) -> str:
        """``float``, or with a shape ``float[3]`` / ``float[N,3]``."""
        base = _TYPE_NAMES[self.type]
        if self.shape is None:
            return base
        return f"{base}[{','.join('N' if n is None else str(n) for n in self.shape)}]"

    def check(self, value: Any) -> tuple[Any, str | None]:
        """Coerce ``value`` to this parameter's type, shape and unit.

        Returns ``(value, None)`` on success or ``(None, reason)``.
        """
        try:
            coerced = self._coerce(value) if self.shape is None else self._coerce_array(value)
        except (TypeError, ValueError) as exc:
            return None, str(exc)
        if self.choices is not None and coerced not in self.choices:
            return None, f"must be one of {', '.join(map(str, self.choices))} (got {coerced!r})"
        if self.bounds is not None and self.type in (int, float):
            lo, hi = self.bounds
            unit = f" {self.unit}" if self.unit else ""
            flat: list[Any] = [coerced] if self.shape is None else list(_flatten(coerced))
            where = "" if self.shape is None else "an element: "
            for x in flat:
                if lo is not None and x < lo:
                    return None, f"{where}{x}{unit} is below the minimum {lo}{unit}"
                if hi is not None and x > hi:
                    return None, f"{where}{x}{unit} is above the maximum {hi}{unit}"
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
        return self._coerce_number(value)

    def _coerce_number(self, value: Any) -> int | float:
        """A bare number in the declared unit, or ``"<number> <unit>"``."""
        if isinstance(value, bool):
            raise TypeError(f"expected a number, got the boolean {value!r}")
        if isinstance(value, str):
            number = self._parse_quantity(value)
        elif isinstance(value, (int, float)):
            number = value
        else:
            raise TypeError(f"expected a number, got {type(value).__name__} {value!r}")
        if self.type is int:
            if isinstance(number, float) and not number.is_integer():
                raise TypeError(f"expected a whole number, got {number!r}")
            return int(number)
        if not math.isfinite(float(number)):
            raise ValueError(f"expected a finite number, got {number!r}")
        return float(number)

    def _parse_quantity(self, text: str) -> float:
        number_text, _, unit = text.strip().partition(" ")
        try:
            number = float(number_text)
        except ValueError:
            raise TypeError(f"expected a number, got {text!r}") from None
        unit = unit.strip()
        if not unit:
            return number
        if not self.unit:
            raise ValueError(f"is dimensionless but was given the unit {unit!r}")
        try:
            return convert_unit(number, unit, self.unit)
        except ValueError as exc:
            raise ValueError(f"wrong unit: {exc}") from None

    def _coerce_array(self, value: Any) -> tuple[Any, ...]:
        assert self.shape is not None
        if isinstance(value, str):
            value = self._split_array(value)
        elif hasattr(value, "tolist"):  # a numpy array from a script
            value = value.tolist()
        return self._nest(value, self.shape, ())

    def _split_array(self, text: str) -> list[Any]:
        """``"1, 2, 3"``, ``"1 m, 2 m, 3 m"``, ``"[1, 2, 3] m"``, rows ``"1, 2; 3, 4"`` → nested lists of strings."""
        assert self.shape is not None
        bracketed = re.fullmatch(r"\s*[\[(](.*)[\])]\s*(.*)", text, re.S)
        body, unit = (bracketed.group(1), bracketed.group(2).strip()) if bracketed else (text, "")
        if unit and re.search(r"[^\d.eE+\-\s,;]", body):
            raise ValueError(f"give either one unit after the brackets or one per element, not both: {text!r}")
        rows = [[f"{e.strip()} {unit}".strip() for e in row.split(",") if e.strip()]
                for row in body.split(";") if row.strip()]
        if len(self.shape) == 1:
            if len(rows) > 1:
                raise ValueError(f"expected one row of numbers separated by ',' ({self.type_name}), got {text!r}")
            return rows[0] if rows else []
        if len(self.shape) == 2:
            return rows
        raise TypeError(f"give a {len(self.shape)}-dimensional {self.type_name} as a (TOML) array, not a string")

    def _nest(self, value: Any, shape: tuple[int | None, ...], index: tuple[int, ...]) -> tuple[Any, ...]:
        at = f" at [{', '.join(map(str, index))}]" if index else ""
        if not isinstance(value, (list, tuple)):
            raise TypeError(f"expected {self._expected(shape)}{at}, got {type(value).__name__} {value!r}")
        if shape[0] is not None and len(value) != shape[0]:
            raise ValueError(f"expected {self._expected(shape)}{at}, got {len(value)}: {list(value)!r}")
        if len(shape) > 1:
            return tuple(self._nest(v, shape[1:], (*index, i)) for i, v in enumerate(value))
        out = []
        for i, v in enumerate(value):
            try:
                out.append(self._coerce_number(v))
            except (TypeError, ValueError) as exc:
                raise type(exc)(f"element [{', '.join(map(str, (*index, i)))}]: {exc}") from None
        return tuple(out)

    def _expected(self, shape: tuple[int | None, ...]) -> str:
        count = "a list of" if shape[0] is None else f"{shape[0]}"
        what = "values" if len(shape) == 1 else "rows"
        unit = f" in {self.unit}" if self.unit else ""
        return f"{count} {what} ({self.type_name}{unit})"

    def describe(self) -> dict[str, Any]:
        """JSON-ready description (for ``mirrorlab plugins --json`` and TUI forms)."""
        return {
            "name": self.name,
            "type": self.type_name,
            "default": str(self.default) if isinstance(self.default, Path) else _lists(self.default),
            "unit": self.unit,
            "bounds": list(self.bounds) if self.bounds else None,
            "choices": list(self.choices) if self.choices else None,
            "help": self.help,
            "required": self.required,
            "live": self.live,
            "shape": list(self.shape) if self.shape else None,
        }


def _flatten(value: Any) -> Iterator[Any]:
    for v in value:
        if isinstance(v, tuple):
            yield from _flatten(v)
        else:
            yield v


def _lists(value: Any) -> Any:
    """Tuples (of tuples) as lists, for JSON."""
    return [_lists(v) for v in value] if isinstance(value, tuple) else value


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

    @property
    def setpoints(self) -> tuple[str, ...]:
        """Names of the live parameters (declared ``live=True``), in declaration order: the set-points
        an instrument accepts through :meth:`~mirrorlab.core.devices.Instrument.set`.

        >>> ParameterSet(Parameter("rate", float, 1.0), Parameter("target", float, 0.0, live=True)).setpoints
        ('target',)
        """
        return tuple(p.name for p in self.parameters if p.live)

    def defaults(self) -> dict[str, Any]:
        return {p.name: p.default for p in self.parameters if not p.required}

    def problems(self, values: Mapping[str, Any], where: str = "", file: str | None = None,
                 others: Iterable[str] = ()) -> tuple[dict[str, Any], list[Problem]]:
        """Validate ``values``; return the typed values (defaults filled in) and every problem.

        ``where`` is the key path prefix used in problem reports (``"instruments.cam.settings"``).
        ``others`` are keys the caller validates itself (a recipe step's ``action`` and nested
        tables): skipped here, but listed with the parameters when a key is unknown, so that the
        list names every key the table takes.
        """
        prefix = f"{where}." if where else ""
        out: dict[str, Any] = {}
        problems: list[Problem] = []
        known = {p.name for p in self.parameters} | set(others)
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
    """Parameter values with paths as strings and vectors as lists, ready for ``json.dumps``."""
    return {k: str(v) if isinstance(v, Path) else _lists(v) for k, v in values.items()}
