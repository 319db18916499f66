"""The bundled recipes validate, and `sessions/scan_film.toml` records the simulated film scanner."""

from __future__ import annotations

from pathlib import Path

import h5py
import numpy as np
import pytest

from tests.support import REPO, run_cli

RECIPES = sorted((REPO / "sessions").glob("*.toml"))


@pytest.mark.parametrize("recipe", RECIPES, ids=[r.name for r in RECIPES])
def test_bundled_recipes_validate(recipe: Path) -> None:
    proc = run_cli("run", str(recipe), "--check")
    assert proc.returncode == 0, proc.stderr


def test_scan_film_records_frames(tmp_path: Path) -> None:
    out = tmp_path / "scan.h5"
    proc = run_cli("run", str(REPO / "sessions" / "scan_film.toml"), "--out", str(out),
                   "--set", "steps.0.seconds=3", "--set", "instruments.scanner.settings.lines=128")
    assert proc.returncode == 0, proc.stderr
    with h5py.File(out, "r") as f:
        frames = f["instruments/scanner/frames/data"]
        index = f["instruments/scanner/frame_index/data"][()]
        times = f["instruments/scanner/frames/time"][()]
        assert frames.shape[0] >= 2 and frames.shape[1:] == (128, 512)
        scanned = frames[()]
        assert set(np.unique(scanned)) == {0, 255}  # binary frames with markers in them
        assert np.all(np.diff(index) > 0) and np.all(np.diff(times) > 0)
        assert f["instruments/scanner"].attrs["plugin"] == "film_scanner"
        assert f.attrs["status"] == "closed"
