"""Parallel projection (spec §1–2): minimum shooting distance and chain reconstruction."""

from __future__ import annotations

import doctest

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from mirrorlab.plugins.photogrammetry import parallel
from mirrorlab.plugins.photogrammetry.errors import AmbiguousSign, InconsistentLength, InvalidArgument
from mirrorlab.plugins.photogrammetry.parallel import (
    min_shooting_distance_rotation,
    min_shooting_distance_translation,
    reconstruct_chain_parallel,
    relative_image_error,
)

from tests.plugins.photogrammetry.bounds import parallel_roundoff
from tests.tolerances import abs_err, roundoff

FIG_2_4 = np.array([
    [8.63, 17.19, 33.86, 49.50],
    [7.95, 15.66, 30.09, 42.85],
    [6.30, 12.22, 22.77, 31.33],
    [4.11, 7.81, 13.89, 18.04],
    [1.97, 3.61, 5.82, 6.56],
])


def test_doctests():
    assert doctest.testmod(parallel).failed == 0


def test_fig_2_4_table():
    th = np.radians([0, 15, 30, 45, 60])[:, None]
    dth = np.radians([5, 10, 20, 30])[None, :]
    L = min_shooting_distance_rotation(1.0, 0.01, th, dth)
    # the figure prints 2 decimals: half a unit, plus the formula's rounding (sin(theta + dtheta) -
    # sin(theta) cancels by up to 22x at theta = 60, dtheta = 5 deg) for values printed from a tie
    sin_cancel = np.max((np.sin(th + dth) + np.sin(th)) / (np.sin(th + dth) - np.sin(th)))
    np.testing.assert_allclose(L, FIG_2_4, rtol=0, atol=0.005 + roundoff(cond=sin_cancel, scale=np.abs(L).max(), ops=8))
    # (2.3) with eps_max = gamma / cos(theta) and Delta L of (2.4) gives the same numbers: the same
    # (bitwise) sine difference times (1 - eps) / eps or (cos - gamma) / gamma, ~8 roundings apart
    L23 = min_shooting_distance_translation(np.sin(th + dth) - np.sin(th), 0.01 / np.cos(th))
    np.testing.assert_allclose(L23, L, rtol=roundoff(ops=8))


def test_relative_image_error_matches_image_lengths():
    L, dL, A, ell = 20.0, 0.5, 1.0, 0.05
    a, a2 = ell / L * A, ell / (L + dL) * A  # (2.1)
    # a - a2 cancels: relative error (a / (a - a2)) eps = ((L + dL) / dL) eps = 41 eps
    assert relative_image_error(L, dL) == pytest.approx((a - a2) / a, rel=roundoff(cond=(L + dL) / dL, ops=6))
    assert relative_image_error(L, dL) == pytest.approx(0.0243902, abs=5e-8)  # 7 decimals: half a unit


@pytest.mark.parametrize("kwargs", [
    dict(A=1.0, gamma=0.01, theta=0.0, dtheta=0.0),
    dict(A=1.0, gamma=0.01, theta=1.2, dtheta=0.5),
    dict(A=-1.0, gamma=0.01, theta=0.0, dtheta=0.1),
    dict(A=1.0, gamma=0.9, theta=1.0, dtheta=0.1),
])
def test_rotation_invalid(kwargs):
    with pytest.raises(InvalidArgument):
        min_shooting_distance_rotation(**kwargs)


def test_translation_invalid():
    with pytest.raises(InvalidArgument):
        min_shooting_distance_translation(1.0, 1.0)
    with pytest.raises(InvalidArgument):
        min_shooting_distance_translation(-1.0, 0.1)


def _chain(rng, frames, n, lengths):
    d = rng.normal(size=(frames, n, 3))
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    return np.cumsum(lengths[:, None] * d, axis=-2)


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), m=st.floats(0.5, 200.0), n=st.integers(1, 6))
def test_round_trip_property(seed, m, n):
    rng = np.random.default_rng(seed)
    D = rng.uniform(50, 500, n)
    P = _chain(rng, 4, n, D)
    xy = P[..., :2] / m
    prev = np.concatenate([np.zeros((4, 1, 3)), P[:, :-1]], axis=1)
    signs = np.where(P[..., 2] >= prev[..., 2], 1, -1)
    r = reconstruct_chain_parallel(xy, D, m, signs=signs)
    assert abs_err(r.points, P) <= parallel_roundoff(P, D)


def test_missing_sign_names_frame_and_marker():
    xy = np.array([[[0.1, 0.0], [0.2, 0.1]], [[0.1, 0.0], [0.2, 0.1]]])
    with pytest.raises(AmbiguousSign, match=r"frame 1, marker 2.*signs="):
        reconstruct_chain_parallel(xy, [1.0, 1.0], 1.0, signs=[[1, 1], [1, 0]])


def test_resolver_is_called_with_candidates():
    calls = []

    def resolver(frame, link, cand):
        calls.append((frame, link, cand.copy()))
        return -1

    r = reconstruct_chain_parallel([[0.6, 0.0], [0.6, 0.8]], [1.0, 1.0], 1.0, signs=[1, 0], resolver=resolver)
    assert [(f, l) for f, l, _ in calls] == [(0, 2)]
    # sqrt(1 - 0.6^2) = 0.8 to rounding; 0.8 - 0.6 cancels by 1.4 / 0.2 = 7
    rtol = roundoff(cond=7.0, ops=6)
    np.testing.assert_allclose(calls[0][2][:, 2], [0.8 + 0.6, 0.8 - 0.6], rtol=rtol)
    np.testing.assert_allclose(r.points[-1], [0.6, 0.8, 0.2], rtol=rtol)


def test_inconsistent_length_and_clamp():
    with pytest.raises(InconsistentLength, match=r"frame 0, marker 1.*exceeds"):
        reconstruct_chain_parallel([[2.0, 0.0]], [1.0], 1.0, signs=[1])
    r = reconstruct_chain_parallel([[1.0 + 1e-4, 0.0]], [1.0], 1.0, signs=[1])
    assert r.flags["segment_in_image_plane"].tolist() == [True]
    assert r.points[0, 2] == 0.0
