"""Fixtures T0–T3 of spec retargeting.md §9 and the verified claims of §5 and §7."""

from __future__ import annotations

import numpy as np
import pytest
from mirrorlab.plugins.retarget import Chain, Objective, approximate, correspondence_pairs, serial_correspondence
from mirrorlab.plugins.retarget.correspondence import serial_parents
from mirrorlab.plugins.retarget.solvers import levenberg_marquardt, multistart, paper_sweeps, start_points

T1_IN = Chain([1, 1, 1, 1], ["z", "y", "z", "y"])
T1_Q = [0.4, -0.3, 0.5, 0.2]
T1_OUT = Chain([2, 2], ["z", "y"])
T2_IN = Chain([1] * 6, ["z", "y", "z", "y", "z", "y"])
T2_Q = [0.3, -0.2, 0.4, 0.3, -0.5, 0.2]
T2_OUT = Chain([1.5] * 4, ["z", "y", "z", "y"])


def objective(inp: Chain, out: Chain) -> Objective:
    n = inp.n_links + 1
    return Objective(out, correspondence_pairs(serial_parents(n), inp.lengths, out), serial_parents(n))


def test_t0_identity_f_zero_and_recovery() -> None:
    rng = np.random.default_rng(3)
    chain = Chain([1.0, 0.7, 1.3, 0.5], ["zy", "y", "zyx", "z"])
    q_in = rng.uniform(-0.8, 0.8, chain.dof) + 0.01 * np.arange(5)[:, None]     # a slow motion
    X = chain.forward(q_in)
    obj = objective(chain, chain)
    assert np.abs(obj.value(q_in, obj.arms(X), np.eye(3), np.zeros(3))).max() < 1e-28
    res = approximate(X, chain, q0=q_in[0] + 0.05, multistart=False, max_iter=100, block=0)
    assert np.abs(res.q - q_in).max() < 1e-6
    assert np.abs(res.joints - X).max() < 1e-6
    assert res.f.max() < 1e-12


def test_t1_input_joints_correspondence_and_optimum() -> None:
    X = T1_IN.forward(T1_Q)
    expected = [[0, 0, 0], [0.921061, 0.389418, 0], [1.800984, 0.761444, 0.295520],
                [2.386492, 1.529507, 0.554864], [3.014405, 2.305123, 0.619241]]
    assert np.abs(X - expected).max() < 5e-7
    assert serial_correspondence(T1_IN.lengths, T1_OUT.lengths).tolist() == [0, 2, 3]
    for method in ("lm", "paper"):
        res = approximate(X[None], T1_OUT, method, max_iter=200)
        assert np.abs(res.q[0] - [0.604032, -0.333016]).max() < 1e-6, method
        assert abs(res.f[0] - 0.282540) < 1e-6, method
        assert np.abs(res.joints[0] - [[0, 0, 0], [1.646105, 1.135931, 0], [3.201774, 2.209455, 0.653789]]).max() < 1e-6


def test_t2_optimum() -> None:
    X = T2_IN.forward(T2_Q)
    assert serial_correspondence(T2_IN.lengths, T2_OUT.lengths).tolist() == [0, 1, 3, 4, 5]
    for method in ("lm", "paper"):
        res = approximate(X[None], T2_OUT, method, max_iter=200)
        assert np.abs(res.q[0] - [0.438238, -0.122719, -0.071623, 0.435642]).max() < 1e-6, method
        assert abs(res.f[0] - 0.163601) < 1e-6, method
        assert np.abs(res.joints[0, -1] - [5.426871, 2.317178, -0.095424]).max() < 1e-6


def test_t2_fifty_start_multistart_agrees() -> None:
    obj = objective(T2_IN, T2_OUT)
    arms = obj.arms(T2_IN.forward([T2_Q]))
    ms = multistart(obj, start_points(obj, 50, seed=1), arms, np.eye(3), np.zeros(3))
    lm = levenberg_marquardt(obj, np.zeros((1, 4)), arms, np.eye(3), np.zeros(3), max_iter=200)
    assert abs(ms.f[0] - lm.f[0]) < 1e-12
    wrapped = (ms.q[0] + np.pi) % (2 * np.pi) - np.pi
    assert np.abs(wrapped - lm.q[0]).max() < 1e-6


@pytest.mark.parametrize("case", ["T1", "T2"])
def test_section5_newton_sweep_matches_lm_and_multistart(case: str) -> None:
    inp, out = (T1_IN, T1_OUT) if case == "T1" else (T2_IN, T2_OUT)
    obj = objective(inp, out)
    rng = np.random.default_rng(5)
    q_in = rng.uniform(-0.8, 0.8, (20, inp.dof))
    arms = obj.arms(inp.forward(q_in))
    zero = np.zeros((20, out.dof))
    newton = paper_sweeps(obj, zero, arms, np.eye(3), np.zeros(3), sweeps=None)
    lm = levenberg_marquardt(obj, zero, arms, np.eye(3), np.zeros(3), max_iter=200)
    best = multistart(obj, start_points(obj, 40, seed=2), arms, np.eye(3), np.zeros(3))
    assert np.abs(newton.f - best.f).max() < 1e-6
    # plain LM from q = 0 can stop in another basin (so does MINPACK's: seed 5, T2 trial 18 ends at
    # f = 1.6938 against 0.2873); the tracker's multistart fallback removes that
    assert np.sum(np.abs(lm.f - best.f) > 1e-6) <= 1
    tracked = approximate(inp.forward(q_in), out, block=0, max_iter=200, jump_factor=0.0, jump_abs=0.0)
    assert np.abs(tracked.f - best.f).max() < 1e-6


def t3_input(frames: int = 100) -> np.ndarray:
    t = np.arange(frames)
    return T2_IN.forward(0.6 * np.sin(0.05 * t[:, None] + np.arange(6)))


def test_t3_paper_mode_lag_within_bounds() -> None:
    X = t3_input()
    ref = approximate(X, T2_OUT, "lm", max_iter=100)
    paper = approximate(X, T2_OUT, "paper", sweeps=3)
    lag = paper.f - ref.f
    assert lag.min() > -1e-9                      # lm is converged: paper is never better
    assert lag.max() <= 0.2
    assert paper.f.mean() <= 1.02 * ref.f.mean()
    assert ref.f.mean() == pytest.approx(0.2417, abs=5e-4)      # the spec's converged mean
    assert paper.f.mean() == pytest.approx(0.2444, abs=5e-4)    # and its 3-sweep mean


def test_t3_blocked_batch_equals_sequential() -> None:
    X = t3_input(400)
    seq = approximate(X, T2_OUT, block=0)
    for block in (8, 32):
        par = approximate(X, T2_OUT, block=block)
        assert np.abs(par.q - seq.q).max() < 1e-6
        assert np.abs(par.f - seq.f).max() < 1e-9
    assert len(seq.jumps(0.5)) == 0
