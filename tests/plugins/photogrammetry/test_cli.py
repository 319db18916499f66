"""``mirrorlab calibrate`` / ``mirrorlab reconstruct`` through real subprocesses and real files."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import h5py
import numpy as np
import pytest
from mirrorlab.core import Session
from mirrorlab.plugins.photogrammetry.camera_arrays import camera_from_arrays, pinhole_arrays
from mirrorlab.plugins.photogrammetry.csvio import read_points_csv
from mirrorlab.plugins.photogrammetry.mirror import reflect

from tests.plugins.photogrammetry.bounds import (
    UNDISTORT_TOL,
    map_roundoff,
    normal_roundoff,
    plane_ray_error,
    triangulation_condition,
    triangulation_roundoff,
)
from tests.support import SHARED_DATA, run_cli
from tests.tolerances import abs_err, roundoff

from .scenes import F1, NORMAL, G, grid_points, markers, pinhole_camera, plane_images

CHESS = SHARED_DATA / "calibration" / "chessboard_pycalib"


def _v(values) -> str:
    return ",".join(f"{float(x):.17g}" for x in values)


def _marker_csv(path: Path, real: np.ndarray, virt: np.ndarray | None = None) -> Path:
    rows = ["frame,marker,x,y" + (",xv,yv" if virt is not None else "")]
    for f in range(real.shape[0]):
        for m in range(real.shape[1]):
            cells = [f"{v:.17g}" if np.isfinite(v) else "" for v in real[f, m]]
            if virt is not None:
                cells += [f"{v:.17g}" if np.isfinite(v) else "" for v in virt[f, m]]
            rows.append(",".join([str(f), str(m), *cells]))
    path.write_text("\n".join(rows) + "\n")
    return path


@pytest.mark.data
def test_calibrate_real_chessboard_photos(tmp_path: Path) -> None:
    """pycalib's 29 photos, 10x7 inner corners: fx, fy within 1 % of 1329.34, RMS <= 0.5 px."""
    session = tmp_path / "cal.h5"
    r = run_cli("calibrate", "--images", str(CHESS), "--pattern", "10x7", "--square", "160", "--fix-aspect-ratio",
                "--session", str(session), "--json", "--no-progress")
    assert r.returncode == 0, r.stderr
    doc = json.loads(r.stdout)
    K = np.array(doc["camera_matrix"])
    # shared/data README section 3: the published K within about 1 %, RMS below 0.5 px
    assert K[0, 0] == pytest.approx(1329.34, rel=0.01) and K[1, 1] == pytest.approx(1329.34, rel=0.01)
    assert doc["rms"] <= 0.5 and doc["model"] == "pinhole" and len(doc["found"]) == 29
    with Session.open(session) as s:
        g, attrs = s.read_group("calibration/cam"), s.attributes("calibration/cam")
        assert attrs["result"] == "/results/calibrate_pinhole/run-0001" and attrs["model"] == "pinhole"
        assert g["image_points"].shape == (29, 70, 2)
        np.testing.assert_array_equal(g["camera_matrix"], K)  # JSON writes repr(float): exact


def test_calibrate_points_then_reconstruct_mirror_csv(tmp_path: Path) -> None:
    film, grid = grid_points()
    pts_csv = tmp_path / "grid.csv"
    pts_csv.write_text("x,y,plane_x,plane_y\n" + "\n".join(_v([a, b, c, d]) for (a, b), (c, d)
                                                           in zip(film, grid)) + "\n")
    r = run_cli("calibrate", "--points", str(pts_csv), "--camera-center", _v(F1), "--json")
    assert r.returncode == 0, r.stderr
    cam_json = tmp_path / "cam.json"
    cam_json.write_text(r.stdout)
    doc = json.loads(r.stdout)
    arrays = {k: np.asarray(v) for k, v in doc.items() if k.startswith(("plane_", "camera_"))}
    cal = dataclasses.replace(camera_from_arrays(arrays), condition=doc["condition"])
    plane = float(np.abs(grid).max())
    assert doc["rms"] <= map_roundoff(cal, film, plane)  # exact model: the fit's rounding (CSV written with %.17g)

    P = markers(4, 5)
    U, V = plane_images(P)
    U[2, 3] = np.nan
    csv_in = _marker_csv(tmp_path / "markers.csv", U, V)
    out, session = tmp_path / "points.csv", tmp_path / "rec.h5"
    r = run_cli("reconstruct", str(session), "--method", "mirror", "--markers", str(csv_in), "--camera-file",
                str(cam_json), f"--mirror-point={_v(G)}", f"--normal={_v(NORMAL)}",
                "--out", str(out), "--no-progress")
    assert r.returncode == 0, r.stderr
    assert "19 of 4 x 5 markers reconstructed" in r.stdout
    got, extra = read_points_csv(out)  # %.17g: the doubles themselves
    expect = P.copy()
    expect[2, 3] = np.nan
    assert np.array_equal(np.isnan(got), np.isnan(expect))
    # rays from the plane map (its rounding turns them), triangulated at their angles; F1, F2 and the
    # depths are ~1.6e3 mm
    ray_error = plane_ray_error(cal, np.r_[U.reshape(-1, 2), V.reshape(-1, 2)], plane)
    F2 = reflect(F1, G, NORMAL)
    scale = max(np.abs(F1).max(), np.abs(F2).max(), np.linalg.norm(P - F2, axis=-1).max())
    bound = triangulation_roundoff(np.cos(extra["angle"]), scale, ray_error=ray_error)
    assert abs_err(got, expect) <= bound
    assert np.nanmax(extra["gap"]) <= bound
    with Session.open(session) as s:
        (ref,) = s.results("reconstruct_mirror")
        res = s.result(ref)
        assert res.attrs["status"] == "ok" and res.attrs["inputs"]["real_xy"].startswith("sha256:")
        assert abs_err(res.outputs["points"], expect) <= bound  # NaN where the marker was not seen


def test_reconstruct_from_session_datasets_and_calibration_group(tmp_path: Path) -> None:
    cam = pinhole_camera()
    P = markers(3, 4, seed=11)
    flat = P.reshape(-1, 3)
    path = tmp_path / "s.h5"
    with Session.create(path) as s:
        s.write_group("calibration/cam", pinhole_arrays(cam))
        s.write_group("truth/markers", {"real_xy": cam.project(flat).reshape(3, 4, 2),
                                        "virtual_xy": cam.project(reflect(flat, G, NORMAL)).reshape(3, 4, 2),
                                        "mirror_point": G})
    r = run_cli("reconstruct", str(path), "--method", "mirror", "--calibration", "/calibration/cam",
                "--input", "real_xy=/truth/markers/real_xy", "--input", "virtual_xy=/truth/markers/virtual_xy",
                "--mirror-point", "/truth/markers/mirror_point", "--json", "--no-progress")
    assert r.returncode == 0, r.stderr
    assert json.loads(r.stdout)["result"] == "/results/reconstruct_mirror/run-0001"
    with h5py.File(path, "r") as f:
        g = f["results/reconstruct_mirror/run-0001"]
        assert json.loads(g.attrs["inputs"])["camera_matrix"] == "/calibration/cam/camera_matrix"
        # the normal estimated from the data (rays through cv2.undistortPoints), then the triangulation;
        # a normal off by dn turns the mirror ray by 2 dn and moves F2 by 4 |F1 - G| dn
        flat = P.reshape(-1, 3)
        dn = normal_roundoff(flat - F1, reflect(flat, G, NORMAL) - F1, UNDISTORT_TOL)
        F2 = reflect(F1, G, NORMAL)
        scale = max(np.abs(F1).max(), np.abs(F2).max(), np.linalg.norm(P - F2, axis=-1).max())
        cos = np.cos(g["angle"][()])
        bound = (triangulation_roundoff(cos, scale, ray_error=UNDISTORT_TOL)
                 + triangulation_condition(cos) * (2 * scale + 4 * np.linalg.norm(F1 - G)) * dn)
        assert abs_err(g["points"][()], P) <= bound
        assert np.max(np.abs(g["normal"][()] - NORMAL)) <= dn


def test_reconstruct_parallel_csv_to_csv(tmp_path: Path) -> None:
    # frame 0, link 2: projected length 1 + 1e-7 > 1 mm, within the clamp tolerance: Z step 0, flagged
    image = np.array([[[1.0, 1.0], [1.3, 1.4], [1.3, 2.4000001]], [[0.0, 0.0], [0.0, 0.5], [np.nan, np.nan]]])
    out = tmp_path / "p.csv"
    r = run_cli("reconstruct", "--method", "parallel", "--markers", str(_marker_csv(tmp_path / "m.csv", image)),
                "--lengths", "1,1", "--signs", "1,-1", "--magnification", "1", "--out", str(out), "--no-progress")
    assert r.returncode == 0, r.stderr
    got, extra = read_points_csv(out)
    z1 = np.sqrt(1 - 0.25)
    # differences of the parsed decimals (|x| <= 2.4) and sqrt(1 - 0.25) without cancellation: a few
    # roundings; the clamped link adds exactly 0 to Z
    atol = roundoff(scale=2.4, ops=6)
    np.testing.assert_allclose(got[0], [[0, 0, 0], [0.3, 0.4, np.sqrt(0.75)], [0.3, 1.4000001, np.sqrt(0.75)]],
                               rtol=0, atol=atol)
    np.testing.assert_allclose(got[1, :2], [[0, 0, 0], [0, 0.5, z1]], rtol=0, atol=atol)
    assert np.isnan(got[1, 2]).all()
    assert extra["segment_in_image_plane"][0, 2] == 1.0  # the second link lies in the image plane


def test_malformed_csv_exits_2_naming_file_line_and_reason(tmp_path: Path) -> None:
    bad = tmp_path / "bad.csv"
    bad.write_text("# two markers\nframe,marker,x,y,xv,yv\n0,0,1,2,3,4\n0,1,1,abc,3,4\n")
    r = run_cli("reconstruct", "--method", "mirror", "--markers", str(bad), "--out", str(tmp_path / "o.csv"),
                "--mirror-point", "0,0,0")
    assert r.returncode == 2
    assert f"{bad}: line 4: column y: 'abc' is not a number" in r.stderr
    missing = tmp_path / "short.csv"
    missing.write_text("frame,marker,x\n0,0,1\n")
    r = run_cli("reconstruct", "--method", "parallel", "--markers", str(missing), "--out", str(tmp_path / "o.csv"))
    assert r.returncode == 2 and f"{missing}: line 1: header frame,marker,x lacks the column(s) y" in r.stderr


def test_option_of_another_method_is_a_usage_error(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from mirrorlab.core.cli import main

    code = main(["reconstruct", "--method", "parallel", "--markers", "m.csv", "--out", "o.csv",
                 "--triangulation", "optimal"])
    assert code == 2 and "--triangulation: does not apply to reconstruct_parallel" in capsys.readouterr().err


def test_degenerate_geometry_exits_1_naming_frame_and_marker(tmp_path: Path) -> None:
    cam = pinhole_camera()
    P = markers(3, 2, seed=2)
    foot = F1 - ((F1 - G) @ NORMAL) * NORMAL
    P[1, 1] = F1 + 0.4 * (foot - F1)  # on the camera's normal line to the mirror
    flat = P.reshape(-1, 3)
    csv_in = _marker_csv(tmp_path / "m.csv", cam.project(flat).reshape(3, 2, 2),
                         cam.project(reflect(flat, G, NORMAL)).reshape(3, 2, 2))
    cam_json = tmp_path / "cam.json"
    cam_json.write_text(json.dumps({k: v.tolist() for k, v in pinhole_arrays(cam).items()}))
    session = tmp_path / "s.h5"
    r = run_cli("reconstruct", str(session), "--method", "mirror", "--markers", str(csv_in), "--camera-file",
                str(cam_json), f"--mirror-point={_v(G)}", f"--normal={_v(NORMAL)}",
                "--no-progress")
    assert r.returncode == 1
    assert "DegenerateGeometry: frame 1 marker 1:" in r.stderr and "rays are parallel" in r.stderr
    with Session.open(session) as s:  # the failed run is stored, with its error
        assert [ref.status for ref in s.results("reconstruct_mirror")] == ["failed"]


def test_central_with_marker_k_imaged_too_names_the_mismatch(tmp_path: Path) -> None:
    """N + 1 markers (K included) for N lengths: one clear line naming lengths and image_xy, not numpy's
    broadcasting error; a failed algorithm run, exit 1."""
    from mirrorlab.plugins.photogrammetry.central import CentralCamera

    cam = CentralCamera(2687.0, 54.0, np.radians(12.0))
    z = np.sqrt(300.0 ** 2 - 200.0 ** 2 - 100.0 ** 2)
    chain = cam.K + np.array([[0.0, 0.0, 0.0], [200.0, 100.0, -z], [400.0, 0.0, 0.0]])   # K, markers 1, 2
    csv_in = _marker_csv(tmp_path / "k.csv", cam.project(chain)[None])
    r = run_cli("reconstruct", "--method", "central", "--markers", str(csv_in), "--lengths", "300,300",
                "--signs=-1,1", "--a", "2687", "--f", "54", "--alpha", "12 deg", "--out", str(tmp_path / "c.csv"),
                "--no-progress")
    assert r.returncode == 1 and len(r.stderr.strip().splitlines()) == 1
    assert ("InvalidArgument: lengths has shape (2,), but image_xy has 1 frame(s) of 3 markers (1..3; K, marker 0, "
            "is not imaged): give 3 per frame") in r.stderr
    assert "if its first marker is K, leave it out" in r.stderr and "broadcast" not in r.stderr
    r = run_cli("reconstruct", "--method", "parallel", "--markers", str(csv_in), "--lengths", "300,300,300",
                "--signs=1,1,1", "--out", str(tmp_path / "p.csv"), "--no-progress")
    assert r.returncode == 1 and ("lengths has shape (3,), but image_xy has 1 frame(s) of 3 markers (0..2): give 2 "
                                  "per frame") in r.stderr


@pytest.mark.data
def test_chessboard_square_is_required(tmp_path: Path) -> None:
    """No silent 1 mm squares: a calibration without --square would be off in scale by the square size."""
    r = run_cli("calibrate", "--images", str(CHESS), "--pattern", "10x7", "--json", "--no-progress")
    assert r.returncode == 2
    assert "--square: required with --images: the chessboard square side in mm" in r.stderr


def test_calibrate_names_every_missing_option_at_once() -> None:
    """All that is missing in one run, one line each (it named one per run: --json, then --pattern, then --square)."""
    r = run_cli("calibrate", "--images", str(CHESS))
    assert r.returncode == 2
    assert [line.split(": ")[2] for line in r.stderr.splitlines()] == ["calibrate", "--pattern", "--square"], r.stderr
    assert "--session FILE and/or --json" in r.stderr
    r = run_cli("calibrate", "--points", "grid.csv")
    assert r.returncode == 2
    assert [line.split(": ")[2] for line in r.stderr.splitlines()] == ["calibrate", "--camera-center"], r.stderr


def test_missing_mirror_point_names_the_option(tmp_path: Path) -> None:
    cam = pinhole_camera()
    flat = markers(2, 2, seed=3).reshape(-1, 3)
    path = tmp_path / "s.h5"
    with Session.create(path) as s:
        s.write_group("calibration/cam", pinhole_arrays(cam))
        s.write_group("m", {"real_xy": cam.project(flat).reshape(2, 2, 2),
                            "virtual_xy": cam.project(reflect(flat, G, NORMAL)).reshape(2, 2, 2)})
    r = run_cli("reconstruct", str(path), "--method", "mirror", "--calibration", "/calibration/cam",
                "--input", "real_xy=/m/real_xy", "--input", "virtual_xy=/m/virtual_xy", "--no-progress")
    assert r.returncode == 2
    assert ("mirror_point: --method mirror needs (3,) point G on the mirror [mm]; "
            "pass --mirror-point V1,V2,...|/DATASET") in r.stderr
    with Session.open(path) as s:  # refused before running: nothing stored
        assert s.results("reconstruct_mirror") == []
