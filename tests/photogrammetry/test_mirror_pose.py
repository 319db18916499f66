"""Mirror pose from the scene: direct + mirrored view, and Takahashi et al. (CVPR 2012)."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from mirrorlab.plugins.photogrammetry import (
    calibrate_mirrors_takahashi,
    mirror_pose_from_views,
    reflect,
    triangulate_mirror,
)
from mirrorlab.plugins.photogrammetry.errors import CalibrationError, DegenerateGeometry

from tests.support import SHARED_DATA

DATA = SHARED_DATA / "mirror" / "takahashi_mirror_chessboard"


def _load_takahashi():
    K = np.loadtxt(DATA / "camera.txt", delimiter=",")
    X = np.loadtxt(DATA / "model.txt")
    xs = [np.loadtxt(DATA / f"input{i}.txt") for i in range(1, 6)]
    return K, X, xs


def _board(nx: int = 10, ny: int = 7, pitch: float = 27.5) -> np.ndarray:
    g = np.stack(np.meshgrid(np.arange(nx), np.arange(ny)), -1).reshape(-1, 2) * pitch
    return np.c_[g, np.zeros(len(g))]


def _project_cam(Y: np.ndarray, K: np.ndarray) -> np.ndarray:
    h = Y @ K.T
    return h[:, :2] / h[:, 2:]


# ---------------------------------------------------------------- Takahashi data (real photos)


@pytest.mark.data
def test_takahashi_data_reprojection() -> None:
    """Five photos through a mirror: ≤ 0.5 px with radial distortion refined (published 0.354 px)."""
    K, X, xs = _load_takahashi()
    fixed = calibrate_mirrors_takahashi(X, xs, K)
    # K fixed, no distortion: the pycalib reference (bundle adjustment) prints 0.64 px (mean error)
    assert fixed.reprojection_mean == pytest.approx(0.64, abs=0.02)
    cal = calibrate_mirrors_takahashi(X, xs, K, refine_distortion=True)
    print(f"Takahashi: linear {cal.linear_rms:.2f} px RMS; refined K-fixed {fixed.reprojection_rms:.3f} px RMS "
          f"({fixed.reprojection_mean:.3f} mean); with k1,k2 {cal.reprojection_rms:.3f} px RMS "
          f"({cal.reprojection_mean:.3f} mean), k = {cal.dist_coeffs[:2]}")
    assert cal.reprojection_rms <= 0.5
    assert np.all(cal.distances > 0)
    assert np.allclose(np.linalg.norm(cal.normals, axis=1), 1.0)
    assert np.all(cal.mirror_points @ cal.normals.T < 0) or np.all(np.einsum("ij,ij->i", -cal.mirror_points,
                                                                          cal.normals) > 0)
    assert np.linalg.det(cal.rotation) == pytest.approx(1.0)
    # the board lies between the camera and each mirror (reflecting side)
    Y = X @ cal.rotation.T + cal.translation
    assert np.all(Y @ cal.normals.T + cal.distances > 0)


@pytest.mark.data
def test_takahashi_detected_corners_are_flipped() -> None:
    """A chessboard detector returns each row of a mirrored board reversed."""
    K, X, xs = _load_takahashi()
    detected = []
    for i in range(1, 6):
        img = cv2.imread(str(DATA / f"input{i}.jpg"), cv2.IMREAD_GRAYSCALE)
        ok, corners = cv2.findChessboardCorners(img, (10, 7))
        assert ok
        corners = corners.reshape(7, 10, 2)
        assert np.abs(corners.reshape(-1, 2) - xs[i - 1]).max() > 100  # detector order ≠ model order
        flipped = corners[:, ::-1].reshape(-1, 2)
        assert np.abs(flipped - xs[i - 1]).max() < 3.0  # listed points are undistorted, detector's are not
        detected.append(flipped)
    cal = calibrate_mirrors_takahashi(X, detected, K, refine_distortion=True)
    assert cal.reprojection_rms < 1.0


# ---------------------------------------------------------------- Takahashi synthetic round trip


def _synthetic_mirrors(seed: int):
    rng = np.random.default_rng(seed)
    K = np.array([[2400.0, 0, 800], [0, 2400.0, 600], [0, 0, 1]])
    X = _board()
    R = cv2.Rodrigues(np.array([np.pi, 0, 0]) + rng.normal(0, 0.15, 3))[0]  # board faces the mirrors
    T = np.array([-120.0, -80.0, -150.0]) + rng.normal(0, 20, 3)
    tilt = rng.normal(0, 0.25, (4, 2))
    normals = np.c_[tilt, -np.ones(4)]
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    dists = rng.uniform(500, 800, 4)
    Y = X @ R.T + T
    imgs = [_project_cam(Y - 2 * ((Y @ n) + d)[:, None] * n, K) for n, d in zip(normals, dists)]
    return K, X, R, T, normals, dists, imgs


def test_takahashi_synthetic_round_trip() -> None:
    K, X, R, T, normals, dists, imgs = _synthetic_mirrors(0)
    for views in (slice(0, 3), slice(0, 4)):  # minimal three mirrors and an overdetermined four
        cal = calibrate_mirrors_takahashi(X, imgs[views], K)
        np.testing.assert_allclose(cal.normals, normals[views], atol=1e-9)
        np.testing.assert_allclose(cal.distances, dists[views], rtol=1e-9)
        np.testing.assert_allclose(cal.rotation, R, atol=1e-9)
        np.testing.assert_allclose(cal.translation, T, rtol=1e-9, atol=1e-7)
        assert cal.reprojection_rms < 1e-6 and cal.linear_rms < 1e-3  # PnP stops at its own tolerance
    with pytest.raises(CalibrationError, match="at least 3"):
        calibrate_mirrors_takahashi(X, imgs[:2], K)
    with pytest.raises(DegenerateGeometry, match="tilt the mirror"):
        calibrate_mirrors_takahashi(X, [imgs[0], imgs[0], imgs[1]], K)


def test_takahashi_synthetic_noise() -> None:
    K, X, R, T, normals, dists, imgs = _synthetic_mirrors(1)
    rng = np.random.default_rng(11)
    noisy = [x + rng.normal(0, 0.3, x.shape) for x in imgs]
    cal = calibrate_mirrors_takahashi(X, noisy, K)
    assert 0.2 < cal.reprojection_rms < 0.45  # ≈ 0.3·√2 px minus the fitted degrees of freedom
    assert np.degrees(np.arccos(np.clip(np.einsum("ij,ij->i", cal.normals, normals), -1, 1))).max() < 0.5


# ---------------------------------------------------------------- direct + mirrored view


def _direct_and_mirror_scene():
    K = np.array([[1500.0, 0, 640], [0, 1500.0, 480], [0, 0, 1]])
    X = _board(8, 6, 30.0)
    n = np.array([0.8, 0.1, 0.6])
    n /= np.linalg.norm(n)
    Gm = np.array([-250.0, 0.0, 0.0])
    C = np.array([150.0, 300.0, 1500.0])  # camera in the board (world) frame
    target = 0.5 * (X.mean(0) + reflect(X.mean(0), Gm, n))
    z = (target - C) / np.linalg.norm(target - C)
    x = np.cross([0.0, 1.0, 0.0], z)
    x /= np.linalg.norm(x)
    R = np.stack([x, np.cross(z, x), z])
    t = -R @ C

    def img(P):
        return _project_cam(P @ R.T + t, K)

    return K, X, n, Gm, C, R, t, img


def test_mirror_pose_from_views_exact_and_noisy() -> None:
    K, X, n, Gm, C, R, t, img = _direct_and_mirror_scene()
    x1, x2 = img(X), img(reflect(X, Gm, n))
    pose = mirror_pose_from_views(X, x1, x2, K)
    np.testing.assert_allclose(pose.normal, n, atol=1e-9)
    np.testing.assert_allclose(pose.camera_center, C, rtol=1e-9, atol=1e-7)
    assert abs((pose.mirror_point - Gm) @ n) < 1e-7  # G lies on the true plane
    np.testing.assert_allclose(pose.virtual_center, reflect(C, Gm, n), atol=1e-6)
    assert pose.reprojection_rms < 1e-6 and pose.initial_rms < 1e-3  # PnP stops at its own tolerance
    # with 0.3 px noise: refine, then triangulate further markers through the estimated mirror
    rng = np.random.default_rng(4)
    pose = mirror_pose_from_views(X, x1 + rng.normal(0, 0.3, x1.shape), x2 + rng.normal(0, 0.3, x2.shape), K)
    assert pose.reprojection_rms <= pose.initial_rms + 1e-12
    assert np.degrees(np.arccos(min(1.0, pose.normal @ n))) < 0.5
    V = X[::5] + [0.0, 0.0, 40.0]
    Kinv = np.linalg.inv(K)
    rays = lambda xy: np.c_[xy, np.ones(len(xy))] @ Kinv.T @ pose.rotation  # noqa: E731
    r = triangulate_mirror(pose.camera_center, pose.mirror_point, pose.normal, rays(img(V)),
                           rays(img(reflect(V, Gm, n))))
    assert np.sqrt(np.mean(np.sum((r.points - V) ** 2, axis=1))) < 3.0
