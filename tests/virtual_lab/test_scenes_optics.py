"""Virtual lab: scenes against their analytic models, mirror visibility and virtual images, grids."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from mirrorlab.instruments.virtual_lab import (
    SCENE_NAMES,
    BoxScene,
    FourBarScene,
    Mirror,
    Placement,
    RSSRScene,
    UpperLimbScene,
    calibration_grid,
    look_at_camera,
    make_lab,
    thesis_grid_points,
    view_points,
)
from mirrorlab.plugins.kinematics import kabsch, rssr_state, upper_limb_angles


def test_rssr_scene_is_rssr_state_exactly() -> None:
    t = np.linspace(0.0, 12.0, 37)
    s = rssr_state(0.58 * t)
    st0 = RSSRScene().state(t)
    assert np.array_equal(st0.positions, np.stack([s.S_A, s.S_C], axis=1))
    for key in ("phi", "phi_dot", "phi_ddot"):
        assert np.array_equal(st0.analytic[key], getattr(s, key))
    placed = RSSRScene(placement=Placement.from_euler((0.1, -0.2, 0.3), (300.0, -100.0, 700.0)))
    p = placed.state(t)
    assert np.allclose(p.positions, placed.placement.apply(st0.positions), atol=1e-12)
    # the thesis table (kinematics.md §6.5) at theta = 90°
    q = RSSRScene().state([np.pi / 2 / 0.58])
    assert np.allclose(q.positions[0, 1], (-170.933, -132.503, -85.571), atol=1e-3)
    assert abs(q.analytic["phi_dot"][0] - (-0.229503)) < 1e-6


def test_box_conserves_angular_momentum_and_flies_ballistically() -> None:
    box = BoxScene()
    t = np.linspace(0.0, 0.6, 26)
    s = box.state(t)
    H = s.analytic["H_world"]
    assert np.abs(H - H[0]).max() < 1e-9 * np.linalg.norm(H[0])
    assert np.allclose(H[0], (0.0715, 0.0238333, 0.088), atol=1e-6)        # kinematics.md §5 fixture
    R, origin, rms, _ = kabsch(box.vertices, s.positions)
    assert np.allclose(R, s.analytic["R"], atol=1e-9) and rms.max() < 1e-9
    centre = np.array(box.centre0) + t[:, None] * box.velocity0 + 0.5 * t[:, None] ** 2 * [0, -9806.65, 0]
    assert np.allclose(s.positions.mean(axis=1), centre, atol=1e-9)
    # self-occlusion: seen from far along +x exactly the four +x vertices are visible
    s0 = box.state([0.0])
    hidden = box.occluded(s0, [1e6, 0.0, 0.0])[0]
    assert hidden.tolist() == (box.vertices[:, 0] < 0).tolist()


def test_four_bar_closes_and_markers_are_rigid() -> None:
    fb = FourBarScene()
    s = fb.state(np.linspace(0.0, 2 * np.pi / fb.omega, 31))
    a = s.analytic
    assert np.allclose(np.linalg.norm(a["J1"], axis=1), 100.0, atol=1e-9)
    assert np.allclose(np.linalg.norm(a["J2"] - a["J1"], axis=1), 220.0, atol=1e-9)
    assert np.allclose(np.linalg.norm(a["J2"] - a["G2"], axis=1), 133.0, atol=1e-9)
    p = s.positions
    for i, j in ((3, 4), (5, 6), (7, 8), (0, 1)):                        # two markers on one link
        d = np.linalg.norm(p[:, i] - p[:, j], axis=1)
        assert np.ptp(d) < 1e-9
    gaps = np.linalg.norm(p[:, :, None] - p[:, None], axis=-1) + np.eye(9) * 1e9
    assert gaps.min() > 2 * fb.marker_radius                                # markers never touch


def test_upper_limb_bar_and_elbow_angle_match_the_kinematics_plugin() -> None:
    ul = UpperLimbScene()
    s = ul.state(np.linspace(0.0, ul.period, 21))
    P = s.positions
    assert np.allclose(np.linalg.norm(P[:, 5] - P[:, 4], axis=1), 700.0, atol=1e-9)
    assert np.allclose((P[:, 4] + P[:, 5]) / 2, s.analytic["P6"], atol=1e-9)
    ang = upper_limb_angles(P[:, 0], P[:, 1], P[:, 2], P[:, 3], P[:, 4], P[:, 5])
    assert np.allclose(ang.theta3, s.analytic["theta3"], atol=1e-9)


def _independent_mirror_hit(C: np.ndarray, P: np.ndarray, m: Mirror) -> bool:
    """Reflected-ray test written out separately: intersect C -> P' with the plane, check the rectangle."""
    n = m.normal
    Pv = P - 2 * ((P - m.centre) @ n) * n
    d = Pv - C
    s = ((m.centre - C) @ n) / (d @ n)
    X = C + s * d - m.centre
    u, v = m.axes
    return bool((P - m.centre) @ n > 0 and 0 < s < 1 and abs(X @ u) <= m.width / 2 and abs(X @ v) <= m.height / 2)


CAM = look_at_camera((0.0, 0.0, 2000.0), (0.0, 0.0, 0.0), 20.0, (36.0, 24.0), (1800, 1200))


@settings(max_examples=60, deadline=None)
@given(st.floats(-400, 400), st.floats(-300, 300), st.floats(100, 900), st.floats(20, 60),
       st.floats(200, 1200), st.floats(200, 1200))
def test_mirror_visibility_follows_the_reflected_ray(x: float, y: float, z: float, tilt_deg: float,
                                                     w: float, h: float) -> None:
    a = np.deg2rad(tilt_deg)
    m = Mirror((-600.0, 0.0, 200.0), (np.cos(a), 0.0, np.sin(a)), w, h)
    P = np.array([[[x, y, z]]])
    v = view_points(CAM, [m], P)
    expected = _independent_mirror_hit(CAM.camera_center, P[0, 0], m)
    in_frame = np.all(np.isfinite(CAM.project(m.reflect(P[0]))))
    if v.virtual_visible[0, 0, 0]:
        assert expected and in_frame
    else:
        pxy = CAM.project(m.reflect(P[0]))[0]
        outside = not (0 <= pxy[0] <= 1799 and 0 <= pxy[1] <= 1199)
        assert not expected or outside
        assert np.isnan(v.virtual_xy[0, 0, 0]).all()


def test_a_marker_whose_reflected_ray_misses_the_mirror_is_invisible_in_it() -> None:
    P = np.array([[[100.0, 0.0, 400.0]]])
    big = Mirror((-600.0, 0.0, 200.0), (np.cos(0.7), 0.0, np.sin(0.7)), 1500.0, 1500.0)
    small = Mirror((-600.0, 0.0, 200.0), (np.cos(0.7), 0.0, np.sin(0.7)), 1500.0, 20.0)  # narrow strip
    shifted = Mirror((-600.0, 400.0, 200.0), (np.cos(0.7), 0.0, np.sin(0.7)), 1500.0, 300.0)
    assert view_points(CAM, [big], P).virtual_visible[0, 0, 0]
    assert not view_points(CAM, [shifted], P).virtual_visible[0, 0, 0]
    assert view_points(CAM, [small], P).virtual_visible[0, 0, 0] == _independent_mirror_hit(
        CAM.camera_center, P[0, 0], small)
    behind = np.array([[[-900.0, 0.0, 100.0]]])                        # behind the mirror plane
    v = view_points(CAM, [big], behind)
    assert not v.virtual_visible.any()


@settings(max_examples=40, deadline=None)
@given(st.floats(-300, 300), st.floats(-300, 300), st.floats(200, 800))
def test_virtual_image_is_the_projected_reflection_on_the_epipolar_line(x: float, y: float, z: float) -> None:
    lab = make_lab("rssr")
    m = lab.mirrors[0]
    P = np.array([[[x, y, z]]])
    v = view_points(lab.camera, [m], P)
    V = m.reflect(P[0])
    assert np.allclose(v.virtual_points[0, 0], V, atol=1e-12)
    if not v.virtual_visible[0, 0, 0] or not v.real_visible[0, 0]:
        return
    assert np.allclose(v.virtual_xy[0, 0, 0], lab.camera.project(V)[0], atol=1e-9)
    e = lab.camera.project(m.virtual_camera(lab.camera.camera_center).center[None])[0]   # mirror epipole
    r, q = v.real_xy[0, 0] - e, v.virtual_xy[0, 0, 0] - e
    assert abs(r[0] * q[1] - r[1] * q[0]) <= 1e-9 * np.linalg.norm(r) * np.linalg.norm(q)


def test_calibration_grids() -> None:
    g = calibration_grid(60.0, (5, 4), (10.0, -20.0))
    assert g.shape == (20, 3) and np.all(g[:, 2] == 0.0)
    assert np.allclose(np.diff(np.unique(g[:, 0])), 60.0) and np.allclose(np.diff(np.unique(g[:, 1])), 60.0)
    assert np.allclose(g[:, :2].mean(axis=0), (10.0, -20.0))
    p = thesis_grid_points()
    I, II = np.meshgrid(np.arange(-7, 6), np.arange(-4, 3), indexing="ij")
    num = (7 * I + II + 53).ravel()
    assert num.tolist() == list(range(91))
    assert p[53].tolist() == [0.0, 0.0, 0.0] and p[90].tolist() == [607.0, 243.0, 0.0]
    lab = make_lab("grid")
    tr = lab.truth([0.0])
    assert tr.real_visible.mean() > 0.6 and not tr.virtual_xy.size


def test_the_lab_knows_nothing_of_the_film_scanner() -> None:
    """One direction only: the film scanner films the lab (no import cycle, one scene list)."""
    import subprocess
    import sys

    probe = ("import sys, mirrorlab.instruments.virtual_lab\n"
             "print(sorted(m for m in sys.modules if m.startswith('mirrorlab.instruments.film_scanner')))")
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"
    from mirrorlab.instruments.film_scanner import FilmScanner

    assert FilmScanner.parameters["scene"].choices == ("", *SCENE_NAMES)
