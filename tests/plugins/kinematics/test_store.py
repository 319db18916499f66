"""The session marker layout (import, read back, export) and the ``import_markers`` recipe step."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from mirrorlab.core import Session
from mirrorlab.core.errors import ValidationError
from mirrorlab.core.recipes import load_recipe, run_recipe
from mirrorlab.plugins.kinematics import KinematicsIOError, read_c3d, read_trc, write_c3d
from mirrorlab.plugins.kinematics.store import (
    export_markers,
    import_markers,
    marker_names,
    read_markers,
    resolve_label,
    sha256_file,
)

from tests.derived_bounds import F32, smoothing_spline_rounding
from tests.support import SHARED_DATA
from tests.tolerances import abs_err


@pytest.mark.data
def test_import_read_export_round_trip(tmp_path: Path):
    rng = np.random.default_rng(1)
    pts = rng.normal(0, 300, (30, 3, 3))
    pts[4:7, 1] = np.nan
    src = tmp_path / "recon.c3d"
    write_c3d(src, ["a", "b", "c"], 60.0, pts)
    path = tmp_path / "s.h5"
    with Session.create(path) as s:
        group, data = import_markers(s, src)
        assert group == "/markers/recon"
        with pytest.raises(KinematicsIOError, match="already holds /markers/recon"):
            import_markers(s, src)
        import_markers(s, SHARED_DATA / "mocap" / "markers.trc", name="trc")
    with Session.open(path) as s:
        assert marker_names(s) == ["recon", "trc"]
        back = read_markers(s, "recon")
        attrs = s.attributes("markers/recon")
        trc = read_markers(s, "/markers/trc")
    assert back.labels == ["a", "b", "c"] and back.rate == 60.0
    assert abs_err(back.points, pts) <= F32 * np.nanmax(np.abs(pts))            # float32 C3D storage
    assert attrs["source_sha256"] == sha256_file(src) and attrs["source_format"] == "c3d"
    ref = read_trc(SHARED_DATA / "mocap" / "markers.trc")
    assert trc.labels == ref.labels and np.array_equal(trc.points, ref.points, equal_nan=True)
    out = tmp_path / "out.c3d"
    export_markers(back, out, "c3d")
    assert abs_err(read_c3d(out).points, pts) <= F32 * np.nanmax(np.abs(pts))   # stored as float32 once more
    with pytest.raises(KinematicsIOError, match="csv or c3d"):
        export_markers(back, tmp_path / "x.trc", "trc")


def test_label_resolution():
    labels = ["S:STER", "S:STERl", "T:STER", "XIPH"]
    assert resolve_label(labels, "STERl") == 1 and resolve_label(labels, "XIPH") == 3
    with pytest.raises(KinematicsIOError, match="ambiguous"):
        resolve_label(labels, "STER")
    with pytest.raises(KinematicsIOError, match="similar labels"):
        resolve_label(labels, "ster_x")


def test_import_markers_recipe_step(tmp_path: Path):
    pts = np.arange(5 * 3 * 3, dtype=float).reshape(5, 3, 3)
    write_c3d(tmp_path / "walk.c3d", ["p", "q", "r"], 100.0, pts)
    recipe = tmp_path / "import.toml"
    recipe.write_text(
        '[session]\ndescription = "import"\n\n'
        '[[steps]]\naction = "import_markers"\nfile = "walk.c3d"\n\n'
        '[[steps]]\naction = "run"\nalgorithm = "derivatives"\n'
        'inputs = { time = "/markers/walk/time", values = "/markers/walk/points" }\n'
        'parameters = { method = "smoothing_spline", lam = 0.0 }\n')
    out = run_recipe(load_recipe(recipe), tmp_path / "r.h5")
    with Session.open(out) as s:
        assert read_markers(s, "walk").labels == ["p", "q", "r"]
        (ref,) = s.results("derivatives")
        assert ref.status == "ok"
        # points advance 9 mm per frame: a line, which the interpolating spline (lam = 0) reproduces
        # up to its rounding (integers, exact in float32)
        t = np.arange(5) / 100.0
        tol = max(smoothing_spline_rounding(t, pts.reshape(5, -1)[:, j], 1, lam=0.0) for j in range(9))
        assert abs_err(s.result(ref).outputs["velocity"], 9.0 * 100.0) <= tol

    bad = tmp_path / "bad.toml"
    bad.write_text('[[steps]]\naction = "import_markers"\nfile = "none.c3d"\n')
    with pytest.raises(ValidationError, match="steps.*file: no such marker file"):
        load_recipe(bad)
