"""The ``calibrate`` and ``reconstruct`` recipe steps on real files (synthetic chessboard photos, HDF5)."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest
from mirrorlab.core import Session, get_registry
from mirrorlab.core.errors import ValidationError
from mirrorlab.core.recipes import load_recipe, run_recipe
from mirrorlab.plugins.photogrammetry.camera_arrays import pinhole_arrays
from mirrorlab.plugins.photogrammetry.mirror import reflect

from tests.plugins.photogrammetry.bounds import UNDISTORT_TOL, triangulation_roundoff
from tests.tolerances import abs_err

from .scenes import F1, NORMAL, G, markers, pinhole_camera

K = np.array([[800.0, 0, 320], [0, 800.0, 240], [0, 0, 1]])


def _board_photos(folder: Path) -> Path:
    """Five 640x480 photos of a 8x6-square board (7x5 inner corners, 20 mm squares) at known poses."""
    folder.mkdir()
    s, margin = 40, 40  # texture px per square, white margin
    board = np.kron((np.indices((6, 8)).sum(0) % 2), np.ones((s, s))).astype(np.uint8) * 255
    tex = np.pad(board, margin, constant_values=255)
    scale = 20.0 / s  # mm per texture px; first inner corner at texture (margin + s, margin + s)
    A = np.array([[scale, 0, -(margin + s) * scale], [0, scale, -(margin + s) * scale], [0, 0, 1]])
    poses = [([0.3, 0.0, 0.0], [-60., -40., 400.]), ([0.0, 0.4, 0.1], [-50., -50., 420.]),
             ([-0.3, -0.2, 0.0], [-70., -30., 380.]), ([0.2, -0.3, 0.2], [-60., -40., 450.]),
             ([-0.1, 0.3, -0.2], [-40., -50., 400.])]
    for i, (r, t) in enumerate(poses):
        R = cv2.Rodrigues(np.array(r))[0]
        H = K @ np.c_[R[:, :2], t] @ A
        img = cv2.warpPerspective(tex, H, (640, 480), flags=cv2.INTER_AREA, borderValue=255)
        cv2.imwrite(str(folder / f"view{i}.png"), cv2.GaussianBlur(img, (3, 3), 0.6))
    return folder


def test_recipe_calibrate_step_from_photos(tmp_path: Path) -> None:
    photos = _board_photos(tmp_path / "photos")
    recipe = tmp_path / "cal.toml"
    recipe.write_text(f'''
[session]
description = "calibrate from photos"

[[steps]]
action = "calibrate"
camera = "cam"
algorithm = "calibrate_pinhole"
images = "{photos}"
pattern = "7x5"
square = "2 cm"
parameters = {{ fix_aspect_ratio = true }}
''')
    out = tmp_path / "cal.h5"
    run_recipe(load_recipe(recipe), out)
    with Session.open(out) as s:
        g, attrs = s.read_group("calibration/cam"), s.attributes("calibration/cam")
        assert attrs["result"] == "/results/calibrate_pinhole/run-0001" and attrs["square_mm"] == 20.0
        Kc = g["camera_matrix"]
        # corners detected in rendered (area-resampled, blurred) photos: ~0.04 px RMS; f comes out within
        # ~0.1 %, the bounds are 5x: 0.5 % on f, 0.2 px RMS, and 5 mm on a 400 mm distance (f's 0.5 % is 2 mm)
        assert np.allclose(np.diag(Kc)[:2], 800.0, rtol=0.005) and g["rms"] < 0.2
        assert np.linalg.norm(g["translation"] - [-60., -40., 400.]) < 5.0  # mm, from the 20 mm squares


def test_recipe_validation_reports_every_problem(tmp_path: Path) -> None:
    recipe = tmp_path / "bad.toml"
    recipe.write_text('''
[[steps]]
action = "calibrate"
camera = "cam"
algorithm = "calibrate_plane"
images = "photos"
inputs = { image_xy = "relative/path", bogus = "/x" }

[[steps]]
action = "reconstruct"
method = "mirror"
parameters = { triangulation = "best" }
''')
    with pytest.raises(ValidationError) as info:
        load_recipe(recipe)
    text = str(info.value)
    for expected in ("steps.0.images", "steps.0.pattern", "steps.0.square", "steps.0.inputs.image_xy", "steps.0.inputs.bogus",
                     "steps.1.inputs.real_xy", "steps.1.parameters.triangulation"):
        assert expected in text, text


def test_reconstruct_step_uses_the_calibration_group(tmp_path: Path) -> None:
    cam = pinhole_camera()
    P = markers(3, 4, seed=4)
    flat = P.reshape(-1, 3)
    step_cls = get_registry().step("reconstruct")
    table = {"method": "mirror", "calibration": "/calibration/cam",
             "inputs": {"real_xy": "/truth/m/real_xy", "virtual_xy": "/truth/m/virtual_xy",
                        "mirror_point": "/truth/m/G", "normal": "/truth/m/n"}}
    values, problems = step_cls.validate(table, "steps.0", None, get_registry(), {})
    assert problems == []
    with Session.create(tmp_path / "s.h5") as s:
        s.write_group("calibration/cam", pinhole_arrays(cam))
        s.write_group("truth/m", {"real_xy": cam.project(flat).reshape(3, 4, 2), "G": G, "n": NORMAL,
                                  "virtual_xy": cam.project(reflect(flat, G, NORMAL)).reshape(3, 4, 2)})
        step_cls().execute(s, values)
        (ref,) = s.results("reconstruct_mirror")
        res = s.result(ref)
    assert res.attrs["inputs"]["dist_coeffs"] == "/calibration/cam/dist_coeffs"
    # rays through cv2.undistortPoints (stops at UNDISTORT_TOL), triangulated at their angles
    F2 = reflect(F1, G, NORMAL)
    scale = max(np.abs(F1).max(), np.abs(F2).max(), np.linalg.norm(P - F2, axis=-1).max())
    bound = triangulation_roundoff(np.cos(res.outputs["angle"]), scale, ray_error=UNDISTORT_TOL)
    assert abs_err(res.outputs["points"], P) <= bound
