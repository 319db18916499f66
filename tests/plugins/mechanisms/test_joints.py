"""Spatial joints between rigid marker groups: the RSSR linkage's revolute and spherical joints."""

from __future__ import annotations

import numpy as np
import pytest
from mirrorlab.plugins.kinematics.rssr import THESIS_RSSR, rssr_state
from mirrorlab.plugins.mechanisms import DegenerateGeometry, InvalidPoints
from mirrorlab.plugins.mechanisms.grouping import rigid_groups
from mirrorlab.plugins.mechanisms.joints import revolute_joint, spherical_joint
from scipy.spatial.transform import Rotation

from tests.derived_bounds import perturbation_rounding
from tests.tolerances import roundoff

P = THESIS_RSSR
THETA = np.linspace(0, 2 * np.pi, 37)[:-1]
T_ALL = len(THETA)



def _cluster(origin: np.ndarray, R: np.ndarray, offsets: np.ndarray) -> np.ndarray:
    return origin[:, None] + np.einsum("tij,mj->tmi", R, offsets)


def _rssr_bodies() -> dict[str, np.ndarray]:
    """Ground, crank and coupler marker clusters moving with the thesis RSSR (mm)."""
    s = rssr_state(THETA)
    e = np.asarray(P.e) / np.linalg.norm(P.e)
    T = len(THETA)
    ground = np.broadcast_to(np.array([[-100.0, 50, 0], [80, 120, 10], [0, -150, -40], [60, 0, 90]]), (T, 4, 3))
    R_crank = Rotation.from_rotvec(np.outer(THETA, e)).as_matrix()
    crank = _cluster(np.broadcast_to(np.asarray(P.O_A, float), (T, 3)), R_crank,
                     np.array([[20.0, 10, 5], [45, -8, 12], [30, 15, -10]]))
    # coupler: the minimal rotation carrying the first S_A -> S_C direction to the current one, about S_A
    u = (s.S_C - s.S_A) / np.linalg.norm(s.S_C - s.S_A, axis=1, keepdims=True)
    R_cpl = np.stack([Rotation.align_vectors(u[k][None], u[0][None])[0].as_matrix() for k in range(T)])
    coupler = _cluster(s.S_A, R_cpl, np.array([[60.0, 20, 0], [150, -30, 20], [200, 10, -25]]))
    return {"ground": ground, "crank": crank, "coupler": coupler, "S_A": s.S_A}


def _hinge_rounding(body1: np.ndarray, body2: np.ndarray) -> np.ndarray:
    """Rounding bounds on the hinge's direction (frame 0), axis points, angles and residuals, from
    its measured sensitivity (tests/derived_bounds.py)."""
    m = body1.shape[1]

    def outputs(p: np.ndarray) -> np.ndarray:
        j = revolute_joint(p[:, :m], p[:, m:])
        return np.concatenate([j.direction[0], j.point.ravel(), np.unwrap(j.angle), j.residual])

    return perturbation_rounding(outputs, np.concatenate([body1, body2], 1))


def test_input_crank_hinge_is_recovered_exactly() -> None:
    b = _rssr_bodies()
    j = revolute_joint(b["ground"], b["crank"])
    e = np.asarray(P.e) / np.linalg.norm(P.e)
    # exact markers: rounding through the pose fits and the axis solve, from the fit's measured
    # sensitivity (tests/derived_bounds.py)
    T = len(THETA)
    bound = _hinge_rounding(b["ground"], b["crank"])
    tol_dir, tol_point, tol_angle, tol_res = (bound[:3].max(), bound[3:3 + 3 * T].max(),
                                              bound[3 + 3 * T:3 + 4 * T].max(), bound[3 + 4 * T:].max())
    # |d·e| = 1 - |dd|²/2 for a direction error dd ⟂ e (|dd|² <= 3 tol² over 3 components):
    # quadratic, plus the dot product's rounding
    assert abs(abs(j.direction[0] @ e) - 1) <= 3 * tol_dir**2 / 2 + roundoff(ops=3)
    off = j.point - np.asarray(P.O_A)
    assert np.abs(np.cross(off, e)).max() <= tol_point                   # the point lies on the true axis
    assert j.rms <= tol_res
    np.testing.assert_allclose(np.unwrap(j.angle) * np.sign(j.direction[0] @ e), THETA, rtol=0,
                               atol=tol_angle + roundoff(scale=2 * np.pi))


def test_crank_coupler_ball_joint_is_recovered_exactly() -> None:
    b = _rssr_bodies()
    j = spherical_joint(b["crank"], b["coupler"])
    tol_centre, tol_res = _ball_rounding(b["crank"], b["coupler"])
    np.testing.assert_allclose(j.centre, b["S_A"], rtol=0, atol=tol_centre)
    assert j.rms <= tol_res


def test_joints_with_noise_and_gaps() -> None:
    b = _rssr_bodies()
    rng = np.random.default_rng(0)
    noisy = {k: v + rng.normal(scale=0.2, size=v.shape) for k, v in b.items() if k != "S_A"}
    noisy["coupler"][3:5, 1] = np.nan
    j = spherical_joint(noisy["crank"], noisy["coupler"])
    err = np.linalg.norm(j.centre - b["S_A"], axis=-1)
    # statistical (fixed seed): 0.2 mm noise amplified by the near-hinge geometry of the crank-coupler
    # pair (condition > 10, see the last test) gives 2.2 mm RMS; rounding is ~1e-12 of that, so 3 mm
    # is a stable margin, not a derived bound
    assert np.isfinite(err).all() and np.sqrt(np.mean(err**2)) < 3.0
    h = revolute_joint(noisy["ground"], noisy["crank"])
    e = np.asarray(P.e) / np.linalg.norm(P.e)
    # 0.2 mm noise on markers 20-50 mm from the axis over 36 frames: ~0.2 / 40 / sqrt(36) rad ~ 0.05°;
    # 0.5° and 1 mm are plausibility margins for the same statistics
    assert np.degrees(np.arccos(min(1.0, abs(h.direction[0] @ e)))) < 0.5
    assert np.abs(np.cross(h.point[0] - np.asarray(P.O_A), e)).max() < 1.0


def test_grouping_then_joints_from_shuffled_columns() -> None:
    b = _rssr_bodies()
    pts = np.concatenate([b["ground"], b["crank"], b["coupler"]], 1)
    perm = np.random.default_rng(3).permutation(pts.shape[1])
    shuffled = pts[:, perm]
    g = rigid_groups(shuffled)
    assert g.ground is not None and len(g.moving) == 2
    crank_cols = {int(np.flatnonzero(perm == k)[0]) for k in (4, 5, 6)}
    crank = next(m for m in g.moving if set(m) == crank_cols)
    coupler = next(m for m in g.moving if m != crank)
    hinge = revolute_joint(shuffled[:, list(g.groups[g.ground])], shuffled[:, list(crank)])
    ball = spherical_joint(shuffled[:, list(crank)], shuffled[:, list(coupler)])
    assert hinge.rms <= _hinge_rounding(shuffled[:, list(g.groups[g.ground])], shuffled[:, list(crank)])[-T_ALL:].max()
    np.testing.assert_allclose(ball.centre, b["S_A"], rtol=0,
                               atol=_ball_rounding(shuffled[:, list(crank)], shuffled[:, list(coupler)])[0])


def _ball_rounding(body1: np.ndarray, body2: np.ndarray) -> tuple[float, float]:
    """Rounding bounds on the ball joint's centre and residual rms, from its measured sensitivity."""
    m = body1.shape[1]

    def outputs(p: np.ndarray) -> np.ndarray:
        j = spherical_joint(p[:, :m], p[:, m:])
        return np.concatenate([j.centre.ravel(), [j.rms]])

    bound = perturbation_rounding(outputs, np.concatenate([body1, body2], 1))
    # the truth (rssr_state's S_A) carries its own rounding of coordinates up to a few hundred mm
    return float(bound[:-1].max()) + roundoff(scale=float(np.abs(body2).max()), ops=20), float(bound[-1])


def test_degenerate_and_bad_input() -> None:
    b = _rssr_bodies()
    with pytest.raises(DegenerateGeometry, match="revolute_joint"):
        spherical_joint(b["ground"], b["crank"])
    with pytest.raises(DegenerateGeometry, match="barely rotate"):
        revolute_joint(b["ground"], b["ground"] + [5.0, 0, 0])
    with pytest.raises(InvalidPoints, match="at least 3 markers"):
        spherical_joint(b["crank"][:, :2], b["coupler"])
    with pytest.raises(InvalidPoints, match="same frames"):
        spherical_joint(b["crank"][:10], b["coupler"])


def test_condition_flags_a_nearly_single_axis_relative_rotation() -> None:
    b = _rssr_bodies()
    near_hinge = spherical_joint(b["crank"], b["coupler"]).condition
    R1, R2 = (Rotation.random(20, random_state=k).as_matrix() for k in (1, 2))
    q = np.array([[50.0, 0, 0], [0, 40, 0], [0, 0, 30], [20, 20, 20]])
    c = np.array([10.0, 20, 30])
    t1 = np.zeros((20, 3))
    t2 = t1 + np.einsum("tij,j->ti", R1, c) - np.einsum("tij,j->ti", R2, c)
    free = spherical_joint(np.einsum("tij,mj->tmi", R1, q) + t1[:, None], np.einsum("tij,mj->tmi", R2, q) + t2[:, None])
    # condition numbers (sigma_max / sigma_min) of well-spread random rotations vs a nearly single-axis
    # motion: structural figures, orders of magnitude apart
    assert free.condition < 3 and near_hinge > 10
