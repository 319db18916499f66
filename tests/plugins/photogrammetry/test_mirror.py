"""Mirror method (spec §6, §7, §10): reflection, mirror normal, virtual camera, triangulation."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp
from mirrorlab.plugins.photogrammetry import (
    DegenerateGeometry,
    intersect_rays,
    mirror_normal,
    reflect,
    reflection_matrix,
    triangulate_mirror,
    triangulate_mirrors,
    virtual_camera,
)

from tests.plugins.photogrammetry.bounds import normal_roundoff, pair_planes, triangulation_roundoff
from tests.tolerances import abs_err, roundoff

# ---------------------------------------------------------------- spec §10 synthetic fixture
F1 = np.array([435.68, 202.6, 1442.024])
G = np.array([-291.62, -52.76, 487.56])
N_TRUE = np.array([np.cos(np.deg2rad(50.0)), 0.0, np.sin(np.deg2rad(50.0))])
F2_SPEC = np.array([-1105.289, 202.600, -394.432])
MARKERS = np.array([[100.0, 50.0, 300.0], [-150.0, -100.0, 200.0], [250.0, 120.0, 420.0]])
PAIRS = np.array([[0.0, 0.0, 250.0], [200.0, -150.0, 350.0], [-100.0, 100.0, 150.0], [150.0, 200.0, 300.0]])


def _mirror_rays(points: np.ndarray, center: np.ndarray, g: np.ndarray, n: np.ndarray):
    return points - center, reflect(points, g, n) - center


def test_spec_fixture_round_trip() -> None:
    """§10: n̂, F2 and all V to rounding, miss distance 0 (purely algebraic).

    The spec's 1e-12 on n̂ is tighter than the conditioning allows: PAIRS[0] sees its mirror image
    along nearly the same ray (|A_0| = 0.003), which amplifies rounding 300-fold; the bounds below
    come from the fixture's own condition numbers.
    """
    P, Pv = _mirror_rays(PAIRS, F1, G, N_TRUE)
    for method in ("lstsq", "thesis"):
        res = mirror_normal(P, Pv, mirror_point=G, camera_center=F1, method=method)
        assert np.abs(res.normal - N_TRUE).max() <= normal_roundoff(P, Pv)
        # the residual |A^ n| is a backward error: the unit A_k's rounding eps / |A_k|, without the gap
        assert res.residual <= roundoff(cond=1 / pair_planes(P, Pv)[0].min(), ops=10)
    # without G the orientation comes from the mirror rays
    assert np.abs(mirror_normal(P, Pv).normal - N_TRUE).max() <= normal_roundoff(P, Pv)
    F2, M = virtual_camera(F1, G, N_TRUE)
    assert np.abs(F2 - F2_SPEC).max() < 5e-4  # spec prints 3 decimals: half a unit of the last digit
    # (3.11) and reflect() evaluate F1 - 2 ((F1 - G).n) n: ~8 roundings of terms up to |F1| + 2 |F1 - G|
    reach = np.abs(F1).max() + 2 * np.linalg.norm(F1 - G)
    assert np.abs(F2 - reflect(F1, G, N_TRUE)).max() <= roundoff(scale=reach, ops=8)
    # M = I - 2 n n^T (entries to ~3 eps), det by LU of a 3 x 3 orthogonal matrix: ~9 roundings
    assert np.linalg.det(M) == pytest.approx(-1.0, abs=roundoff(ops=9))
    u1, u2p = _mirror_rays(MARKERS, F1, G, N_TRUE)
    r = triangulate_mirror(F1, G, res.normal, u1, u2p)
    # res.normal carries its own rounding: F2 moves by <= 4 |F1 - G| |dn|, the markers by as much
    dn = normal_roundoff(P, Pv) * 4 * np.linalg.norm(F1 - G)
    bound = triangulation_roundoff(r.cos_angle, reach) + dn
    assert np.abs(r.points - MARKERS).max() <= bound
    assert r.gap.max() <= bound
    assert np.all(r.a1 > 0) and np.all(r.a2 > 0) and not r.weak.any()
    assert abs_err(r.virtual_center, F2) <= dn + roundoff(scale=reach, ops=8)


def test_thesis_average_differs_from_lstsq_under_noise() -> None:
    rng = np.random.default_rng(3)
    pts = rng.uniform([-200, -200, 150], [200, 200, 450], size=(6, 3))
    P, Pv = _mirror_rays(pts, F1, G, N_TRUE)
    P += rng.normal(0, 1e-3, P.shape)
    a = mirror_normal(P, Pv, mirror_point=G, camera_center=F1, method="lstsq")
    b = mirror_normal(P, Pv, mirror_point=G, camera_center=F1, method="thesis")
    # 1e-3 mm on rays >= 1 m long turns them by <= 1e-6 rad; the pair planes amplify that by up to
    # normal_condition (~2e3 here): ~2e-3 rad, bound 5x
    for res in (a, b):
        assert np.arccos(min(1.0, res.normal @ N_TRUE)) < 1e-2 and res.residual > 0
    # the two estimators weigh the noisy pairs differently: they differ by more than rounding
    assert np.abs(a.normal - b.normal).max() > normal_roundoff(P, Pv)
    with pytest.raises(ValueError, match="odd"):
        mirror_normal(P[:5], Pv[:5], method="thesis")


# ---------------------------------------------------------------- hypothesis property tests
coord = st.floats(-2000, 2000, allow_nan=False)
vec3 = st.tuples(coord, coord, coord).map(np.array)


@st.composite
def scenes(draw, n_points: int = 8):
    """Random camera, mirror (normal toward the camera), and markers on the camera side."""
    F = draw(vec3)
    theta = draw(st.floats(0.05, np.pi - 0.05))
    phi = draw(st.floats(0, 2 * np.pi))
    n = np.array([np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta)])
    dist = draw(st.floats(100, 3000))
    slide = draw(vec3)
    g = F - dist * n + (slide - (slide @ n) * n)  # any point of the plane
    unit = draw(hnp.arrays(np.float64, (n_points, 3), elements=st.floats(-1, 1)))
    # markers between camera and mirror, spread along two directions in the mirror plane
    t1 = np.cross(n, [1.0, 0, 0] if abs(n[0]) < 0.9 else [0, 1.0, 0])
    t1 /= np.linalg.norm(t1)
    t2 = np.cross(n, t1)
    pts = F - np.outer(dist * (0.1 + 0.4 * (unit[:, 0] + 1)), n) + np.outer(1500 * unit[:, 1], t1) + np.outer(
        1500 * unit[:, 2], t2
    )
    return F, g, n, pts


@settings(max_examples=60, deadline=None)
@given(g=vec3, theta=st.floats(0, np.pi), phi=st.floats(0, 2 * np.pi),
       x=hnp.arrays(np.float64, (5, 3), elements=st.floats(-5000, 5000)))
def test_reflection_is_involution_with_det_minus_one(g, theta, phi, x) -> None:
    n = np.array([np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta)])
    H = reflection_matrix(g, n)
    # [[M, t], [0, 1]]: LU never pivots on the last row, det = det(M) (3 x 3 orthogonal) to ~16 roundings
    assert np.linalg.det(H) == pytest.approx(-1.0, abs=roundoff(ops=16))
    # H H cancels M t + t = 0 with |t| = 2 |g.n|: ~8 roundings of the largest entry
    np.testing.assert_allclose(H @ H, np.eye(4), rtol=0, atol=roundoff(scale=np.abs(H).max(), ops=8))
    # x - 2 ((x - g).n) n: ~8 roundings of coordinates up to `scale` per reflection
    scale = 1 + np.abs(x).max() + np.abs(g).max()
    np.testing.assert_allclose(reflect(reflect(x, g, n), g, n), x, rtol=0, atol=roundoff(scale=scale, ops=16))
    xh = np.c_[x, np.ones(len(x))] @ H.T
    np.testing.assert_allclose(xh[:, :3], reflect(x, g, n), rtol=0, atol=roundoff(scale=scale, ops=16))
    # points on the plane are fixed; the reflected vector keeps its length
    np.testing.assert_allclose(reflect(g, g, n), g, rtol=0, atol=roundoff(scale=scale, ops=8))
    v = reflect(x, g, n, vectors=True)
    assert np.all(np.abs(np.linalg.norm(v, axis=1) - np.linalg.norm(x, axis=1))
                  <= roundoff(scale=np.linalg.norm(x, axis=1), ops=12))


@settings(max_examples=60, deadline=None)
@given(scenes())
def test_virtual_camera_is_reflection_of_camera(scene) -> None:
    F, g, n, _ = scene
    vc = virtual_camera(F, g, n)
    # two evaluations of F - 2 ((F - g).n) n (one through the 4 x 4 matrix): ~8 roundings each
    scale = 1 + np.abs(F).max() + np.abs(g).max()
    np.testing.assert_allclose(vc.center, reflect(F, g, n), rtol=0, atol=roundoff(scale=scale, ops=16))
    assert vc.distance > 0
    np.testing.assert_allclose(vc.homogeneous @ np.r_[F, 1], np.r_[vc.center, 1], rtol=0,
                               atol=roundoff(scale=scale, ops=16))
    with pytest.raises(DegenerateGeometry, match="3.10"):
        virtual_camera(F, g, -n)


@settings(max_examples=60, deadline=None)
@given(scenes())
def test_exact_rays_round_trip(scene) -> None:
    """Noiseless rays return the markers to rounding (amplified by the rays' angle) with gap ≈ 0."""
    F, g, n, pts = scene
    u1, u2p = _mirror_rays(pts, F, g, n)
    u2 = reflect(u2p, g, n, vectors=True)
    k = np.einsum("ij,ij->i", u1, u2) / np.linalg.norm(u1, axis=1) / np.linalg.norm(u2, axis=1)
    assume(np.all(1 - k**2 > 1e-6))
    r = triangulate_mirror(F, g, n, u1 * 3.7, u2p)  # ray length is irrelevant
    # coordinates, the virtual camera and the depths all enter the closed form
    scale = max(np.abs(F).max(), np.abs(r.virtual_center).max(), np.abs(pts).max(), np.nanmax(r.a2))
    assert np.abs(r.points - pts).max() <= triangulation_roundoff(r.cos_angle, scale)
    assert r.gap.max() <= triangulation_roundoff(r.cos_angle, scale)
    assert np.abs(r.a1 - np.linalg.norm(pts - F, axis=1)).max() <= triangulation_roundoff(r.cos_angle, scale)


@settings(max_examples=60, deadline=None)
@given(scenes(n_points=5))
def test_recovered_normal_equals_true(scene) -> None:
    F, g, n, pts = scene
    P, Pv = _mirror_rays(pts, F, g, n)
    A = np.cross(P / np.linalg.norm(P, axis=1)[:, None], Pv / np.linalg.norm(Pv, axis=1)[:, None])
    an = np.linalg.norm(A, axis=1)
    assume(an.min() > 1e-3)
    assume(np.linalg.svd(A / an[:, None], compute_uv=False)[1] > 1e-2)
    res = mirror_normal(P, Pv, mirror_point=g, camera_center=F)
    # assume() keeps |A_k| > 1e-3 and sigma_2 > 1e-2: condition <= sqrt(5) / 1e-5; the bound follows the draw
    assert np.abs(res.normal - n).max() <= normal_roundoff(P, Pv)
    assert np.abs(mirror_normal(P, Pv).normal - n).max() <= normal_roundoff(P, Pv)  # orientation from the mirror rays


# ---------------------------------------------------------------- several mirrors / general intersection


def test_multi_mirror_with_missing_views() -> None:
    rng = np.random.default_rng(7)
    F = np.array([0.0, 0.0, 1500.0])
    mirrors = [(np.array([-600.0, 0, 0]), np.array([1.0, 0, 0])),
               (np.array([0, -600.0, 0]), np.array([0, 1.0, 0])),
               (np.array([0, 0, -300.0]), np.array([0.1, 0.1, 1.0]) / np.linalg.norm([0.1, 0.1, 1.0]))]
    pts = rng.uniform(-250, 250, size=(500, 3))
    virt = np.stack([reflect(pts, g, n) - F for g, n in mirrors], axis=1)
    real = pts - F
    hide = rng.random(virt.shape[:2]) < 0.4
    virt[hide] = np.nan
    real[rng.random(500) < 0.3] = np.nan
    seen = (~hide).sum(1) + np.isfinite(real).all(1)
    keep = seen >= 2
    r = triangulate_mirrors(F, mirrors, real[keep], virt[keep])
    # the virtual cameras lie up to 2 x 1500 mm from the origin: that is the computation's scale
    scale = max(np.abs(F).max(), max(np.abs(reflect(F, g, n)).max() for g, n in mirrors))
    assert np.all(np.abs(r.points - pts[keep]).max(axis=1) <= triangulation_roundoff(r.cos_angle, scale, r.n_views))
    assert r.residual.max() <= triangulation_roundoff(r.cos_angle, scale, r.n_views)
    np.testing.assert_array_equal(r.n_views, seen[keep])
    with pytest.raises(DegenerateGeometry, match="fewer than two views"):
        triangulate_mirrors(F, mirrors, real, virt)
    flagged = triangulate_mirrors(F, mirrors, real, virt, on_degenerate="flag")
    np.testing.assert_array_equal(flagged.degenerate, ~keep)
    assert np.isnan(flagged.points[~keep]).all()


def test_general_path_matches_closed_form() -> None:
    rng = np.random.default_rng(1)
    o = np.array([[0.0, 0, 0], [300.0, 20, -10]])
    d = rng.normal(size=(200, 2, 3)) * 0.05 + [[[0, 0, 1], [-0.3, 0, 1]]]
    closed = intersect_rays(o, d, check_front=False)
    d3 = np.concatenate([d, np.full((200, 1, 3), np.nan)], axis=1)
    general = intersect_rays(np.r_[o, [[9.0, 9, 9]]], d3, check_front=False)
    # both rounded, each within the rays' conditioning (angles ~ 17 deg) at the depths' scale
    scale = np.abs(closed.depths).max() + np.abs(o).max()
    bound = (triangulation_roundoff(closed.cos_angle, scale, closed.n_views)
             + triangulation_roundoff(general.cos_angle, scale, general.n_views))
    assert abs_err(general.points, closed.points) <= bound
    assert abs_err(general.residual, closed.residual) <= bound
    assert abs_err(general.depths[:, :2], closed.depths) <= bound


# ---------------------------------------------------------------- degenerate geometry


def test_degenerate_cases_name_marker_and_cause() -> None:
    u1, u2p = _mirror_rays(MARKERS, F1, G, N_TRUE)
    # marker 1 on the line F1-F2 (mirror normal through the camera): parallel rays
    on_axis = F1 - 300.0 * N_TRUE
    u1[1], u2p[1] = on_axis - F1, reflect(on_axis, G, N_TRUE) - F1
    with pytest.raises(DegenerateGeometry, match=r"marker 1\b.*parallel"):
        triangulate_mirror(F1, G, N_TRUE, u1, u2p)
    r = triangulate_mirror(F1, G, N_TRUE, u1, u2p, on_degenerate="flag")
    assert r.degenerate.tolist() == [False, True, False] and np.isnan(r.points[1]).all()
    # a wrong correspondence is caught by max_gap
    u1, u2p = _mirror_rays(MARKERS, F1, G, N_TRUE)
    u2p[[0, 2]] = u2p[[2, 0]]
    with pytest.raises(DegenerateGeometry, match=r"markers 0, 2\b.*max_gap"):
        triangulate_mirror(F1, G, N_TRUE, u1, u2p, max_gap=5.0)
    # marker 2 behind the camera: its direct ray is reversed
    u1, u2p = _mirror_rays(MARKERS, F1, G, N_TRUE)
    u1[2] *= -1
    with pytest.raises(DegenerateGeometry, match=r"marker 2\b.*behind"):
        triangulate_mirror(F1, G, N_TRUE, u1, u2p)
    # normal violating (3.10)
    with pytest.raises(DegenerateGeometry, match="3.10"):
        triangulate_mirror(F1, G, -N_TRUE, *_mirror_rays(MARKERS, F1, G, N_TRUE))
    # mirror normal: a pair on the camera's normal line, too few pairs, coplanar pairs
    P, Pv = _mirror_rays(np.r_[PAIRS[:2], [on_axis]], F1, G, N_TRUE)
    with pytest.raises(DegenerateGeometry, match=r"marker 2\b"):
        mirror_normal(P, Pv)
    with pytest.raises(DegenerateGeometry, match="at least two"):
        mirror_normal(P[:1], Pv[:1])
    along = PAIRS[0] + np.outer([0.0, 1.0], F1 - PAIRS[0]) * 0.3  # both markers in one plane with F1 and n
    P, Pv = _mirror_rays(along, F1, G, N_TRUE)
    with pytest.raises(DegenerateGeometry, match="coplanar"):
        mirror_normal(P, Pv)


# ---------------------------------------------------------------- noise: midpoint / optimal vs OpenCV


class _Pinhole:
    """Minimal pinhole camera (no distortion) for the tests: y = R x + t, pixels = K y / y_z."""

    def __init__(self, K: np.ndarray, R: np.ndarray, center: np.ndarray) -> None:
        self.K, self.R, self.camera_center = K, R, center
        self.t = -R @ center
        self.P = K @ np.c_[R, self.t]

    def project(self, X: np.ndarray) -> np.ndarray:
        y = (X @ self.R.T + self.t) @ self.K.T
        return y[:, :2] / y[:, 2:]

    def rays(self, xy: np.ndarray) -> np.ndarray:
        h = np.c_[xy, np.ones(len(xy))]
        return h @ np.linalg.inv(self.K).T @ self.R


def _look_at(center: np.ndarray, target: np.ndarray) -> np.ndarray:
    z = (target - center) / np.linalg.norm(target - center)
    x = np.cross([0.0, 1.0, 0.0], z)
    x /= np.linalg.norm(x)
    return np.stack([x, np.cross(z, x), z])


def _noisy_scene(n_pts: int, sigma: float, seed: int):
    rng = np.random.default_rng(seed)
    pts = rng.uniform([-100, -100, 150], [300, 200, 450], size=(3 * n_pts, 3))
    pts = pts[(pts - G) @ N_TRUE > 30.0][:n_pts]  # markers in front of the mirror
    target = 0.5 * (pts.mean(0) + reflect(pts.mean(0), G, N_TRUE))
    cam = _Pinhole(np.array([[1500.0, 0, 640], [0, 1500.0, 480], [0, 0, 1]]), _look_at(F1, target), F1)
    xy1 = cam.project(pts) + rng.normal(0, sigma, (len(pts), 2))
    xy2 = cam.project(reflect(pts, G, N_TRUE)) + rng.normal(0, sigma, (len(pts), 2))
    return cam, pts, xy1, xy2


def test_optimal_is_exact_without_noise() -> None:
    cam, pts, xy1, xy2 = _noisy_scene(200, 0.0, 5)
    r = triangulate_mirror(F1, G, N_TRUE, None, None, "optimal", camera=cam, image_xy_real=xy1,
                           image_xy_virtual=xy2)
    # the midpoint start is exact to rounding (pixels ~1e3 through K^-1: ~eps |xy| / f relative per
    # ray); least_squares stops at xtol = 1e-12 relative (mirror.py), which dominates
    scale = max(np.abs(F1).max(), np.abs(r.virtual_center).max(), np.nanmax(r.a2))
    assert np.abs(r.points - pts).max() <= triangulation_roundoff(r.cos_angle, scale) + 1e-12 * scale
    # 1500 px focal length at ~1 m: 1.5 px per mm of the bound above, ~1e-8 px; 1e-6 px is looser,
    # a check that the residuals vanish, not of rounding
    assert r.reprojection.max() < 1e-6


def test_noise_midpoint_and_optimal_vs_opencv() -> None:
    """0.3 px noise: midpoint within 25 % of cv2.triangulatePoints, optimal at or below it."""
    cam, pts, xy1, xy2 = _noisy_scene(3000, 0.3, 2026)
    assert np.all(cam.project(pts).min(0) > 0) and np.all(cam.project(pts).max(0) < [1280, 960])
    P2 = cam.P @ reflection_matrix(G, N_TRUE)  # virtual camera = P · reflection
    Xh = cv2.triangulatePoints(cam.P, P2, xy1.T, xy2.T)
    X_cv = (Xh[:3] / Xh[3]).T
    mid = triangulate_mirror(F1, G, N_TRUE, cam.rays(xy1), cam.rays(xy2))
    opt = triangulate_mirror(F1, G, N_TRUE, cam.rays(xy1), cam.rays(xy2), "optimal", camera=cam,
                             image_xy_real=xy1, image_xy_virtual=xy2)
    rms = {k: float(np.sqrt(np.mean(np.sum((X - pts) ** 2, axis=1))))
           for k, X in (("cv2", X_cv), ("midpoint", mid.points), ("optimal", opt.points))}
    print("3-D RMS error (mm):", rms)
    # statistics of 3000 markers (sampling error of an RMS ~ 1/sqrt(2 * 3000) = 1.3 %): the midpoint
    # is not the ML estimate (cv2's linear DLT is, to first order, at small noise), 25 % margin
    assert rms["midpoint"] <= 1.25 * rms["cv2"]
    assert rms["optimal"] <= rms["cv2"]
    assert mid.gap.mean() > 0 and np.all(np.isfinite(opt.reprojection))


def test_optimal_with_distorting_camera_model() -> None:
    """Any camera with project/rays works, e.g. the package's PinholeCamera with lens distortion."""
    from mirrorlab.plugins.photogrammetry.cameras import PinholeCamera

    ref, pts, _, _ = _noisy_scene(300, 0.0, 9)
    cam = PinholeCamera(ref.K, np.array([-0.12, 0.05, 0.0, 0.0, 0.0]), ref.R, ref.t)
    xy1, xy2 = cam.project(pts), cam.project(reflect(pts, G, N_TRUE))
    rng = np.random.default_rng(0)
    xy1n, xy2n = xy1 + rng.normal(0, 0.3, xy1.shape), xy2 + rng.normal(0, 0.3, xy2.shape)
    exact = triangulate_mirror(cam.camera_center, G, N_TRUE, None, None, "optimal", camera=cam,
                               image_xy_real=xy1, image_xy_virtual=xy2)
    # cv2.undistortPoints stops at 1e-14 (normalised units), least_squares at xtol 1e-12 (~1e-9 mm
    # at 1 m): 1e-6 mm is a loose check that the distorting model round-trips, not of rounding
    assert np.abs(exact.points - pts).max() < 1e-6
    mid = triangulate_mirror(cam.camera_center, G, N_TRUE, cam.rays(xy1n), cam.rays(xy2n))
    opt = triangulate_mirror(cam.camera_center, G, N_TRUE, cam.rays(xy1n), cam.rays(xy2n), "optimal",
                             camera=cam)  # image points recovered from the rays
    # 0.3 px / 1500 px on rays up to 1.65 m long is 0.33 mm across a ray, <= 0.9 mm per point with the
    # rays 22-66 deg apart (1 sigma); two estimates from the same data differ by less than either's error
    assert np.abs(opt.points - mid.points).max() < 2.0
    # 4 residuals per marker, 3 fitted: rep^2 = chi^2_1 sigma^2 / 2, mean rep ~ 0.8 * 0.3 / sqrt(2) = 0.17 px
    assert opt.reprojection.mean() < 0.35
