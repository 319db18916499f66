"""``AlgorithmStep``: the one base of recipe steps that run an algorithm (``run``, ``calibrate``, ``reconstruct``
and third-party kinds) checks the algorithm, the step's own keys and the ``inputs`` / ``parameters`` tables,
and stops the recipe on a failed run with the step's error class."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from mirrorlab.core import (
    AlgorithmError,
    AlgorithmStep,
    Parameter,
    ParameterSet,
    Problem,
    Registry,
    Session,
    Step,
    get_registry,
)
from mirrorlab.plugins.photogrammetry.errors import PhotogrammetryError


class SmoothFailed(AlgorithmError):
    """The error class the step below raises on a failed run."""


class Smooth(AlgorithmStep):
    """A plugin's step: ``filter = "spline"`` runs ``derivatives``; the step supplies ``time`` itself."""

    name = "smooth"
    description = "test step"
    algorithm_key = "filter"
    failure = SmoothFailed
    parameters = ParameterSet(Parameter("filter", str, help="spline or anything else (no such algorithm)"),
                              Parameter("rate", float, 0.0, help="sample rate, Hz; > 0"))

    @classmethod
    def algorithm_name(cls, values: Mapping[str, Any]) -> str:
        return "derivatives" if values["filter"] == "spline" else f"no_{values['filter']}"

    @classmethod
    def provided(cls, values: Mapping[str, Any]) -> set[str]:
        return {"time"}

    @classmethod
    def check(cls, values: Mapping[str, Any], where: str, file: str | None, registry: Registry) -> list[Problem]:
        return [] if values["rate"] > 0 else [Problem(f"{where}.rate", "must be > 0", file)]

    def execute(self, session: Session, values: Mapping[str, Any]) -> None:
        self.run_algorithm(session, self.algorithm_name(values),
                           {"time": "/data/time", **values["inputs"]}, values["parameters"])


def _problems(table: dict[str, Any], step: type[AlgorithmStep] = Smooth) -> tuple[dict[str, Any], list[str]]:
    values, problems = step.validate(table, "steps.0", "r.toml", get_registry(), {})
    return values, [f"{p.key}: {p.reason}" for p in problems]


def test_an_unknown_algorithm_is_reported_at_the_key_that_names_it() -> None:
    _, problems = _problems({"filter": "kalman", "rate": 10.0})
    assert len(problems) == 1 and problems[0].startswith("steps.0.filter: ") and "no_kalman" in problems[0], problems


def test_own_checks_then_the_inputs_and_parameters_of_the_algorithm() -> None:
    _, problems = _problems({"filter": "spline", "inputs": {"value": "/data/x", "values": "data/x"},
                             "parameters": {"method": "magic"}})
    keys = [p.split(": ")[0] for p in problems]
    assert keys == ["steps.0.rate", "steps.0.inputs.value", "steps.0.inputs.values", "steps.0.parameters.method"], problems


def test_provided_inputs_need_not_be_named_and_the_tables_are_typed() -> None:
    values, problems = _problems({"filter": "spline", "rate": 10.0, "inputs": {"values": "/data/x"},
                                  "parameters": {"method": "butterworth"}})
    assert problems == []
    assert values["inputs"] == {"values": "/data/x"} and values["parameters"]["method"] == "butterworth"


def test_builtin_algorithm_steps_share_the_base() -> None:
    registry = get_registry()
    assert all(issubclass(registry.step(name), AlgorithmStep) for name in ("run", "calibrate", "reconstruct"))
    _, problems = _problems({"method": "stereo"}, registry.step("reconstruct"))
    assert problems and problems[0].startswith("steps.0.method: "), problems


@pytest.mark.parametrize(("step", "error"), [("smooth", SmoothFailed), ("reconstruct", PhotogrammetryError),
                                             ("run", AlgorithmError)])
def test_a_failed_run_is_stored_and_stops_the_recipe_with_the_steps_error(tmp_path: Path, step: str,
                                                                         error: type[Exception]) -> None:
    cls = Smooth if step == "smooth" else get_registry().step(step)
    table = {"smooth": {"filter": "spline", "rate": 10.0, "inputs": {"values": "/data/x"}},
             "run": {"algorithm": "derivatives", "inputs": {"time": "/data/time", "values": "/data/x"}},
             "reconstruct": {"method": "parallel", "inputs": {"image_xy": "/data/x", "lengths": "/data/time",
                                                              "signs": "/data/time"}}}[step]
    values, problems = cls.validate(table, "steps.0", None, get_registry(), {})
    assert problems == []
    with Session.create(tmp_path / "s.h5") as s:
        # time goes back for derivatives; a 1-D image_xy for reconstruct_parallel
        s.write_group("data", {"time": np.array([0.0, 1.0, 1.0, 0.5]), "x": np.arange(4.0)})
        with pytest.raises(error) as info:
            cls().execute(s, values)
        (ref,) = s.results()
        assert ref.status == "failed" and str(info.value).startswith(f"{ref.path} failed: ")


class Pause(Step):
    """A plain step whose two keys go together: ``until`` after ``since``."""

    name = "pause"
    description = "test step"
    parameters = ParameterSet(Parameter("since", float, 0.0), Parameter("until", float, 1.0),
                              Parameter("instrument", str, ""))
    instrument_keys = ("instrument",)

    @classmethod
    def check(cls, values: Mapping[str, Any], where: str, file: str | None, registry: Registry) -> list[Problem]:
        return [] if values["until"] > values["since"] else [Problem(f"{where}.until", "must follow since", file)]

    def execute(self, session: Session, values: Mapping[str, Any]) -> None:
        raise AssertionError("not run")


@pytest.mark.parametrize(("table", "expected"), [
    ({"since": 2.0, "until": 1.0, "instrument": "cam"}, ["steps.0.until", "steps.0.instrument"]),
    ({"since": "x", "until": 1.0}, ["steps.0.since"]),                   # check waits for valid values
    ({"since": 0.0, "until": 1.0, "instrument": "dut"}, []),
])
def test_a_plain_steps_check_sees_its_typed_values(table: dict[str, Any], expected: list[str]) -> None:
    _, problems = Pause.validate(table, "steps.0", None, get_registry(), {"dut": {}})
    assert [p.key for p in problems] == expected, problems
