"""The bundled recipes validate, and `sessions/scan_film.toml` records the simulated film scanner."""

from __future__ import annotations

from pathlib import Path

import cv2
import h5py
import numpy as np
import pytest

from tests.support import REPO, run_cli

RECIPES = sorted((REPO / "sessions").glob("*.toml"))


@pytest.mark.parametrize("recipe", [pytest.param(r, marks=pytest.mark.data) if "shared/data" in r.read_text() else r
                                    for r in RECIPES], ids=[r.name for r in RECIPES])
def test_bundled_recipes_validate(recipe: Path) -> None:
    proc = run_cli("run", str(recipe), "--check")
    assert proc.returncode == 0, proc.stderr


def test_scan_film_records_frames(tmp_path: Path) -> None:
    """Recorded until the end of a 3-frame film (not for a time): every frame, each with its 4 markers."""
    out = tmp_path / "scan.h5"
    proc = run_cli("run", str(REPO / "sessions" / "scan_film.toml"), "--out", str(out),
                   "--set", "steps.0.seconds=0", "--set", "instruments.scanner.settings.scene_frames=3")
    assert proc.returncode == 0, proc.stderr
    with h5py.File(out, "r") as f:
        scanned = f["instruments/scanner/frames/data"][()]
        index = f["instruments/scanner/frame_index/data"][()]
        times = f["instruments/scanner/frames/time"][()]
        assert scanned.shape == (3, 344, 512)
        assert index.tolist() == [0, 1, 2] and np.all(np.diff(times) > 0)
        for frame in scanned:  # binary frames, four white discs on black
            assert set(np.unique(frame)) == {0, 255}
            assert cv2.connectedComponents(frame)[0] - 1 == 4
        assert f["instruments/scanner"].attrs["plugin"] == "film_scanner"
        assert f.attrs["status"] == "closed"


def test_scan_film_runs_quietly(tmp_path: Path) -> None:
    """As shipped, the recipe records the film to its end and says nothing on stderr (it recorded for
    6 s and warned on every run that the 1.4 s film had ended first)."""
    out = tmp_path / "scan.h5"
    proc = run_cli("run", str(REPO / "sessions" / "scan_film.toml"), "--out", str(out), "--no-progress",
                   "--set", "instruments.scanner.settings.scene_frames=3")
    assert proc.returncode == 0 and proc.stderr == "", proc.stderr
    with h5py.File(out, "r") as f:
        assert f["instruments/scanner/frame_index/data"][()].tolist() == [0, 1, 2]
