"""Typed parameters: coercion, units, bounds, choices and problem reports."""

from __future__ import annotations

import math
from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st
from mirrorlab.core import Parameter, ParameterSet, ValidationError
from mirrorlab.core.params import convert_unit

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
        Parameter("x", float, 1.0, unit="furlong")
    with pytest.raises(ValueError, match="default"):
        Parameter("x", float, 5.0, bounds=(0, 1))
    with pytest.raises(ValueError, match="declared twice"):
        ParameterSet(Parameter("a", float, 1.0), Parameter("a", float, 2.0))


@given(st.floats(-1e6, 1e6, allow_nan=False), st.sampled_from(["mm", "um", "cm", "m"]),
       st.sampled_from(["mm", "um", "cm", "m"]))
def test_unit_conversion_round_trips(x: float, a: str, b: str) -> None:
    assert math.isclose(convert_unit(convert_unit(x, a, b), b, a), x, rel_tol=1e-12, abs_tol=1e-9)


def test_describe_is_json_ready() -> None:
    import json

    desc = json.loads(json.dumps(PARAMS.describe()))
    assert desc[0] == {"name": "exposure", "type": "float", "default": 0.01, "unit": "s", "bounds": [1e-4, 1.0],
                       "choices": None, "help": "exposure", "required": False, "live": False}
