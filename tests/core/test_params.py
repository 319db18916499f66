"""Typed parameters: coercion, units, bounds, choices and problem reports."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from mirrorlab.core import Parameter, ParameterSet, ValidationError
from mirrorlab.core.params import _UNITS, _pint, convert_unit

from tests.tolerances import roundoff

#: Below the smallest normal float (hypothesis draws subnormals) rounding is absolute: each operation
#: may lose up to the smallest subnormal, which a conversion factor (<= 1e9 here: km <-> um) scales.
UNDERFLOW = 1e9 * float(np.finfo(float).smallest_subnormal)


def _conversion_tol(x: float, ops: float, offset: float = 0.0) -> float:
    """Rounding bound of a unit conversion of ``x``: ``ops`` rounded operations at the scale of the
    value plus any offset added on the way (temperatures), and the underflow floor."""
    return roundoff(scale=abs(x) + offset, ops=ops) + ops * UNDERFLOW

PARAMS = ParameterSet(
    Parameter("exposure", float, 0.01, unit="s", bounds=(1e-4, 1.0), help="exposure"),
    Parameter("lines", int, 344, bounds=(1, 344), help="lines per frame"),
    Parameter("mode", str, "fast", choices=("fast", "slow"), help="mode"),
    Parameter("loop", bool, False, help="loop"),
    Parameter("film", Path, Path("."), help="film folder"),
    Parameter("gain", float, help="required gain"),
)


def test_defaults_and_coercion() -> None:
    values = PARAMS.validate({"gain": 2, "exposure": "5 ms", "loop": "yes", "lines": 12.0, "film": "x"})
    assert values == {"exposure": 0.005, "lines": 12, "mode": "fast", "loop": True, "film": Path("x"), "gain": 2.0}
    assert isinstance(values["gain"], float) and isinstance(values["lines"], int)


def test_every_problem_is_reported_with_key_and_reason() -> None:
    with pytest.raises(ValidationError) as info:
        PARAMS.validate({"exposure": "5 mm", "lines": 400, "mode": "medium", "loop": 3, "bogus": 1},
                        where="instruments.cam.settings", file="r.toml")
    text = [str(p) for p in info.value.problems]
    assert "r.toml: instruments.cam.settings.bogus: unknown parameter" in text[0]
    joined = "\n".join(text)
    assert "exposure: wrong unit: cannot convert mm (length) to s (time)" in joined
    assert "lines: 400 is above the maximum 344" in joined
    assert "mode: must be one of fast, slow" in joined
    assert "loop: expected true or false" in joined
    assert "gain: required" in joined
    assert len(text) == 6


@pytest.mark.parametrize("value", [1.5, "1.5", True])
def test_int_rejects_non_integers(value: object) -> None:
    assert Parameter("n", int, 1).check(value)[1] is not None


def test_bad_declarations_fail_at_definition() -> None:
    with pytest.raises(ValueError, match="unknown unit"):
        Parameter("x", float, 1.0, unit="bogons")
    with pytest.raises(ValueError, match="default"):
        Parameter("x", float, 5.0, bounds=(0, 1))
    with pytest.raises(ValueError, match="declared twice"):
        ParameterSet(Parameter("a", float, 1.0), Parameter("a", float, 2.0))


@given(st.floats(-1e6, 1e6, allow_nan=False), st.sampled_from(["mm", "um", "cm", "m"]),
       st.sampled_from(["mm", "um", "cm", "m"]))
def test_unit_conversion_round_trips(x: float, a: str, b: str) -> None:
    # two products and two quotients by inexact factors (1e-3): rounding only
    assert abs(convert_unit(convert_unit(x, a, b), b, a) - x) <= _conversion_tol(x, ops=6)


def test_describe_is_json_ready() -> None:
    import json

    desc = json.loads(json.dumps(PARAMS.describe()))
    assert desc[0] == {"name": "exposure", "type": "float", "default": 0.01, "unit": "s", "bounds": [1e-4, 1.0],
                       "choices": None, "help": "exposure", "required": False, "live": False, "shape": None}


# -- any unit pint understands ---------------------------------------------------------------------
@pytest.mark.parametrize(("unit", "given", "expected"), [
    ("m/s", "250 mm/s", 0.25), ("m/s", "3.6 km/h", 1.0), ("V", "5 mV", 0.005), ("dB", "3 dB", 3.0),
    ("%", "0.5", 0.5), ("%", "0.25 dimensionless", 25.0), ("degC", "300 K", 26.85), ("degC", "68 degF", 20.0),
    ("K", "20 degC", 293.15), ("s", "1 h", 3600.0), ("mm", "2 inch", 50.8), ("rad", "90 deg", math.pi / 2),
])
def test_any_pint_unit_converts_into_the_declared_one(unit: str, given: str, expected: float) -> None:
    value, problem = Parameter("x", float, unit=unit).check(given)
    # pint: a parse and a few products, and for temperatures an offset of up to 459.67
    offset = 459.67 if unit in ("degC", "K") else 0.0
    assert problem is None and abs(value - expected) <= _conversion_tol(expected, ops=8, offset=offset), (value, problem)


def test_a_unit_pint_does_not_know_fails_at_declaration_naming_the_parameter() -> None:
    with pytest.raises(ValueError, match=r"parameter 'speed': unknown unit 'bogons/s' \(pint: 'bogons' is not defined"):
        Parameter("speed", float, 1.0, unit="bogons/s")
    with pytest.raises(ValueError, match="parameter 'gain': unknown unit 'm\\+'"):
        Parameter("gain", float, unit="m+")


def test_wrong_dimension_through_pint_names_both_units() -> None:
    reason = Parameter("speed", float, unit="m/s").check("3 V")[1]
    assert reason is not None and reason.startswith("wrong unit: cannot convert V (") and "to m/s (" in reason


def test_common_units_do_not_import_pint() -> None:
    import subprocess
    import sys

    probe = ("import sys\nfrom mirrorlab.core.params import Parameter\n"
             "assert Parameter('t', float, unit='s').check('250 ms') == (0.25, None)\n"
             "assert Parameter('a', float, unit='deg/s').check('1 rad/s')[1] is None\n"
             "print('pint' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "False"


PINT_UNITS = {"length": ["mm", "m", "inch", "km", "um"], "time": ["s", "ms", "h", "min"],
              "temperature": ["degC", "K", "degF"], "voltage": ["V", "mV", "kV"],
              "speed": ["m/s", "mm/s", "km/h"], "ratio": ["%", "dimensionless", "ppm"]}


@given(st.sampled_from(sorted(PINT_UNITS)).flatmap(lambda d: st.tuples(st.sampled_from(PINT_UNITS[d]),
                                                                       st.sampled_from(PINT_UNITS[d]))),
       st.floats(-1e6, 1e6, allow_nan=False))
def test_pint_unit_conversion_round_trips(units: tuple[str, str], x: float) -> None:
    a, b = units
    # pint's factors through its base units, both ways; temperatures add and remove offsets of up to
    # 459.67 (degF), which round absolutely
    offset = 459.67 if a in PINT_UNITS["temperature"] else 0.0
    assert abs(convert_unit(convert_unit(x, a, b), b, a) - x) <= _conversion_tol(x, ops=16, offset=offset)


@given(st.sampled_from(sorted(_UNITS)), st.sampled_from(sorted(_UNITS)), st.floats(-1e6, 1e6, allow_nan=False))
def test_fast_table_agrees_with_pint(a: str, b: str, x: float) -> None:
    """The built-in table is only a shortcut: where it converts, pint gives the same number."""
    if _UNITS[a][0] != _UNITS[b][0]:
        return
    expected = _pint().Quantity(x, a).to(b).magnitude
    # the same product by two routes (the table's two factors, pint's base units): rounding only
    assert abs(convert_unit(x, a, b) - expected) <= _conversion_tol(expected, ops=8)


# -- vectors ---------------------------------------------------------------------------------------
CENTRE = Parameter("camera_center", float, shape=(3,), unit="mm", bounds=(-1e4, 1e4), help="camera centre")
CORNERS = Parameter("mirror_corners", float, shape=(None, 3), unit="mm", help="mirror corners")


@pytest.mark.parametrize("given", [[435.5, 202.5, 1442.0], (435.5, 202.5, 1442), "435.5, 202.5, 1442",
                                   ["0.4355 m", "202.5 mm", "144.2 cm"], "0.4355 m, 202.5, 144.2 cm",
                                   "[0.4355, 0.2025, 1.442] m", "(435.5, 202.5, 1442)"])
def test_vector_accepts_toml_arrays_and_cli_strings(given: object) -> None:
    value, problem = CENTRE.check(given)
    assert problem is None and isinstance(value, tuple)
    assert all(isinstance(v, float) for v in value)
    # a parse and a unit factor per element: rounding only
    assert all(abs(v - e) <= _conversion_tol(e, ops=4) for v, e in zip(value, (435.5, 202.5, 1442.0), strict=True))


def test_vector_of_numpy_values_from_a_script() -> None:
    import numpy as np

    assert CENTRE.check(np.array([1.0, 2.0, 3.0])) == ((1.0, 2.0, 3.0), None)


@pytest.mark.parametrize(("given", "reason"), [
    ("1, 2", "expected 3 values (float[3] in mm), got 2: ['1', '2']"),
    ([1, 2, 3, 4], "expected 3 values (float[3] in mm), got 4: [1, 2, 3, 4]"),
    (5.0, "expected 3 values (float[3] in mm), got float 5.0"),
    ([1, "x", 3], "element [1]: expected a number, got 'x'"),
    ([1, "2 s", 3], "element [1]: wrong unit: cannot convert s (time) to mm (length)"),
    ([1, 2, 2e4], "an element: 20000.0 mm is above the maximum 10000.0 mm"),
    ("1, 2; 3, 4", "expected one row of numbers separated by ',' (float[3]), got '1, 2; 3, 4'"),
    ("[1 m, 2, 3] m", "give either one unit after the brackets or one per element, not both: '[1 m, 2, 3] m'"),
])
def test_vector_problems_say_what_is_wrong(given: object, reason: str) -> None:
    assert CENTRE.check(given) == (None, reason)


def test_rows_of_points_any_count() -> None:
    assert CORNERS.check("1, 2, 3; 4, 5, 6")[0] == ((1.0, 2.0, 3.0), (4.0, 5.0, 6.0))
    assert CORNERS.check([[1, 2, 3]])[0] == ((1.0, 2.0, 3.0),)
    assert CORNERS.check("[0.001, 0, 0; 0, 0, 1] m")[0] == ((1.0, 0.0, 0.0), (0.0, 0.0, 1000.0))
    assert CORNERS.check([[1, 2, 3], [4, 5]])[1] == "expected 3 values (float[N,3] in mm) at [1], got 2: [4, 5]"


def test_vector_validation_names_the_key_and_describe_shows_the_shape() -> None:
    with pytest.raises(ValidationError) as info:
        ParameterSet(CENTRE).validate({"camera_center": "1, 2"}, where="steps[0].parameters", file="r.toml")
    assert str(info.value.problems[0]) == ("r.toml: steps[0].parameters.camera_center: "
                                           "expected 3 values (float[3] in mm), got 2: ['1', '2']")
    desc = Parameter("c", float, [1, 2, 3], unit="mm", shape=(3,)).describe()
    assert desc["type"] == "float[3]" and desc["shape"] == [3] and desc["default"] == [1.0, 2.0, 3.0]
    assert CORNERS.describe()["shape"] == [None, 3] and CORNERS.type_name == "float[N,3]"


def test_vector_defaults_and_declarations() -> None:
    p = Parameter("gains", int, [1, 2], shape=(2,))
    assert p.default == (1, 2) and hash(p)
    assert p.check([1.5, 2])[1] == "element [0]: expected a whole number, got 1.5"
    with pytest.raises(TypeError, match="a shape needs type int or float"):
        Parameter("names", str, shape=(2,))
    with pytest.raises(ValueError, match="shape must be positive lengths"):
        Parameter("v", float, shape=(0,))
    with pytest.raises(ValueError, match="default"):
        Parameter("v", float, [1, 2], shape=(3,))


@given(st.lists(st.floats(-1e6, 1e6, allow_nan=False), min_size=3, max_size=3), st.sampled_from(["mm", "m", "inch", "um"]))
def test_vector_string_round_trip(xs: list[float], unit: str) -> None:
    """A vector written as a string in any length unit reads back as the same point in mm."""
    text = "[" + ", ".join(repr(convert_unit(x, "mm", unit)) for x in xs) + f"] {unit}"
    value, problem = Parameter("p", float, shape=(3,), unit="mm").check(text)
    assert problem is None
    # repr() round-trips exactly; the two conversions round
    assert all(abs(v - x) <= _conversion_tol(x, ops=8) for v, x in zip(value, xs, strict=True))

