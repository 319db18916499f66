"""Camera models (spec §8): thesis plane calibration, projective map, OpenCV pinhole, real chessboard."""

from __future__ import annotations

import doctest

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from mirrorlab.plugins.photogrammetry import cameras
from mirrorlab.plugins.photogrammetry.cameras import (
    CameraModel,
    PinholeCamera,
    calibrate_pinhole,
    chessboard_object_points,
    find_chessboard_corners,
    fit_plane_calibration,
    quadratic_design_matrix,
)
from mirrorlab.plugins.photogrammetry.errors import CalibrationError, DegenerateGeometry

from tests.plugins.photogrammetry.bounds import map_roundoff
from tests.support import SHARED_DATA
from tests.tolerances import cond, roundoff

CHESS = SHARED_DATA / "calibration" / "chessboard_pycalib"

F1 = np.array([435.68, 202.6, 1442.024])
GX = np.array([-849, -728.5, -607.5, -485, -364, -241.5, -120.5, 0, 121, 243, 365, 486, 607], float)
GY = np.array([-486, -365, -244, -122, 0, 121, 243], float)
GRID = np.stack(np.meshgrid(GX, GY, indexing="ij"), -1).reshape(-1, 2)  # 91 points, I outer
PLANE = float(np.abs(GRID).max())  # mm, magnitude of the plane coordinates


def rot(axis: str, a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    return {"x": np.array([[1, 0, 0], [0, c, -s], [0, s, c]]),
            "y": np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])}[axis]


def _camera_frame(points, center, R_tilt):
    """Camera coordinates of ``points`` for a camera at ``center`` looking along -Z, tilted by R_tilt."""
    R_tilt = np.eye(3) if R_tilt is None else R_tilt
    Rc = np.array([[1, 0, 0], [0, -1, 0], [0, 0, -1.0]]) @ R_tilt.T
    return (np.asarray(points, float) - center) @ Rc.T


def film_image(points, center, R_tilt=None, focal=30.0):
    """Pinhole at ``center`` looking along -Z (camera x = X, y = -Y), tilted by R_tilt; film mm."""
    v = _camera_frame(points, center, R_tilt)
    return focal * v[:, :2] / v[:, 2:3]


def film_gain(points, center, R_tilt=None, focal=30.0):
    """Largest |d film / d point| (film mm per mm) of :func:`film_image` at ``points``.

    d(f v_xy / v_z)/dv = (f / v_z) [I, -v_xy / v_z] has norm <= f (1 + |v_xy / v_z|) / v_z.
    """
    v = _camera_frame(points, center, R_tilt)
    return float(np.max(focal * (1 + np.linalg.norm(v[:, :2] / v[:, 2:3], axis=1)) / v[:, 2]))


def on_plane(points, center, plane_z):
    """Where the rays from ``center`` through ``points`` meet the plane Z = plane_z (what project() inverts)."""
    P = np.asarray(points, float)
    return center + ((plane_z - center[2]) / (P[:, 2] - center[2]))[:, None] * (P - center)


def test_doctests():
    assert doctest.testmod(cameras).failed == 0


# ---- quadratic (thesis) -----------------------------------------------------------------------


@settings(max_examples=25, deadline=None)
@given(cx=st.floats(-500, 500), cy=st.floats(-500, 500), h=st.floats(300, 5000), f=st.floats(5, 100),
       roll=st.floats(-np.pi, np.pi), zc=st.floats(-200, 200))
def test_quadratic_round_trip_parallel_film(cx, cy, h, f, roll, zc):
    """Film plane parallel to the calibration plane: the map is exact, rays and project round-trip."""
    F = np.array([cx, cy, zc + h])
    Rz = np.array([[np.cos(roll), -np.sin(roll), 0], [np.sin(roll), np.cos(roll), 0], [0, 0, 1]])
    P = np.c_[GRID, np.full(len(GRID), zc)]
    img = film_image(P, F, Rz, f)
    cal = fit_plane_calibration(img, GRID, zc, F)
    # exact map: the residual is the rounding of the least-squares fit
    assert cal.max_residual <= map_roundoff(cal, img, PLANE)
    rng = np.random.default_rng(0)
    Q = np.c_[rng.uniform(-600, 400, (40, 2)), rng.uniform(zc + 0.05 * h, zc + 0.9 * h, 40)]
    u_true = (Q - F) / np.linalg.norm(Q - F, axis=1, keepdims=True)
    qimg = film_image(Q, F, Rz, f)
    # a plane point off by delta moves the ray by <= delta / |C - F|, and |C - F| >= h
    assert np.abs(cal.rays(qimg) - u_true).max() <= map_roundoff(cal, qimg, PLANE) / h
    # project() inverts the map: delta on the plane is delta * film_gain on the film
    C = on_plane(Q, F, zc)
    assert np.abs(cal.project(Q) - qimg).max() <= map_roundoff(cal, qimg, PLANE) * film_gain(C, F, Rz, f)


@pytest.mark.parametrize("axis,deg,expected", [("x", 0, 0.0), ("x", 5, 0.21), ("x", 15, 2.2),
                                               ("y", 5, 0.58), ("y", 15, 4.8)])
def test_quadratic_tilt_residuals_reproduce_spec(axis, deg, expected):
    img = film_image(np.c_[GRID, np.zeros(91)], F1, rot(axis, np.radians(deg)))
    cal = fit_plane_calibration(img, GRID, 0.0, F1)
    # the spec prints 2 significant digits: one unit of the last digit
    assert cal.max_residual == pytest.approx(expected, abs=0.01 if expected < 1 else 0.1)
    proj = fit_plane_calibration(img, GRID, 0.0, F1, model="projective")
    assert proj.max_residual <= map_roundoff(proj, img, PLANE)  # exact model: rounding only


def test_normal_equations_equal_lstsq_and_thesis_coefficients():
    img = film_image(np.c_[GRID, np.zeros(91)], F1, rot("x", np.radians(10)))
    a = fit_plane_calibration(img, GRID, 0.0, F1)
    b = fit_plane_calibration(img, GRID, 0.0, F1, solver="normal_equations")
    # the normal equations in raw film coordinates square the design matrix's condition number
    # (kappa(N) ~ 8e6 here); back in normalised coordinates through T^-T (_scaled_to_raw)
    Phi = quadratic_design_matrix(img)
    T = cameras._scaled_to_raw(a.center, a.scale)
    kappa_normal = cond(Phi.T @ Phi) * cond(T)
    assert np.abs(b.params - a.params).max() <= roundoff(cond=kappa_normal, scale=np.abs(a.params).max())
    bb, cc = a.thesis_coefficients
    # the same polynomial in raw coordinates: rounding of |Phi| |T^T| |p| (componentwise product bound)
    terms = np.abs(Phi) @ np.abs(T.T) @ np.abs(a.params)
    assert np.all(np.abs(Phi @ np.c_[bb, cc] - a.map_to_plane(img)) <= roundoff(scale=terms, ops=12))
    # (3.19) normal matrix as printed (with the corrected entries) equals Phi^T Phi
    x, y = img.T
    S = lambda p, q: np.sum(x**p * y**q)  # noqa: E731
    N = np.array([[91, S(1, 0), S(0, 1), S(1, 1), S(2, 0), S(0, 2)],
                  [0, S(2, 0), S(1, 1), S(2, 1), S(3, 0), S(1, 2)],
                  [0, 0, S(0, 2), S(1, 2), S(2, 1), S(0, 3)],
                  [0, 0, 0, S(2, 2), S(3, 1), S(1, 3)],
                  [0, 0, 0, 0, S(4, 0), S(2, 2)],
                  [0, 0, 0, 0, 0, S(0, 4)]])
    N = np.triu(N) + np.triu(N, 1).T
    # two orders of summing 91 products: <= 91 eps (|Phi|^T |Phi|) per entry (odd powers cancel)
    assert np.all(np.abs(N - Phi.T @ Phi) <= roundoff(scale=np.abs(Phi).T @ np.abs(Phi), ops=91))
    assert np.abs(np.linalg.solve(N, Phi.T @ GRID[:, 0]) - bb).max() <= roundoff(cond=cond(N), scale=np.abs(bb).max())


def test_calibration_errors():
    img = film_image(np.c_[GRID, np.zeros(91)], F1)
    with pytest.raises(CalibrationError, match=r"only 5 calibration points.*at least 6"):
        fit_plane_calibration(img[:5], GRID[:5], 0.0, F1)
    line = np.c_[np.linspace(0, 1, 10), 2 * np.linspace(0, 1, 10)]
    with pytest.raises(CalibrationError, match="collinear"):
        fit_plane_calibration(line, line * 100, 0.0, F1)
    with pytest.raises(CalibrationError, match="collinear"):
        fit_plane_calibration(line, line * 100, 0.0, F1, model="projective")
    with pytest.raises(CalibrationError, match="at least 4"):
        fit_plane_calibration(img[:3], GRID[:3], 0.0, F1, model="projective")
    with pytest.raises(DegenerateGeometry, match="calibration plane"):
        fit_plane_calibration(img, GRID, F1[2], F1)
    cal = fit_plane_calibration(img, GRID, 0.0, F1)
    assert cal.extrapolated(np.array([[0.0, 0.0], [1e3, 1e3]])).tolist() == [False, True]


# ---- projective ---------------------------------------------------------------------------------


@settings(max_examples=20, deadline=None)
@given(tx=st.floats(-30, 30), ty=st.floats(-30, 30), f=st.floats(10, 80), seed=st.integers(0, 1000))
def test_projective_round_trip_any_tilt(tx, ty, f, seed):
    R = rot("x", np.radians(tx)) @ rot("y", np.radians(ty))
    img = film_image(np.c_[GRID, np.zeros(91)], F1, R, f)
    cal = fit_plane_calibration(img, GRID, 0.0, F1, model="projective")
    assert cal.max_residual <= map_roundoff(cal, img, PLANE)  # exact model: rounding only
    Q = np.c_[np.random.default_rng(seed).uniform(-500, 300, (20, 2)), np.random.default_rng(seed).uniform(50, 900, 20)]
    u = (Q - F1) / np.linalg.norm(Q - F1, axis=1, keepdims=True)
    qimg = film_image(Q, F1, R, f)
    # as in the parallel case: |C - F1| >= F1_z above the plane Z = 0; film error = plane error * gain
    assert np.abs(cal.rays(qimg) - u).max() <= map_roundoff(cal, qimg, PLANE) / F1[2]
    assert np.abs(cal.project(Q) - qimg).max() <= map_roundoff(cal, qimg, PLANE) * film_gain(on_plane(Q, F1, 0.0), F1, R, f)


def test_projective_radial_terms_recover_distortion():
    R = rot("x", np.radians(12))
    img = film_image(np.c_[GRID, np.zeros(91)], F1, R)
    c = img.mean(axis=0)
    s = np.sqrt(np.mean(np.sum((img - c) ** 2, axis=1)))
    # distort: undistorted = c + (x - c)(1 + k r^2) with r normalised by s -> invert numerically
    k = 0.02
    dist = img.copy()
    for _ in range(60):
        r2 = np.sum(((dist - c) / s) ** 2, axis=1, keepdims=True)
        dist = c + (img - c) / (1 + k * r2)
    plain = fit_plane_calibration(dist, GRID, 0.0, F1, model="projective")
    radial = fit_plane_calibration(dist, GRID, 0.0, F1, model="projective", radial_terms=1, distortion_center=c)
    assert plain.max_residual > 1.0  # k r^2 = 0.02 at r = s moves the edge points by ~1 % of 850 mm
    # the 60 fixed-point steps contract by ~2 k r^2 < 0.2 each: dist is exact to rounding
    assert radial.max_residual <= map_roundoff(radial, dist, PLANE)
    # k is one of 9 parameters: normwise forward error kappa eps |p| (|p| ~ 500 mm, k ~ 0.02)
    assert abs(radial.params[8] - k * (radial.scale / s) ** 2) <= roundoff(cond=radial.condition,
                                                                            scale=np.linalg.norm(radial.params))
    grid_gain = film_gain(np.c_[GRID, np.zeros(91)], F1, R)
    assert np.abs(radial.plane_to_image(GRID) - dist).max() <= map_roundoff(radial, dist, PLANE) * grid_gain


# ---- OpenCV pinhole ------------------------------------------------------------------------------


@settings(max_examples=20, deadline=None)
@given(rv=st.tuples(*[st.floats(-1, 1)] * 3), k1=st.floats(-0.2, 0.2), fx=st.floats(300, 3000), seed=st.integers(0, 99))
def test_pinhole_rays_project_round_trip(rv, k1, fx, seed):
    K = np.array([[fx, 0, 640], [0, 1.01 * fx, 360], [0, 0, 1]])
    dist = np.array([k1, -0.3 * k1, 1e-3, -5e-4, 0.0])
    R = cv2.Rodrigues(np.array(rv, float))[0]
    cam = PinholeCamera(K, dist, R, np.array([10.0, -20.0, 1500.0]))
    assert isinstance(cam, CameraModel)
    rng = np.random.default_rng(seed)
    d = np.c_[rng.uniform(-0.3, 0.3, (50, 2)), np.ones(50)] @ R  # directions inside the field
    P = cam.camera_center + rng.uniform(200, 3000, (50, 1)) * d
    u = (P - cam.camera_center) / np.linalg.norm(P - cam.camera_center, axis=1, keepdims=True)
    # cv2.undistortPoints iterates to 1e-14 (normalised units, = ray directions to first order);
    # rounding of pixels ~ 1e3 px divided by fx >= 300 is ~1e-15: 1e-9 checks that the two maps are
    # each other's inverse, far above both
    assert np.abs(cam.rays(cam.project(P)) - u).max() <= 1e-9


def test_calibrate_pinhole_synthetic_and_errors():
    K = np.array([[900.0, 0, 330], [0, 905.0, 250], [0, 0, 1]])
    dist = np.array([-0.1, 0.05, 0.0, 0.0, 0.0])
    obj = chessboard_object_points((9, 6), 25.0).astype(float)
    rng = np.random.default_rng(7)
    views = [(rng.uniform(-0.5, 0.5, 3), np.array([-100.0, -70.0, 600.0]) + rng.uniform(-50, 50, 3)) for _ in range(8)]
    img = [cv2.projectPoints(obj, r, t, K, dist)[0].reshape(-1, 2) for r, t in views]
    cam = calibrate_pinhole([obj] * 8, img, (640, 480))
    # calibrate_pinhole hands OpenCV float32 points: quantisation noise (same on every CPU) of
    # RMS ulp32(|x| < 1024) / sqrt(12) per coordinate, the data's only error
    quant = np.spacing(np.float32(1023.0)) / np.sqrt(12)  # 1.8e-5 px
    # a fit's RMS is about the noise's (0.5 quant here); 50 quant leaves room for where LM stops
    assert cam.rms <= 50 * quant
    # through the calibration that noise moves K by ~1e-4 px and the centre by ~1e-4 mm; the bounds
    # (0.09 px on f, 1e-2 px and mm) are ~100x that, while a model error moves K by pixels
    np.testing.assert_allclose(cam.K, K, rtol=1e-4, atol=1e-2)
    np.testing.assert_allclose(cam.camera_center, -cv2.Rodrigues(views[0][0])[0].T @ views[0][1], atol=1e-2)
    with pytest.raises(CalibrationError, match="only 2 views"):
        calibrate_pinhole([obj] * 2, img[:2], (640, 480))
    with pytest.raises(CalibrationError, match="view 1"):
        calibrate_pinhole([obj] * 3, [img[0], img[1][:4], img[2]], (640, 480))


# ---- real data: pycalib chessboard ----------------------------------------------------------------


@pytest.fixture(scope="module")
def chessboard(shared_data):
    files = sorted(CHESS.glob("*.jpg"))
    det = find_chessboard_corners(files, (10, 7), square_size=160.0)
    return det


def test_chessboard_real_data(chessboard):
    det = chessboard
    assert len(det.found) == 29 and det.image_size == (1920, 1080)
    # shared/data README section 3: reproduce the published K within about 1 %, RMS below 0.5 px
    cam = calibrate_pinhole(det.object_points, det.image_points, det.image_size, fix_aspect_ratio=True)
    assert cam.K[0, 0] == pytest.approx(1329.34, rel=0.01)
    assert cam.K[1, 1] == pytest.approx(1329.34, rel=0.01)
    assert cam.rms <= 0.5
    free = calibrate_pinhole(det.object_points, det.image_points, det.image_size)
    assert free.rms <= 0.5
    assert abs(free.K[0, 0] / 1329.34 - 1) < 0.01 and abs(free.K[1, 1] / 1329.34 - 1) < 0.01
    # rays of the detected corners pass (nearly) through the board corners of the reference view:
    # 0.38 px RMS / 1329 px = 0.016 deg per corner, the largest of 70 below 6 sigma = 0.1 deg
    P = det.object_points[0].astype(float)
    u = cam.rays(det.image_points[0])
    v = (P - cam.camera_center) / np.linalg.norm(P - cam.camera_center, axis=1, keepdims=True)
    assert np.degrees(np.arccos(np.clip(np.sum(u * v, 1), -1, 1))).max() < 0.1
