"""Error analysis (spec §4, §5, §11), figures, and the validation script's core."""

from __future__ import annotations

import doctest

import numpy as np
import pytest
from mirrorlab.plugins.photogrammetry import figures
from mirrorlab.plugins.photogrammetry import sensitivity as sens_mod
from mirrorlab.plugins.photogrammetry.central import CentralCamera
from mirrorlab.plugins.photogrammetry.errors import RayMissesSphere
from mirrorlab.plugins.photogrammetry.mirror import triangulate_mirror
from mirrorlab.plugins.photogrammetry.sensitivity import (
    THESIS_GRID_X,
    THESIS_GRID_Y,
    THESIS_MIRROR_ERRORS,
    accuracy_statistics,
    central_error_map,
    central_point_sensitivity,
    mirror_angle_sweep,
    mirror_error_map,
    mirror_point_sensitivity,
    mirror_reconstruct,
    monte_carlo,
    rotating_table_points,
    sensitivity,
    table_rotation,
)

from tests.plugins.photogrammetry.bounds import plane_ray_error, triangulation_roundoff
from tests.tolerances import roundoff

CAM = CentralCamera(2687.0, 54.0, np.radians(12.0))


def test_doctests():
    assert doctest.testmod(sens_mod).failed == 0
    assert doctest.testmod(figures).failed == 0


# ---- generic ------------------------------------------------------------------------------------


def test_sensitivity_linear_exact_and_sums():
    A = np.array([[1.0, 2.0], [0.5, -1.0], [0.0, 3.0]])
    p, h = np.array([1.0, 2.0]), np.array([0.1, 0.2])
    r = sensitivity(lambda q: A @ q, p, h)
    # central differences are exact for a linear map; f(p +- h), of size |A| (|p| + h), rounds, and
    # the difference is divided by 2 h
    fd = roundoff(scale=np.max(np.abs(A) @ (np.abs(p) + h)) / h.min(), ops=4)
    np.testing.assert_allclose(r.derivatives, A.T, rtol=0, atol=fd)
    np.testing.assert_allclose(r.contributions, A.T * h[:, None], rtol=0, atol=fd * h.max())
    np.testing.assert_allclose(r.signed_sum, A @ h, rtol=0, atol=fd * h.sum())
    np.testing.assert_allclose(r.abs_sum, np.abs(A) @ h, rtol=0, atol=fd * h.sum())
    np.testing.assert_allclose(r.rss, np.sqrt((A**2) @ h**2), rtol=0, atol=fd * h.sum())


def test_step_halving_on_ray_misses_sphere():
    def f(p):
        if abs(p[0]) > 0.3:
            raise RayMissesSphere("synthetic")
        return np.array([p[0] ** 2 + 3 * p[0]])

    r = sensitivity(f, [0.0], [1.0])
    assert r.halvings.tolist() == [2] and r.steps.tolist() == [0.25]
    # central differences are exact for a quadratic: |f(+-0.25)| <= 0.82 rounds, divided by 0.5
    assert r.derivatives[0, 0] == pytest.approx(3.0, abs=roundoff(scale=0.82 / 0.5, ops=4))
    with pytest.raises(RayMissesSphere):
        sensitivity(f, [0.0], [1e6], max_halvings=3)


# ---- central projection (§4) ------------------------------------------------------------------------


def test_central_reference_values(validation):
    # the spec's values are the same central differences printed to 3 decimals: half a unit (the
    # computation's own rounding, ~1e-8 mm at the near-tangent point's condition ~1e2, is negligible)
    for label, v in validation.central_reference().items():
        for k, ref in v["spec"].items():
            np.testing.assert_allclose(v["ours"][k], ref, rtol=0, atol=5e-4 + roundoff(cond=1e2, scale=3e3),
                                       err_msg=f"{label} {k}")


def test_central_error_map_peaks_at_tangency_and_z_dominates():
    pts, r = central_error_map(CAM, n_lat=9, n_lon=12)
    mag = np.abs(r.signed_sum)
    assert mag[:, 2].max() > mag[:, 0].max() and mag[:, 2].max() > mag[:, 1].max()
    # tangency: the ray from S nearly touches the sphere -> the angle between ray and radius near 90 deg
    ray = (pts - CAM.camera_center) / np.linalg.norm(pts - CAM.camera_center, axis=1, keepdims=True)
    rad = (pts - CAM.K) / 300.0
    cosang = np.abs(np.sum(ray * rad, axis=1))
    worst = np.argmax(np.linalg.norm(r.abs_sum, axis=1))
    assert cosang[worst] < np.quantile(cosang, 0.25)


def test_monte_carlo_matches_linear_propagation():
    P = CAM.K + np.array([[0.0, 0.0, -300.0]])
    small = {k: v / 10 for k, v in sens_mod.THESIS_CENTRAL_ERRORS.items()}
    lin = central_point_sensitivity(P, CAM, small)
    xy = CAM.project(P)

    def rec(p):
        from mirrorlab.plugins.photogrammetry.central import reconstruct_chain_central
        cam = CentralCamera(p["a"], p["f"], p["alpha"])
        return reconstruct_chain_central((xy + [p["x"], p["y"]])[:, None], [[300.0 + p["link"]]], cam,
                                         reference=P[:, None]).points[0, 0]

    p0 = {"x": 0.0, "y": 0.0, "f": CAM.f, "alpha": CAM.alpha, "link": 0.0, "a": CAM.a}
    mc = monte_carlo(rec, p0, small, n=400, rng=1)
    # a standard deviation from 400 samples: relative sampling error 1 / sqrt(2 * 400) = 3.5 %, so 15 %
    # is 4 sd (the errors are a tenth of the thesis's: linearisation error well below that); atol
    # 1e-3 mm is negligible next to the components (0.04-0.24 mm)
    np.testing.assert_allclose(mc.std, lin.rss[0], rtol=0.15, atol=1e-3)


# ---- rotating table (§5) ------------------------------------------------------------------------


def test_table_rotation_is_proper():
    R = table_rotation(0.1, -0.3, 0.7)
    # a product of three rotations, entries to ~6 roundings; R R^T and det add ~3 more per entry
    np.testing.assert_allclose(R @ R.T, np.eye(3), rtol=0, atol=roundoff(ops=9))
    assert np.linalg.det(R) == pytest.approx(1.0, abs=roundoff(ops=9))
    np.testing.assert_allclose(rotating_table_points(0, 0, 0)[:, 2], [2227.37, 2227.37, 2731.37, 2731.37],
                               rtol=0, atol=roundoff(scale=2731.37, ops=4))


def test_rotating_table_reproduces_table_2_1(validation):
    res = validation.rotating_table_check()
    # spec §5: "within 1.9 mm (NO.2), 0.51 mm (NO.3), 0.48 mm (NO.4) ... within 0.1 mm with the refined
    # angles": 1.9 to its printed digit (1.85-1.95), 0.51 / 0.48 plus one unit of the last digit
    assert res["NO.2"]["printed"] == pytest.approx(1.87, abs=0.05)
    assert res["NO.3"]["printed"] <= 0.52 and res["NO.4"]["printed"] <= 0.49
    for pose in ("NO.2", "NO.3", "NO.4"):
        assert res[pose]["refined"] < 0.1
        # both rounded to 2 decimals: equal, or one unit apart when the fit lies near a tie (0.01 + float noise)
        np.testing.assert_allclose(res[pose]["fit_deg"], validation.TABLE_ANGLES_REFINED_DEG[pose], atol=0.011)


def test_table_2_3_consistency_and_statistics(validation):
    s = validation.table_2_3_statistics()
    d = np.abs(s["diff_vs_printed"])
    # 2-decimal tables: the differences are multiples of 0.01 up to float noise (~1e-12 mm); 0.011
    # separates the spec's "+-0.01 mm" from real discrepancies (>= 0.02)
    off = {(int(k), int(i), int(j)) for k, i, j in np.argwhere(d > 0.011)}
    # spec §5: NO.1 Y printed with the opposite sign, NO.4-1 Z and NO.4-4 Y differ
    assert off == {(0, 0, 1), (0, 1, 1), (0, 2, 1), (0, 3, 1), (3, 0, 2), (3, 3, 1)}
    # the mean of 16 printed values, printed to 2 decimals: half a unit plus float noise
    np.testing.assert_allclose(s["printed_mean"], [0.29, 3.45, 14.85], rtol=0, atol=0.006)
    # the largest |printed value| is one of the literals itself: exact
    np.testing.assert_array_equal(s["printed_max"], validation.TABLE_2_3_MAX)
    st = accuracy_statistics(validation.TABLE_2_1, validation.TABLE_2_2)
    assert st["error"].shape == (4, 4, 3)


def test_fig_2_4(validation):
    f = validation.fig_2_4()
    # as tests/plugins/photogrammetry/test_parallel.py::test_fig_2_4_table: half a unit of the figure's 2 decimals
    # plus the formula's rounding (the sine difference cancels by up to 22x); the two equations ~8
    # roundings apart
    np.testing.assert_allclose(f["eq_2_6"], f["thesis"], rtol=0,
                               atol=0.005 + roundoff(cond=22.0, scale=np.abs(f["eq_2_6"]).max(), ops=8))
    np.testing.assert_allclose(f["eq_2_3"], f["eq_2_6"], rtol=roundoff(ops=8))


# ---- mirror method (§11) --------------------------------------------------------------------------


def test_mirror_pipeline_round_trip(scene):
    V = np.array([[100.0, 50.0, 300.0], [-150.0, -100.0, 200.0], [250.0, 120.0, 420.0]])
    U, W = scene.image_points(V)
    # exact plane map (film parallel to the plane) whose rounding turns the rays, then a triangulation
    # with rays ~45 deg apart
    cal = scene.calibration
    r = triangulate_mirror(scene.camera_center, scene.mirror_point, scene.normal, cal.rays(U), cal.rays(W))
    scale = max(np.abs(scene.camera_center).max(), np.abs(r.virtual_center).max(), r.a2.max())
    ray_error = plane_ray_error(cal, np.r_[U, W], max(np.abs(THESIS_GRID_X).max(), np.abs(THESIS_GRID_Y).max()))
    np.testing.assert_allclose(mirror_reconstruct(scene, U, W), V, rtol=0,
                               atol=triangulation_roundoff(r.cos_angle, scale, ray_error=ray_error))
    F2 = scene.camera_center - 2 * np.dot(scene.camera_center - scene.mirror_point, scene.normal) * scene.normal
    np.testing.assert_allclose(F2, [-1105.289, 202.600, -394.432], rtol=0, atol=5e-4)  # 3 decimals: half a unit


def test_table_3_1_structure(validation, scene):
    t = validation.table_3_1(scene)
    assert list(t) == list(THESIS_MIRROR_ERRORS)
    # 10 shares 100 m / total summed: ~10 roundings of 100
    assert sum(r["ours_share"] for r in t.values()) == pytest.approx(100.0, abs=roundoff(scale=100.0, ops=10))
    assert all(r["ours_mm"] > 0 for r in t.values())
    # printed fixture consistency (spec §11): shares = mm / 11.58 within 1 % except T (printed 23.3)
    total = sum(validation.TABLE_3_1_MM.values())
    assert total == pytest.approx(11.58, abs=roundoff(scale=11.58, ops=10))  # 10 literals summed
    for k, mm in validation.TABLE_3_1_MM.items():
        if k != "T":
            assert 100 * mm / total == pytest.approx(validation.TABLE_3_1_SHARE[k], abs=1.0)
    # film-coordinate errors: x larger than y for both images, as in the thesis
    assert t["Ux"]["ours_mm"] > t["Uy"]["ours_mm"] and t["Vx"]["ours_mm"] > t["Vy"]["ours_mm"]


def test_mirror_error_map_smooth(scene):
    pts, r = mirror_error_map(scene, n_lat=5, n_lon=8)
    mag = np.linalg.norm(r.abs_sum, axis=1)
    # no strong position dependence (Fig. 3.22, qualitative): less than a factor 2 over the sphere
    assert mag.max() / mag.min() < 2.0


def test_mirror_angle_sweep_minimum(validation, scene):
    sw = validation.fig_3_23(np.linspace(0.3, 1.3, 21), scene)
    assert 0.4 <= sw["argmin"] <= 1.2  # thesis: minimum 0.68 rad, small from 0.4 to 1.2 rad
    e = np.interp([0.4, 0.68, 1.2], sw["angles"], sw["errors"])
    assert e.max() < 1.5 * sw["errors"].min()  # "small" over that range (qualitative): within 50 % of the minimum


def test_figures_write_png(tmp_path, scene):
    pts, r = central_error_map(CAM, n_lat=5, n_lon=6)
    assert figures.plot_error_map(pts, r.signed_sum, tmp_path / "a.png", center=CAM.K).stat().st_size > 1000
    a = np.linspace(0.4, 1.2, 5)
    e = mirror_angle_sweep(scene, [[100.0, 50.0, 300.0]], a)
    assert figures.plot_mirror_angle_sweep(a, e, tmp_path / "b.png").exists()
    r = mirror_point_sensitivity(scene, [[100.0, 50.0, 300.0]])
    assert r.contributions.shape == (10, 1, 3)
