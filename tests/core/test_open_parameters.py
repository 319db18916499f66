"""Open parameters end to end: a third-party plugin declaring a pint unit and a vector loads, and a recipe
with a vector of the wrong length fails at ``mirrorlab run --check`` naming the key (a real installed
plugin, the CLI in a subprocess)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from tests.support import plugin_site, run_cli
from tests.tolerances import roundoff

PLUGIN = '''
import numpy as np
from mirrorlab.core import Algorithm, Parameter, ParameterSet, Port, hookimpl


class Aim(Algorithm):
    """Where a camera at ``camera_center`` looks after ``seconds`` of a pan at ``speed``."""

    name = "survey_aim"
    version = "1.0.0"
    description = "camera centre moved along x at a speed"
    parameters = ParameterSet(
        Parameter("speed", float, 0.5, unit="m/s", bounds=(0.0, None), help="pan speed"),
        Parameter("supply", float, 5.0, unit="V", help="supply voltage"),
        Parameter("camera_center", float, unit="mm", shape=(3,), help="camera centre x, y, z"),
        Parameter("seconds", float, 1.0, unit="s", help="duration"),
    )
    inputs = ()
    outputs = (Port("position", "(3,) camera centre after the pan", "mm"),)

    def run(self, inputs, params, context):
        moved = np.asarray(params["camera_center"]) + [params["speed"] * 1000.0 * params["seconds"], 0.0, 0.0]
        return {"position": moved}


@hookimpl
def mirrorlab_register_algorithms():
    return [Aim]
'''

RECIPE = """
[session]
description = "open parameters"

[[steps]]
action = "run"
algorithm = "survey_aim"
[steps.parameters]
speed = "{speed}"
camera_center = {center}
seconds = "250 ms"
"""


@pytest.fixture(scope="module")
def survey_site(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return plugin_site(PLUGIN, "mirrorlab-survey", "survey", tmp_path_factory.mktemp("survey-src"),
                       tmp_path_factory.mktemp("survey-site"))


def test_plugin_with_pint_unit_and_vector_loads(survey_site: Path) -> None:
    doctor = run_cli("plugins", "doctor", "--json", sites=(survey_site,))
    survey = next(p for p in json.loads(doctor.stdout)["plugins"] if p["name"] == "survey")
    assert survey["ok"] and survey["provides"] == {"algorithm": ["survey_aim"]}, survey
    shown = run_cli("plugins", "show", "survey_aim", "--json", sites=(survey_site,))
    params = {p["name"]: p for p in json.loads(shown.stdout)["parameters"]}
    assert params["speed"]["unit"] == "m/s" and params["supply"]["unit"] == "V"
    assert params["camera_center"]["type"] == "float[3]" and params["camera_center"]["shape"] == [3]


def test_two_element_vector_fails_at_check_naming_the_key(survey_site: Path, tmp_path: Path) -> None:
    bad = tmp_path / "bad.toml"
    bad.write_text(RECIPE.format(speed="0.5 m/s", center="[435.7, 202.6]"))
    checked = run_cli("run", str(bad), "--check", sites=(survey_site,))
    assert checked.returncode == 2, checked.stderr
    assert (f"{bad}: steps.0.parameters.camera_center: expected 3 values (float[3] in mm), got 2: [435.7, 202.6]"
            in checked.stderr), checked.stderr
    as_string = tmp_path / "string.toml"
    as_string.write_text(RECIPE.format(speed="0.5 m/s", center='"1, 2"'))
    checked = run_cli("run", str(as_string), "--check", sites=(survey_site,))
    assert checked.returncode == 2 and "steps.0.parameters.camera_center: expected 3 values" in checked.stderr


def test_units_and_vectors_reach_the_algorithm_converted(survey_site: Path, tmp_path: Path) -> None:
    good = tmp_path / "good.toml"
    good.write_text(RECIPE.format(speed="3.6 km/h", center='["0.4357 m", "20.26 cm", 1442.0]'))
    assert run_cli("run", str(good), "--check", sites=(survey_site,)).returncode == 0
    out = tmp_path / "good.h5"
    ran = run_cli("run", str(good), "--out", str(out), sites=(survey_site,))
    assert ran.returncode == 0, ran.stderr
    import h5py
    import numpy as np

    with h5py.File(out, "r") as f:
        run = f["results/survey_aim/run-0001"]
        params = json.loads(run.attrs["parameters"])
        position = run["position"][()]
    # unit conversions (3.6 km/h, 0.4357 m, 20.26 cm): a product and a parse each, rounding only
    assert params["speed"] == pytest.approx(1.0, abs=roundoff(scale=1.0, ops=3)) and params["seconds"] == 0.25
    assert params["camera_center"] == pytest.approx([435.7, 202.6, 1442.0], abs=roundoff(scale=1442.0, ops=3))
    np.testing.assert_allclose(position, [435.7 + 250.0, 202.6, 1442.0], rtol=0, atol=roundoff(scale=1442.0, ops=6))

