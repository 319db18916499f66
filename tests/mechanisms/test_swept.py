"""Swept areas: exact union, thesis raster, strip formula, spatial triangles and bilinear patches (§5, §7)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from mirrorlab.plugins.mechanisms import InvalidPoints
from mirrorlab.plugins.mechanisms.swept import segment_swept_area, spatial_swept_area, strip_area, swept_region
from mirrorlab.plugins.mechanisms.walls import astroid_motion, eq63_motion
from scipy.spatial.transform import Rotation

L = 3.0
ASTROID = 3 * np.pi * L**2 / 32          # eq. 6.1: 2.650719


def test_astroid_exact_union_converges_from_below() -> None:
    errs = [segment_swept_area(*astroid_motion(L, n)) / ASTROID - 1 for n in (50, 200, 1000)]
    assert errs[0] < errs[1] < errs[2] < 0
    assert abs(errs[2]) < 1e-4                       # within 0.01 % (measured -6.2e-7)
    assert errs[0] == pytest.approx(-2.6e-4, rel=0.1)


@pytest.mark.parametrize("span,expected", [(170, 0.040), (256, 0.026), (128, 0.053)])
def test_thesis_raster_overestimates_by_its_boundary_layer(span: int, expected: float) -> None:
    a, b = astroid_motion(L, 4000)
    err = segment_swept_area(a, b, "raster", pixel=L / span) / ASTROID - 1
    assert err == pytest.approx(expected, abs=0.002)


def test_raster_default_grid_is_256_pixels() -> None:
    a, b = astroid_motion(L, 2000)
    assert segment_swept_area(a, b, "raster") == pytest.approx(segment_swept_area(a, b, "raster", pixel=L / 255))


def test_strip_formula_matches_astroid_and_union() -> None:
    a, b = astroid_motion(L, 1500)
    assert strip_area(a, b, 4000) / ASTROID - 1 == pytest.approx(0, abs=3e-6)
    a, b = eq63_motion(L, 2.2, 3000)
    assert strip_area(a, b, 3000) == pytest.approx(segment_swept_area(a, b), rel=1e-3)


def test_bow_tie_uses_the_two_triangles_not_the_hull() -> None:
    ang = np.linspace(0, np.pi / 2, 400)
    d = 1.5 * np.stack([np.cos(ang), np.sin(ang)], -1)          # rod of 3 turned about its middle
    region = swept_region(-d, d)
    assert region.area == pytest.approx(np.pi * L**2 / 8, rel=1e-4)
    coarse = segment_swept_area(-d[::100], d[::100])             # 4 steps: the triangles stay inside
    assert coarse < np.pi * L**2 / 8


def test_spatial_triangles_and_bilinear_against_the_spec() -> None:
    truth = np.pi * 300.0**2 / 8
    rows = {}
    for n in (4, 40):
        ang = np.linspace(0, np.pi / 2, n + 1)
        d = 150 * np.stack([np.cos(ang), np.sin(ang), 0 * ang], -1)
        tri = spatial_swept_area(-d, d)
        rows[n] = (tri.area / truth, spatial_swept_area(-d, d, "bilinear").area / truth, len(tri.crossings))
        end = spatial_swept_area(0 * d, 2 * d)                   # rotation about an end: no crossings
        assert end.area / (np.pi * 300.0**2 / 4) - 1 == pytest.approx(-2.6e-4 if n == 40 else -0.0255, abs=2e-4)
        assert len(end.crossings) == 0
        np.testing.assert_allclose(tri.crossing_points, 0.0, atol=1e-9)
    assert rows[4][0] == pytest.approx(1.95, abs=0.01) and rows[40][0] == pytest.approx(2.00, abs=0.005)
    assert rows[4][1] - 1 == pytest.approx(-0.025, abs=0.001) and rows[40][1] - 1 == pytest.approx(-0.0003, abs=1e-4)
    assert rows[4][2] == 4 and rows[40][2] == 40


def test_helicoid_bilinear_against_analytic() -> None:
    """Strip r in [r0, r1] of the helicoid (r cos t, r sin t, c t): area int int sqrt(r^2 + c^2) dr dt."""
    r0, r1, c, turn = 0.1, 0.5, 0.2, 1.0
    t = np.linspace(0, turn, 41)
    a = np.stack([r0 * np.cos(t), r0 * np.sin(t), c * t], -1)
    b = np.stack([r1 * np.cos(t), r1 * np.sin(t), c * t], -1)

    def F(r: float) -> float:
        return 0.5 * (r * np.hypot(r, c) + c * c * np.arcsinh(r / c))

    exact = turn * (F(r1) - F(r0))
    bil = spatial_swept_area(a, b, "bilinear").area
    tri = spatial_swept_area(a, b).area
    assert bil == pytest.approx(exact, rel=2e-4)
    assert abs(tri / exact - 1) > abs(bil / exact - 1)


def test_union_for_a_planar_motion_in_space() -> None:
    a2, b2 = astroid_motion(L, 500)
    R = Rotation.from_euler("xyz", [0.3, -0.5, 1.1]).as_matrix()
    lift = lambda p: np.hstack([p, np.zeros((len(p), 1))]) @ R.T + [1.0, 2.0, 3.0]  # noqa: E731
    s = spatial_swept_area(lift(a2), lift(b2), "union")
    assert s.area == pytest.approx(segment_swept_area(a2, b2), rel=1e-8)   # union snapped to 1e-10 of the extent
    skew = lift(b2) + np.linspace(0, 1, 500)[:, None] * [0, 0, 1]
    with pytest.raises(InvalidPoints, match="one plane"):
        spatial_swept_area(lift(a2), skew, "union")


@settings(max_examples=20, deadline=None)
@given(st.floats(-np.pi, np.pi), st.floats(-50, 50), st.floats(-50, 50), st.booleans())
def test_planar_area_invariant_under_rigid_motion(angle: float, dx: float, dy: float, mirror: bool) -> None:
    a, b = eq63_motion(L, 2.3, 300)
    c, s = np.cos(angle), np.sin(angle)
    R = np.array([[c, -s], [s, c]]) @ (np.diag([1.0, -1.0]) if mirror else np.eye(2))
    moved = [p @ R.T + [dx, dy] for p in (a, b)]
    assert segment_swept_area(*moved) == pytest.approx(segment_swept_area(a, b), rel=1e-8)


@settings(max_examples=20, deadline=None)
@given(st.lists(st.floats(-3, 3), min_size=3, max_size=3), st.lists(st.floats(-100, 100), min_size=3, max_size=3))
def test_spatial_area_invariant_under_rigid_motion(rotvec: list[float], shift: list[float]) -> None:
    t = np.linspace(0, 2, 30)
    a = np.stack([np.cos(t), np.sin(t), 0.3 * t], -1) * 100
    b = np.stack([np.cos(2 * t), 0.5 * t, np.sin(t)], -1) * 80 + 50
    R = Rotation.from_rotvec(rotvec).as_matrix()
    for method in ("triangles", "bilinear"):
        ref = spatial_swept_area(a, b, method)
        moved = spatial_swept_area(a @ R.T + shift, b @ R.T + shift, method)
        assert moved.area == pytest.approx(ref.area, rel=1e-9)
        assert np.array_equal(moved.crossings, ref.crossings)


def test_bad_input_errors() -> None:
    a, b = astroid_motion(L, 10)
    with pytest.raises(InvalidPoints, match=r"rod end a must be positions of shape \(T, 2\)"):
        segment_swept_area(a[:, :1], b)
    with pytest.raises(InvalidPoints, match="same shape"):
        segment_swept_area(a, b[:5])
    bad = a.copy()
    bad[3] = np.nan
    with pytest.raises(InvalidPoints, match="frame 3 has NaN"):
        segment_swept_area(bad, b)
    with pytest.raises(InvalidPoints, match="unknown method"):
        segment_swept_area(a, b, "hull")
    with pytest.raises(InvalidPoints, match="B on the x axis"):
        strip_area(a, b + [0, 1])
    with pytest.raises(InvalidPoints, match=r"\(T, 3\)"):
        spatial_swept_area(a, b)
