"""Adapters: the algorithm through Session.run, the recipe through `mirrorlab run`, the CLI through a subprocess."""

from __future__ import annotations

import json

import numpy as np
import pytest
from mirrorlab.core import Session
from mirrorlab.core.registry import get_registry

from tests.plugins.retarget.optimum import optimum_bounds
from tests.support import REPO, run_cli

from .test_fixtures import PRINTED, T1_IN, T1_OUT, objective


def test_registered_and_runs_through_a_session(tmp_path) -> None:
    reg = get_registry()
    assert reg.get("algorithm", "retarget").name == "retarget" and reg.get("step", "retarget").name == "retarget"
    X = T1_IN.forward(np.array([[0.4, -0.3, 0.5, 0.2]] * 3))
    with Session.create(tmp_path / "s.h5") as s:
        ref = s.run("retarget", {"joints": X}, {"lengths": "2,2", "axes": "z,y"})
        assert ref.status == "ok"
        out = s.result(ref).outputs
    # the spec's printed optimum (±5e-7) and LM's stop (20 iterations, converged here)
    obj = objective(T1_IN, T1_OUT)
    b = optimum_bounds(obj, out["q"], obj.arms(X))
    assert (np.abs(out["q"] - [0.604032, -0.333016]).max(axis=1) <= PRINTED + b.q).all() and T1_OUT.dof == 2


@pytest.mark.data
def test_recipe_retarget_bvh_runs(tmp_path) -> None:
    out = tmp_path / "r.h5"
    proc = run_cli("run", str(REPO / "sessions" / "retarget_bvh.toml"), "--out", str(out), "--no-progress", timeout=600)
    assert proc.returncode == 0, proc.stderr
    with Session.open(out) as s:
        g = s.read_group("retarget/cmu_01_01_right_arm")
        assert g["q"].shape == (2751, 4) and g["input_joints"].shape == (2751, 4, 3)
        # the CMU arm on its robot: mean 8.1, max 37.9 mm² documented (docs/retarget.md); 100 mm² is a
        # plausibility margin on real data
        assert float(np.max(g["f"])) < 100.0 and int(s.attributes("retarget/cmu_01_01_right_arm")["published"]) == 2751


@pytest.mark.data
def test_cli_run_on_the_c3d_with_csv_and_figure(tmp_path) -> None:
    from tests.support import SHARED_DATA

    proc = run_cli("retarget", "run", str(SHARED_DATA / "mocap" / "markers_analogs.c3d"),
                   "--joints", "ACRO_tip,EPICl+EPICm,STYLr+STYLu", "--lengths", "311,262", "--axes", "zyx,y",
                   "--csv", str(tmp_path / "o.csv"), "--figures", str(tmp_path), "--json")
    assert proc.returncode == 0, proc.stderr
    summary = json.loads(proc.stdout)
    assert summary["frames"] == 580 and summary["published"] == 580 and (tmp_path / "chains.png").stat().st_size > 0
    assert len((tmp_path / "o.csv").read_text().splitlines()) == 581
    bad = run_cli("retarget", "run", str(SHARED_DATA / "mocap" / "markers_analogs.c3d"), "--joints", "ACRO_tip,NOPE",
                  "--lengths", "311", "--axes", "zyx")
    assert bad.returncode == 1 and "joint 'NOPE'" in bad.stderr
    usage = run_cli("retarget", "run", "missing.bvh", "--joints", "a,b", "--lengths", "1", "--axes", "q")
    assert usage.returncode == 2 and "no such file" in usage.stderr
