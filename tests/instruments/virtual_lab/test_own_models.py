"""The virtual lab's own optics and motion models against the plugins they validate.

The lab computes its ground truth without the photogrammetry and kinematics plugins (so that a bug
in one would not cancel out in the truth that validates it); each of its models is checked here
against the plugin's, to the rounding of the two computations.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from mirrorlab.instruments.virtual_lab import LabCamera, Mirror, look_at_camera
from mirrorlab.instruments.virtual_lab import motion as lab
from mirrorlab.plugins.kinematics import rssr as plugin_rssr
from mirrorlab.plugins.kinematics import synthetic as plugin_box
from mirrorlab.plugins.photogrammetry import PinholeCamera, reflect, virtual_camera

from tests.tolerances import abs_err, roundoff

DISTORTION = (-0.08, 0.02, 0.0012, -0.0007, 0.004)


def _pinhole(camera: LabCamera) -> PinholeCamera:
    return PinholeCamera(camera.K, camera.dist, camera.R, camera.t, camera.image_size)


@settings(max_examples=40, deadline=None)
@given(st.floats(-0.6, 0.6), st.floats(-0.4, 0.4), st.floats(0.0, 0.3), st.integers(0, 2**31))
def test_lab_camera_projects_as_the_photogrammetry_pinhole(tilt: float, roll: float, offset: float, seed: int) -> None:
    cam = look_at_camera((300.0, 200.0, 1500.0), (-150.0 + 400 * tilt, -60.0, 0.0), 30.0, (36.0, 24.0),
                         (1800, 1200), roll=roll, distortion=DISTORTION, principal_offset_px=(40 * offset, -25 * offset))
    # points in front of the camera across (and a little beyond) its field
    rng = np.random.default_rng(seed)
    C = cam.camera_center
    P = C + rng.uniform(-0.5, 0.5, (200, 2)) @ cam.R[:2] * 1500.0 + rng.uniform(800.0, 2500.0, (200, 1)) * cam.R[2]
    mine, theirs = cam.project(P), _pinhole(cam).project(P)
    # ~20 roundings (camera frame, division, polynomial, K) of pixel coordinates up to ~|px|
    assert abs_err(mine, theirs) <= roundoff(scale=np.abs(theirs).max(), ops=20)


def test_lab_camera_pads_short_distortion_and_refuses_long() -> None:
    K = np.array([[1000.0, 0.0, 320.0], [0.0, 1000.0, 240.0], [0.0, 0.0, 1.0]])
    four = LabCamera(K, [0.1, -0.05, 0.001, 0.002], np.eye(3), np.zeros(3))
    P = np.array([[100.0, -50.0, 900.0], [-200.0, 120.0, 1100.0]])
    assert four.dist.tolist() == [0.1, -0.05, 0.001, 0.002, 0.0]
    assert abs_err(four.project(P), _pinhole(four).project(P)) <= roundoff(scale=1000.0, ops=20)
    with pytest.raises(ValueError, match="5 distortion coefficients"):
        LabCamera(K, np.zeros(8), np.eye(3), np.zeros(3))


@settings(max_examples=60, deadline=None)
@given(st.floats(-1000, 1000), st.floats(-1000, 1000), st.floats(-1000, 1000), st.floats(0.05, 1.5),
       st.floats(-3.1, 3.1))
def test_mirror_reflection_and_virtual_camera_match_the_photogrammetry_plugin(x: float, y: float, z: float,
                                                                              tilt: float, turn: float) -> None:
    n = np.array([np.cos(tilt) * np.cos(turn), np.sin(tilt), np.cos(tilt) * np.sin(turn)])
    m = Mirror((-300.0, 50.0, 400.0), n, 1000.0, 800.0)
    points = np.array([[x, y, z], [0.5 * x, -y, 2 * z]])
    # x - 2 ((x - G).n) n: ~8 roundings of coordinates up to |x| + |G|
    reach = np.abs(points).max() + np.abs(m.centre).max()
    assert abs_err(m.reflect(points), reflect(points, m.centre, m.normal)) <= roundoff(scale=reach, ops=8)
    camera = m.centre + 2000.0 * m.normal + np.array([300.0, -200.0, 100.0])
    expected = virtual_camera(camera, m.centre, m.normal).center
    assert abs_err(m.virtual_centre(camera), expected) <= roundoff(scale=np.abs(camera).max() + reach, ops=8)
    with pytest.raises(ValueError, match="not in front of the mirror"):
        m.virtual_centre(m.centre - 10.0 * m.normal)


@settings(max_examples=60, deadline=None)
@given(st.lists(st.floats(-2.0, 2.0), min_size=3, max_size=3), st.lists(st.floats(-1.0, 1.0), min_size=3, max_size=3),
       st.floats(-7.0, 7.0))
def test_rotate_matches_the_kinematics_rotate(v: list[float], axis: list[float], angle: float) -> None:
    if np.linalg.norm(axis) < 1e-3:
        axis = [0.0, 0.0, 1.0]
    # Rodrigues' three terms, each a few roundings of |v|
    assert abs_err(lab.rotate(v, axis, angle), plugin_rssr.rotate(v, axis, angle)) <= \
        roundoff(scale=max(np.abs(v).max(), 1e-300), ops=12)


@pytest.mark.parametrize("branch", [1, -1])
def test_rssr_motion_matches_the_kinematics_rssr_state(branch: int) -> None:
    theta = np.linspace(-7.0, 7.0, 701)
    theta_dot, theta_ddot = 0.58 * np.cos(theta), 0.3
    mine = lab.rssr_motion(theta, theta_dot, theta_ddot, dataclasses.replace(lab.THESIS_RSSR, branch=branch))
    theirs = plugin_rssr.rssr_state(theta, theta_dot, theta_ddot, plugin_rssr.THESIS_RSSR, branch=branch)
    # The same geometry: the plugin's is the spec's, field for field.
    assert dataclasses.asdict(lab.THESIS_RSSR) == dataclasses.asdict(plugin_rssr.THESIS_RSSR)
    # Both solve for the output crank where its circle meets the coupler's sphere; the root's
    # condition is kappa = b c / |r . (f x c)|, which vanishes at a toggle (the circle tangent to the
    # sphere). Positions and phi carry kappa eps; the rates divide by r . (f x c) once more.
    g = lab.THESIS_RSSR
    f = np.asarray(g.f) / np.linalg.norm(g.f)
    c = mine.S_C - np.asarray(g.O_A) - np.asarray(g.d)
    kappa = float(np.max(g.b * g.c / np.abs(np.sum((mine.S_C - mine.S_A) * np.cross(f, c), axis=-1))))
    reach = max(np.abs(mine.S_C).max(), np.abs(mine.S_A).max(), np.abs(g.d).max())
    assert abs_err(mine.S_A, theirs.S_A) <= roundoff(scale=reach, ops=12)
    assert abs_err(mine.S_C, theirs.S_C) <= roundoff(cond=kappa, scale=reach, ops=50)
    assert abs_err(mine.phi, theirs.phi) <= roundoff(cond=kappa, scale=np.pi, ops=50)
    for key in ("phi_dot", "phi_ddot"):
        expected = getattr(theirs, key)
        assert abs_err(getattr(mine, key), expected) <= roundoff(cond=kappa**2, scale=np.abs(expected).max(), ops=100)


def test_rssr_motion_refuses_a_linkage_that_cannot_close() -> None:
    with pytest.raises(ValueError, match="cannot close at theta"):
        lab.rssr_motion(0.0, geometry=dataclasses.replace(lab.THESIS_RSSR, b=10.0))


def test_box_inertia_and_vertices_match_the_kinematics_fixtures() -> None:
    size = np.array([200.0, 200.0, 300.0])
    # m (a² + b²) / 12 in two summation orders: a few roundings
    assert abs_err(lab.box_inertia(2.2, size / 1000), plugin_box.box_inertia(2.2, size / 1000)) <= \
        roundoff(scale=0.03, ops=6)
    assert np.array_equal(lab.box_vertices([200.0, 250.0, 300.0]), plugin_box.box_vertices([200.0, 250.0, 300.0]))


def test_torque_free_rotation_matches_the_kinematics_integration() -> None:
    inertia = lab.box_inertia(2.2, [0.2, 0.25, 0.3])                    # asymmetric: a tumbling, not precessing, body
    t = np.linspace(0.0, 1.0, 43)
    R, w = lab.torque_free_rotation(inertia, [3.0, 1.0, 6.0], t)
    theirs = plugin_box.torque_free_rotation(inertia, [3.0, 1.0, 6.0], t)
    # Two integrations (quaternion here, rotation matrix there) by DOP853 at rtol = atol = 1e-12:
    # each one's global error over the ~100 steps of 1 s stays below ~1e-10 relative; 1e-9 is 10x
    # (a method bound, not rounding).
    assert abs_err(R, theirs.R) <= 1e-9
    assert abs_err(w, theirs.omega_body) <= 1e-9 * np.abs(theirs.omega_body).max()
