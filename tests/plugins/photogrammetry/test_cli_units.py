"""Length options of ``mirrorlab calibrate`` / ``reconstruct`` take units, as recipes do; the chessboard
error points to the detector that finds the board.

Each length option is given once in mm and once in another unit (values chosen so that the
conversion is exact in binary floating point): the outputs must be identical, byte for byte. An
option that ignored the unit would be off by a factor of 10 or 1000.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import cv2
import h5py
import numpy as np
import pytest
from mirrorlab.plugins.photogrammetry.central import CentralCamera

from tests.support import run_cli

from .scenes import F1, NORMAL, G, grid_points, markers, plane_images
from .test_cli import _marker_csv, _v


def _ok(proc) -> str:
    assert proc.returncode == 0, proc.stderr
    return proc.stdout


def _views(folder: Path) -> Path:
    """Four blurred, noisy photos of a 10x7 (inner corners) board seen from four sides, 510x420 px.

    Blur (sigma 5 px) and noise (sigma 80 grey levels) defeat OpenCV's classic detector; the sb
    detector finds the board in each.
    """
    folder.mkdir()
    board = np.pad(np.kron(np.indices((8, 11)).sum(0) % 2, np.ones((30, 30))) * 255.0, 30, constant_values=255)
    h, w = board.shape
    corners = np.float32([[0, 0], [w, 0], [w, h], [0, h]])
    rng = np.random.default_rng(3)
    for k, shift in enumerate(([0] * 8, [40, 10, -30, 20, -20, 30, 40, -10], [-20, 40, 20, -30, 30, 10, -40, 20],
                               [30, -20, 0, 30, -30, -10, 10, 40])):
        H = cv2.getPerspectiveTransform(corners, corners + np.float32(shift).reshape(4, 2) + 60)
        img = cv2.GaussianBlur(cv2.warpPerspective(board, H, (w + 120, h + 120), borderValue=255), (0, 0), 5)
        cv2.imwrite(str(folder / f"view{k}.png"), np.clip(img + rng.normal(0, 80, img.shape), 0, 255).astype(np.uint8))
    return folder


@pytest.fixture(scope="module")
def views(tmp_path_factory) -> Path:
    return _views(tmp_path_factory.mktemp("board") / "views")


def test_classic_detector_failure_names_the_sb_detector_that_finds_the_board(views: Path) -> None:
    proc = run_cli("calibrate", "--images", str(views), "--pattern", "10x7", "--square", "25", "--json",
                   "--no-progress")
    assert proc.returncode == 1
    assert proc.stderr.splitlines() == [
        "mirrorlab: error: no 10x7 chessboard found in 4 images; the sb corner detector finds it in 4 of them: "
        "rerun with --detector sb (detector = \"sb\" in a recipe step, method=\"sb\" in Python)"]
    assert json.loads(_ok(run_cli("calibrate", "--images", str(views), "--pattern", "10x7", "--square", "25",
                                  "--detector", "sb", "--json", "--no-progress")))["found"] == [
        f"view{k}.png" for k in range(4)]


def test_a_board_no_detector_finds_says_so(tmp_path: Path) -> None:
    (tmp_path / "blank").mkdir()
    cv2.imwrite(str(tmp_path / "blank" / "white.png"), np.full((120, 160), 255, np.uint8))
    proc = run_cli("calibrate", "--images", str(tmp_path / "blank"), "--pattern", "10x7", "--square", "25", "--json")
    assert proc.returncode == 1 and proc.stderr.strip().endswith(
        "check the pattern size (inner corners COLSxROWS, not squares) and the lighting (the sb corner detector "
        "finds none either)")


def test_square_takes_units(views: Path, tmp_path: Path) -> None:
    # the square sets the board's object points (mm); the intrinsics do not depend on it
    for text in ("25", "25 mm", "2.5 cm", "0.025 m"):
        session = tmp_path / f"{text.replace(' ', '')}.h5"
        _ok(run_cli("calibrate", "--images", str(views), "--pattern", "10x7", "--square", text, "--detector", "sb",
                    "--session", str(session), "--no-progress"))
        with h5py.File(session, "r") as f:
            g = f["calibration/cam"]
            assert g.attrs["square_mm"] == 25.0
            assert np.array_equal(np.unique(g["object_points"][0, :, 0]), 25.0 * np.arange(10))
    proc = run_cli("calibrate", "--images", str(views), "--pattern", "10x7", "--square", "25 s", "--json")
    assert proc.returncode == 2
    assert proc.stderr.splitlines()[-1] == ("mirrorlab: error: argument --square: wrong unit: cannot convert s (time) "
                                            "to mm (length)")


def _metres(mm: np.ndarray) -> np.ndarray:
    """Nearby values whose mm equivalent (x 1000, as the conversion multiplies) is what the mm run gets."""
    return np.round(np.asarray(mm, dtype=float) / 1000.0, 6)


def test_camera_center_takes_units(tmp_path: Path) -> None:
    film, grid = grid_points()
    pts_csv = tmp_path / "grid.csv"
    pts_csv.write_text("x,y,plane_x,plane_y\n" + "\n".join(_v([a, b, c, d]) for (a, b), (c, d)
                                                           in zip(film, grid)) + "\n")
    m = _metres(F1)
    in_mm = _ok(run_cli("calibrate", "--points", str(pts_csv), "--camera-center", _v(m * 1000.0), "--json"))
    in_m = _ok(run_cli("calibrate", "--points", str(pts_csv), "--camera-center", f"[{_v(m)}] m", "--json"))
    assert in_m == in_mm and json.loads(in_m)["camera_center"] == (m * 1000.0).tolist()
    proc = run_cli("calibrate", "--points", str(pts_csv), "--camera-center", f"[{_v(m)}] s", "--json")
    assert proc.returncode == 2 and "--camera-center: element [0]: wrong unit: cannot convert s (time)" in proc.stderr


def test_mirror_point_takes_units(tmp_path: Path) -> None:
    film, grid = grid_points()
    pts_csv = tmp_path / "grid.csv"
    pts_csv.write_text("x,y,plane_x,plane_y\n" + "\n".join(_v([a, b, c, d]) for (a, b), (c, d)
                                                           in zip(film, grid)) + "\n")
    cam = tmp_path / "cam.json"
    cam.write_text(_ok(run_cli("calibrate", "--points", str(pts_csv), "--camera-center", _v(F1), "--json")))
    U, V = plane_images(markers(3, 4))
    csv_in = _marker_csv(tmp_path / "markers.csv", U, V)
    m = _metres(G)
    out = {}
    for name, text in (("mm", _v(m * 1000.0)), ("m", f"[{_v(m)}] m"), ("cm", ", ".join(f"{float(x) * 100!r} cm" for x in m))):
        out[name] = tmp_path / f"points-{name}.csv"
        _ok(run_cli("reconstruct", "--method", "mirror", "--markers", str(csv_in), "--camera-file", str(cam),
                    f"--mirror-point={text}", f"--normal={_v(NORMAL)}", "--out", str(out[name]), "--no-progress"))
    assert out["m"].read_bytes() == out["mm"].read_bytes()
    # centimetres convert with x 10 of x 100 of the metres: equal to the mm run up to that rounding
    got, ref = np.loadtxt(out["cm"], delimiter=",", skiprows=1), np.loadtxt(out["mm"], delimiter=",", skiprows=1)
    assert np.max(np.abs(got - ref)) <= 1e-9 * np.max(np.abs(ref))  # 1-ulp input changes, well-conditioned solve


def test_lengths_and_start_take_units(tmp_path: Path) -> None:
    image = np.array([[[1.0, 1.0], [1.3, 1.4], [1.3, 2.4]]])
    csv_in = _marker_csv(tmp_path / "p.csv", image)
    out = {}
    for name, text in (("mm", "1,1"), ("cm", "0.1 cm, 0.1 cm"), ("um", "[1000, 1000] um")):
        out[name] = tmp_path / f"p-{name}.csv"
        _ok(run_cli("reconstruct", "--method", "parallel", "--markers", str(csv_in), "--lengths", text, "--signs",
                    "1,-1", "--magnification", "1", "--out", str(out[name]), "--no-progress"))
    assert out["cm"].read_bytes() == out["mm"].read_bytes() == out["um"].read_bytes()

    cam = CentralCamera(2687.0, 54.0, np.radians(12.0))
    start = np.array([100.0, 50.0, 2500.0])
    z = np.sqrt(300.0 ** 2 - 200.0 ** 2 - 100.0 ** 2)
    chain = start + np.array([[200.0, 100.0, -z], [400.0, 0.0, 0.0]])
    csv_in = _marker_csv(tmp_path / "c.csv", cam.project(chain)[None])
    for name, lengths, first in (("mm", "300,300", "100,50,2500"), ("m", "[0.3, 0.3] m", "[10, 5, 250] cm")):
        out[name] = tmp_path / f"c-{name}.csv"
        _ok(run_cli("reconstruct", "--method", "central", "--markers", str(csv_in), "--lengths", lengths,
                    "--start", first, "--signs=-1,1", "--a", "2687", "--f", "54", "--alpha", "12 deg",
                    "--out", str(out[name]), "--no-progress"))
    assert out["m"].read_bytes() == out["mm"].read_bytes()
    got = np.loadtxt(out["mm"], delimiter=",", skiprows=1, usecols=(2, 3, 4))
    assert np.max(np.abs(got - chain)) <= 1e-6 * 2500.0  # the chain from its start, as imaged


def _length_options() -> set[tuple[str, str]]:
    """(command, option) of every hand-written option of the ``mirrorlab`` CLI whose help says mm."""
    from mirrorlab.core.cli import build_parser

    found = set()

    def walk(parser: argparse.ArgumentParser, path: str) -> None:
        for action in parser._actions:
            if isinstance(action, argparse._SubParsersAction):
                for name, sub in action.choices.items():
                    walk(sub, f"{path} {name}".strip())
            elif action.option_strings and not action.dest.startswith("param__") and "[mm" in (action.help or ""):
                found.add((path, action.option_strings[0]))

    walk(build_parser(), "")
    return found


def test_every_hand_written_length_option_is_tested_here_or_in_kinematics_plugin() -> None:
    # options generated from typed parameters (add_parameter_options) convert units by construction
    assert _length_options() == {("calibrate", "--square"), ("calibrate", "--camera-center"),
                                 ("reconstruct", "--mirror-point"), ("reconstruct", "--lengths"),
                                 ("reconstruct", "--start"), ("retarget run", "--scale"),
                                 ("mechanisms four-bar", "--reference")}  # tests/plugins/mechanisms/test_cli_algorithms.py
