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
from mirrorlab.instruments.virtual_lab.motion import rssr_motion
from mirrorlab.plugins.kinematics import kabsch, upper_limb_angles

from tests.tolerances import roundoff


def test_rssr_scene_is_the_lab_rssr_motion_exactly() -> None:
    # the lab's own RSSR (its cross-check against the kinematics plugin: test_own_models.py)
    t = np.linspace(0.0, 12.0, 37)
    s = rssr_motion(0.58 * t)
    st0 = RSSRScene().state(t)
    assert np.array_equal(st0.positions, np.stack([s.S_A, s.S_C], axis=1))
    for key in ("phi", "phi_dot", "phi_ddot"):
        assert np.array_equal(st0.analytic[key], getattr(s, key))
    placed = RSSRScene(placement=Placement.from_euler((0.1, -0.2, 0.3), (300.0, -100.0, 700.0)))
    p = placed.state(t)
    # R x + t on coordinates up to |p|: ~6 roundings
    np.testing.assert_allclose(p.positions, placed.placement.apply(st0.positions), rtol=0,
                               atol=roundoff(scale=np.abs(p.positions).max(), ops=6))
    # the thesis table (kinematics.md §6.5) at theta = 90°, printed to 3 and 6 decimals: one unit of
    # the last digit (the table's own computation, rounded)
    q = RSSRScene().state([np.pi / 2 / 0.58])
    assert np.allclose(q.positions[0, 1], (-170.933, -132.503, -85.571), rtol=0, atol=1e-3)
    assert abs(q.analytic["phi_dot"][0] - (-0.229503)) < 1e-6


def test_box_conserves_angular_momentum_and_flies_ballistically() -> None:
    box = BoxScene()
    t = np.linspace(0.0, 0.6, 26)
    s = box.state(t)
    H = s.analytic["H_world"]
    # Euler's equations integrated by DOP853 at rtol = atol = 1e-12 (scenes.py): the global error of
    # ~100 steps stays below ~1e-10 relative; 1e-9 is 10x (a method bound, not rounding)
    assert np.abs(H - H[0]).max() < 1e-9 * np.linalg.norm(H[0])
    # kinematics.md §5 fixture: 0.0715 and 0.088 exact, 0.0238333 = 0.0715 / 3 to 7 digits (3e-8 off)
    assert np.allclose(H[0], (0.0715, 0.0238333, 0.088), rtol=0, atol=1e-6)
    R, origin, rms, _ = kabsch(box.vertices, s.positions)
    # positions R v + c (|P| up to ~600 mm) round by eps |P|; Kabsch turns that into a rotation error
    # over the half-extent (100 mm), and its residual is a backward error of the same size
    reach = np.abs(s.positions).max()
    np.testing.assert_allclose(R, s.analytic["R"], rtol=0, atol=roundoff(cond=reach / 100.0, ops=20))
    assert rms.max() <= roundoff(scale=reach, ops=20)
    centre = np.array(box.centre0) + t[:, None] * box.velocity0 + 0.5 * t[:, None] ** 2 * [0, -9806.65, 0]
    # the mean of 8 symmetric vertices R v + c is c up to the rounding of the 8 terms
    np.testing.assert_allclose(s.positions.mean(axis=1), centre, rtol=0, atol=roundoff(scale=reach, ops=16))
    # self-occlusion: seen from far along +x exactly the four +x vertices are visible
    s0 = box.state([0.0])
    hidden = box.occluded(s0, [1e6, 0.0, 0.0])[0]
    assert hidden.tolist() == (box.vertices[:, 0] < 0).tolist()


def test_four_bar_closes_and_markers_are_rigid() -> None:
    fb = FourBarScene()
    s = fb.state(np.linspace(0.0, 2 * np.pi / fb.omega, 31))
    a = s.analytic
    np.testing.assert_allclose(np.linalg.norm(a["J1"], axis=1), 100.0, rtol=0, atol=roundoff(scale=100.0, ops=6))
    # J2 = J1 + along e_x + h e_y with h = sqrt(L3^2 - along^2): the radicand's rounding eps L3^2 moves h
    # by eps L3^2 / h, largest where J1, J2, G2 come closest to a line
    J21, G21 = a["J2"] - a["J1"], a["G2"] - a["J1"]
    h = np.abs(np.cross(J21, G21)[:, 2]) / np.linalg.norm(G21, axis=1)
    closure = roundoff(cond=float(np.max(fb.coupler / h)), scale=fb.frame + fb.crank, ops=10)
    np.testing.assert_allclose(np.linalg.norm(J21, axis=1), 220.0, rtol=0, atol=closure)
    np.testing.assert_allclose(np.linalg.norm(a["J2"] - a["G2"], axis=1), 133.0, rtol=0, atol=closure)
    p = s.positions
    for i, j in ((3, 4), (5, 6), (7, 8), (0, 1)):                        # two markers on one link
        d = np.linalg.norm(p[:, i] - p[:, j], axis=1)
        # both from the same unit link direction and placement: ~12 roundings of the coordinates
        assert np.ptp(d) <= roundoff(scale=np.abs(p).max(), ops=12)
    gaps = np.linalg.norm(p[:, :, None] - p[:, None], axis=-1) + np.eye(9) * 1e9
    assert gaps.min() > 2 * fb.marker_radius                                # markers never touch


def test_upper_limb_bar_and_elbow_angle_match_the_kinematics_plugin() -> None:
    ul = UpperLimbScene()
    s = ul.state(np.linspace(0.0, ul.period, 21))
    P = s.positions
    # chains of 4-5 rotations applied to coordinates up to ~1.5e3 mm: ~20 roundings of |P|
    reach = np.abs(P).max()
    np.testing.assert_allclose(np.linalg.norm(P[:, 5] - P[:, 4], axis=1), 700.0, rtol=0, atol=roundoff(scale=reach, ops=20))
    np.testing.assert_allclose((P[:, 4] + P[:, 5]) / 2, s.analytic["P6"], rtol=0, atol=roundoff(scale=reach, ops=20))
    ang = upper_limb_angles(P[:, 0], P[:, 1], P[:, 2], P[:, 3], P[:, 4], P[:, 5])
    # (6.7) arccos of a cosine from differences of those positions: relative error (|P| / the shorter
    # segment) eps, over sin(theta3)
    segment = min(ul.upper_arm, ul.forearm)
    kappa = reach / segment / np.sin(s.analytic["theta3"]).min()
    np.testing.assert_allclose(ang.theta3, s.analytic["theta3"], rtol=0, atol=roundoff(cond=kappa, ops=20))


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
    # x - 2 ((x - c).n) n, ~8 roundings of coordinates up to |x| + |c|
    reach = np.abs(P).max() + np.abs(m.centre).max()
    np.testing.assert_allclose(v.virtual_points[0, 0], V, rtol=0, atol=roundoff(scale=reach, ops=8))
    if not v.virtual_visible[0, 0, 0] or not v.real_visible[0, 0]:
        return
    # the projection of V: pixels ~1e3 from a ~20-rounding pinhole-plus-distortion evaluation, after V's error
    px = lab.camera.project(V)[0]
    np.testing.assert_allclose(v.virtual_xy[0, 0, 0], px, rtol=0, atol=roundoff(scale=np.abs(px).max(), ops=20))
    e = lab.camera.project(m.virtual_centre(lab.camera.camera_center)[None])[0]   # mirror epipole
    r, q = v.real_xy[0, 0] - e, v.virtual_xy[0, 0, 0] - e
    # both image points and the epipole carry ~20 roundings of their pixel coordinates; r and q are
    # differences from the epipole, so the sine of their angle is good to that over |r| and |q|
    pix = roundoff(scale=max(np.abs(e).max(), np.abs(px).max(), np.abs(v.real_xy[0, 0]).max()), ops=20)
    assert abs(r[0] * q[1] - r[1] * q[0]) <= pix * (np.linalg.norm(r) + np.linalg.norm(q))


def test_calibration_grids() -> None:
    g = calibration_grid(60.0, (5, 4), (10.0, -20.0))
    assert g.shape == (20, 3) and np.all(g[:, 2] == 0.0)
    # offsets + multiples of 60 mm: a few roundings of the coordinates
    atol = roundoff(scale=np.abs(g).max(), ops=4)
    assert np.allclose(np.diff(np.unique(g[:, 0])), 60.0, rtol=0, atol=atol)
    assert np.allclose(np.diff(np.unique(g[:, 1])), 60.0, rtol=0, atol=atol)
    assert np.allclose(g[:, :2].mean(axis=0), (10.0, -20.0), rtol=0, atol=roundoff(scale=np.abs(g).max(), ops=20))
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
