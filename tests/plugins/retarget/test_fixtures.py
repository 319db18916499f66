"""Fixtures T0–T3 of spec retargeting.md §9 and the verified claims of §5 and §7."""

from __future__ import annotations

import numpy as np
import pytest
from mirrorlab.plugins.retarget import Chain, Objective, approximate, correspondence_pairs, serial_correspondence
from mirrorlab.plugins.retarget.correspondence import serial_parents
from mirrorlab.plugins.retarget.solvers import levenberg_marquardt, multistart, paper_sweeps, start_points

from tests.plugins.retarget.optimum import optimum_bounds
from tests.tolerances import roundoff

T1_IN = Chain([1, 1, 1, 1], ["z", "y", "z", "y"])
T1_Q = [0.4, -0.3, 0.5, 0.2]
T1_OUT = Chain([2, 2], ["z", "y"])
T2_IN = Chain([1] * 6, ["z", "y", "z", "y", "z", "y"])
T2_Q = [0.3, -0.2, 0.4, 0.3, -0.5, 0.2]
T2_OUT = Chain([1.5] * 4, ["z", "y", "z", "y"])


#: Half a unit of the spec's 6th decimal: its printed fixtures are that far from the values.
PRINTED = 5e-7


def objective(inp: Chain, out: Chain) -> Objective:

    n = inp.n_links + 1
    return Objective(out, correspondence_pairs(serial_parents(n), inp.lengths, out), serial_parents(n))


def test_t0_identity_f_zero_and_recovery() -> None:
    rng = np.random.default_rng(3)
    chain = Chain([1.0, 0.7, 1.3, 0.5], ["zy", "y", "zyx", "z"])
    q_in = rng.uniform(-0.8, 0.8, chain.dof) + 0.01 * np.arange(5)[:, None]     # a slow motion
    X = chain.forward(q_in)
    obj = objective(chain, chain)
    arms = obj.arms(X)
    # at the input's own angles every residual is a difference of equal positions: rounding of
    # coordinates up to |X| (the former 1e-28 was below that: 5 pairs x (eps |X| x ops)²)
    assert np.abs(obj.value(q_in, arms, np.eye(3), np.zeros(3))).max() <= 5 * roundoff(scale=np.abs(X).max(), ops=10) ** 2
    res = approximate(X, chain, q0=q_in[0] + 0.05, multistart=False, max_iter=100, block=0)
    assert (res.iterations < 100).all()                  # stopped by its tolerances, as the bounds assume
    bound = optimum_bounds(obj, res.q, arms)             # f* = 0 at q_in: how far LM's stop may be
    assert (np.abs(res.q - q_in).max(axis=1) <= bound.q).all()
    assert (np.abs(res.joints - X).max(axis=(1, 2)) <= bound.joints).all()
    assert (res.f <= bound.f).all()


def test_t1_input_joints_correspondence_and_optimum() -> None:
    X = T1_IN.forward(T1_Q)
    expected = [[0, 0, 0], [0.921061, 0.389418, 0], [1.800984, 0.761444, 0.295520],
                [2.386492, 1.529507, 0.554864], [3.014405, 2.305123, 0.619241]]
    # the spec prints 6 decimals (±5e-7 each); forward kinematics rounds at |X| <= 3
    assert np.abs(X - expected).max() <= PRINTED + roundoff(scale=np.abs(X).max(), ops=10)
    assert serial_correspondence(T1_IN.lengths, T1_OUT.lengths).tolist() == [0, 2, 3]
    obj = objective(T1_IN, T1_OUT)
    for method in ("lm", "paper"):
        res = approximate(X[None], T1_OUT, method, max_iter=200)
        # the printed optimum (±5e-7) and the solver's distance from the exact one at its stop
        b = optimum_bounds(obj, res.q, obj.arms(X[None]), method=method)
        assert np.abs(res.q[0] - [0.604032, -0.333016]).max() <= PRINTED + b.q[0], method
        assert abs(res.f[0] - 0.282540) <= PRINTED + b.f[0], method
        assert np.abs(res.joints[0] - [[0, 0, 0], [1.646105, 1.135931, 0], [3.201774, 2.209455, 0.653789]]).max() \
            <= PRINTED + b.joints[0]


def test_t2_optimum() -> None:
    X = T2_IN.forward(T2_Q)
    assert serial_correspondence(T2_IN.lengths, T2_OUT.lengths).tolist() == [0, 1, 3, 4, 5]
    obj = objective(T2_IN, T2_OUT)
    for method in ("lm", "paper"):
        res = approximate(X[None], T2_OUT, method, max_iter=200)
        b = optimum_bounds(obj, res.q, obj.arms(X[None]), method=method)   # as in T1
        assert np.abs(res.q[0] - [0.438238, -0.122719, -0.071623, 0.435642]).max() <= PRINTED + b.q[0], method
        assert abs(res.f[0] - 0.163601) <= PRINTED + b.f[0], method
        assert np.abs(res.joints[0, -1] - [5.426871, 2.317178, -0.095424]).max() <= PRINTED + b.joints[0]


def test_t2_fifty_start_multistart_agrees() -> None:
    obj = objective(T2_IN, T2_OUT)
    arms = obj.arms(T2_IN.forward([T2_Q]))
    ms = multistart(obj, start_points(obj, 50, seed=1), arms, np.eye(3), np.zeros(3))
    lm = levenberg_marquardt(obj, np.zeros((1, 4)), arms, np.eye(3), np.zeros(3), max_iter=200)
    # two LM stops near the same minimum: each within its bound of it (the former 1e-6 on q was below
    # the bound LM's ftol allows here, 2.5e-6 rad)
    b_ms, b_lm = optimum_bounds(obj, ms.q, arms), optimum_bounds(obj, lm.q, arms)
    assert abs(ms.f[0] - lm.f[0]) <= b_ms.f[0] + b_lm.f[0]
    wrapped = (ms.q[0] + np.pi) % (2 * np.pi) - np.pi
    assert np.abs(wrapped - lm.q[0]).max() <= b_ms.q[0] + b_lm.q[0]


#: The T2 trial (of 20 poses from seed 5) in which LM from q = 0 misses the optimum.
LM_TRAP = 18


def section5_poses(dof: int, n: int = 20, seed: int = 5) -> np.ndarray:
    """The §5 check's random input angles (n, dof) rad, uniform in ±0.8 rad."""
    return np.random.default_rng(seed).uniform(-0.8, 0.8, (n, dof))


@pytest.mark.parametrize("case", ["T1", "T2"])
def test_section5_newton_sweep_matches_lm_and_multistart(case: str) -> None:
    inp, out = (T1_IN, T1_OUT) if case == "T1" else (T2_IN, T2_OUT)
    obj = objective(inp, out)
    q_in = section5_poses(inp.dof)
    arms = obj.arms(inp.forward(q_in))
    zero = np.zeros((20, out.dof))
    newton = paper_sweeps(obj, zero, arms, np.eye(3), np.zeros(3), sweeps=None)
    lm = levenberg_marquardt(obj, zero, arms, np.eye(3), np.zeros(3), max_iter=200)
    best = multistart(obj, start_points(obj, 40, seed=2), arms, np.eye(3), np.zeros(3))
    # 1e-6 mm² separates "the same minimum" (f within the solvers' bounds, ~1e-11 here) from "another
    # minimum" (f higher by 0.1 and more): a classification threshold, not a precision claim
    same = optimum_bounds(obj, newton.q, arms, method="paper").f + optimum_bounds(obj, best.q, arms).f
    assert (np.abs(newton.f - best.f) <= same).all() and same.max() < 1e-6
    # plain LM from q = 0 stops in another minimum in T2 trial 18 (see the next test); the tracker's
    # multistart fallback removes that
    assert np.flatnonzero(np.abs(lm.f - best.f) > 1e-6).tolist() == ([] if case == "T1" else [LM_TRAP])
    tracked = approximate(inp.forward(q_in), out, block=0, max_iter=200, jump_factor=0.0, jump_abs=0.0)
    assert np.abs(tracked.f - best.f).max() < 1e-6                  # the same minimum, as above


def test_section5_lm_miss_is_a_second_local_minimum_chosen_by_the_first_step() -> None:
    """Why spec §5's "LM agrees in every trial" fails for T2 trial 18: f has a second strict local
    minimum (the elbow bent the other way), LM's first step from q = 0 lands in its basin, the
    per-joint scheme's first 0.3 rad steps do not. Not a tolerance (MINPACK with 1e-15 tolerances
    stops at the same point), not lag (both run to convergence). docs/retarget.md has the rates."""
    obj = objective(T2_IN, T2_OUT)
    arms = obj.arms(T2_IN.forward(section5_poses(6)[LM_TRAP:LM_TRAP + 1]))
    I3, o = np.eye(3), np.zeros(3)
    zero = np.zeros((1, 4))
    lm = levenberg_marquardt(obj, zero, arms, I3, o, max_iter=200)
    best = multistart(obj, start_points(obj, 40, seed=2), arms, I3, o)
    newton = paper_sweeps(obj, zero, arms, I3, o, sweeps=None)
    b_lm, b_best = optimum_bounds(obj, lm.q, arms), optimum_bounds(obj, best.q, arms)
    b_newton = optimum_bounds(obj, newton.q, arms, method="paper")
    # printed to 6 decimals (±5e-7), plus each solver's distance from its minimum
    assert lm.f[0] == pytest.approx(1.693810, abs=PRINTED + b_lm.f[0])
    assert best.f[0] == pytest.approx(0.287316, abs=PRINTED + b_best.f[0])
    assert newton.f[0] == pytest.approx(best.f[0], abs=b_newton.f[0] + b_best.f[0])
    assert np.abs(lm.q[0] - [0.586333, -0.941001, -0.534716, 1.057766]).max() <= PRINTED + b_lm.q[0]

    def gradient(q: np.ndarray) -> np.ndarray:
        r, J, _ = obj.residuals_jacobian(q[None], arms, I3, o)
        return 2.0 * np.einsum("pi,pij->j", r[0], J[0])

    q_lm = lm.q[0]
    h = 1e-6
    H = np.array([(gradient(q_lm + h * e) - gradient(q_lm - h * e)) / (2 * h) for e in np.eye(4)])
    # stationary (mm²/rad): |g| <= |H| |q - q*| at LM's stop, plus the gradient's rounding
    r_lm, J_lm, pos_lm = obj.residuals_jacobian(q_lm[None], arms, I3, o)
    g_round = roundoff(scale=2 * np.abs(r_lm).sum() * np.abs(J_lm).max() + 2 * np.sqrt(lm.f[0]) * np.abs(pos_lm).max(),
                       ops=20)
    assert np.abs(gradient(q_lm)).max() <= np.abs(np.linalg.eigvalsh((H + H.T) / 2)).max() * b_lm.q[0] + g_round
    # positive definite: a strict minimum (its smallest eigenvalue is O(1); 0.2 leaves room for the
    # O(h²) and eps |g| / h errors of the difference quotient, ~1e-10)
    assert np.linalg.eigvalsh((H + H.T) / 2).min() > 0.2
    from scipy.optimize import least_squares

    minpack = least_squares(lambda x: obj.residuals(x[None], arms, I3, o)[0].ravel(), np.zeros(4),
                            jac=lambda x: obj.residuals_jacobian(x[None], arms, I3, o)[1].reshape(-1, 4),
                            method="lm", xtol=1e-15, ftol=1e-15, gtol=1e-15)
    # MINPACK to 1e-15 lands on the same minimum: within LM's bound of it (MINPACK's own is ~1e-7 rad)
    b_minpack = optimum_bounds(obj, minpack.x[None], arms)
    assert np.abs(minpack.x - q_lm).max() <= b_lm.q[0] + b_minpack.q[0]
    assert 2 * minpack.cost == pytest.approx(lm.f[0], abs=b_lm.f[0] + b_minpack.f[0])
    # the first step decides: LM puts the elbow (q3) at +0.9 rad on the local minimum's side (+1.06),
    # the first Newton sweep at -0.3 rad on the optimum's side (-0.81)
    first_lm = levenberg_marquardt(obj, zero, arms, I3, o, max_iter=1).q[0, 3]
    first_sweep = paper_sweeps(obj, zero, arms, I3, o, sweeps=1).q[0, 3]
    # one LM step (a 4x4 solve, printed to 3 decimals: ±5e-4) and the sweep's step limit, 0.3 rad,
    # taken whole (rounding of q + step only)
    assert first_lm == pytest.approx(0.907, abs=1e-3) and first_sweep == pytest.approx(-0.3, abs=roundoff(scale=0.3))
    assert best.q[0, 3] == pytest.approx(-0.812473, abs=PRINTED + b_best.q[0])


def test_section5_lm_from_zero_misses_rarely_per_joint_newton_never_in_400_more_poses() -> None:
    obj = objective(T2_IN, T2_OUT)
    arms = obj.arms(T2_IN.forward(section5_poses(6, 400, seed=2026)))
    I3, o, zero = np.eye(3), np.zeros(3), np.zeros((400, 4))
    best = multistart(obj, start_points(obj, 40, seed=2), arms, I3, o).f
    lm = levenberg_marquardt(obj, zero, arms, I3, o, max_iter=200).f
    newton = paper_sweeps(obj, zero, arms, I3, o, sweeps=None).f
    # the same classification threshold as above (another minimum: f higher by >= 0.1)
    assert np.flatnonzero(lm - best > 1e-6).tolist() == [201, 246]
    # LM is never below the best minimum by more than their bounds (~1e-11): it is never better
    assert np.abs(newton - best).max() < 1e-6 and (lm - best).min() > -1e-9


def t3_input(frames: int = 100) -> np.ndarray:
    t = np.arange(frames)
    return T2_IN.forward(0.6 * np.sin(0.05 * t[:, None] + np.arange(6)))


def test_t3_paper_mode_lag_within_bounds() -> None:
    X = t3_input()
    ref = approximate(X, T2_OUT, "lm", max_iter=100)
    paper = approximate(X, T2_OUT, "paper", sweeps=3)
    lag = paper.f - ref.f
    obj = objective(T2_IN, T2_OUT)
    # lm is converged: paper is never better than lm's bound from the exact minimum allows
    assert (lag >= -optimum_bounds(obj, ref.q, obj.arms(X)).f).all()
    assert lag.max() <= 0.2                                     # the spec's bounds on the 3-sweep lag
    assert paper.f.mean() <= 1.02 * ref.f.mean()
    # the spec's means (4 decimals, ±5e-5), which it computed with its own stopping rules: 5e-4 is
    # a comparison with a figure of the spec, not a derived bound
    assert ref.f.mean() == pytest.approx(0.2417, abs=5e-4)
    assert paper.f.mean() == pytest.approx(0.2444, abs=5e-4)    # and its 3-sweep mean


def test_t3_blocked_batch_equals_sequential() -> None:
    X = t3_input(400)
    seq = approximate(X, T2_OUT, block=0)
    obj = objective(T2_IN, T2_OUT)
    b_seq = optimum_bounds(obj, seq.q, obj.arms(X))
    for block in (8, 32):
        par = approximate(X, T2_OUT, block=block)
        # every frame converges to the same minimum from the same side of the seam check: within
        # both stops' bounds of it
        b_par = optimum_bounds(obj, par.q, obj.arms(X))
        assert (np.abs(par.q - seq.q).max(axis=1) <= b_seq.q + b_par.q).all()
        assert (np.abs(par.f - seq.f) <= b_seq.f + b_par.f).all()
    assert len(seq.jumps(0.5)) == 0
