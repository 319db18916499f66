"""Filters: thesis 1-2-3-3-2-1 kernel and response, Butterworth, GCV spline, gap handling."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from mirrorlab.core.errors import AlgorithmError
from mirrorlab.plugins.kinematics import (
    THESIS_KERNEL,
    InsufficientSamples,
    NonMonotonicTime,
    NonUniformSampling,
    butterworth,
    fill_gaps,
    residual_cutoff,
    smoothing_spline,
    thesis_filter,
    thesis_filter_response,
)

from tests.derived_bounds import butterworth_ramp_transient, smoothing_spline_rounding
from tests.tolerances import abs_err, roundoff

FIXTURE_GAINS = {0.02: 0.9850, 0.05: 0.9087, 0.10: 0.6715, 0.15: 0.3798, 0.20: 0.1348,
                 0.25: 0.0, 1 / 3: 0.0, 0.40: 0.0515, 0.50: 0.0}


def test_kernel_is_convolution_of_moving_averages():
    # sums of <= 3 rounded products of size <= 1/12
    assert abs_err(THESIS_KERNEL, np.convolve(np.ones(3) / 3, np.ones(4) / 4)) <= roundoff(scale=0.25, ops=3)


@pytest.mark.parametrize("sigma,gain", sorted(FIXTURE_GAINS.items()))
def test_response_fixture_gains(sigma, gain):
    # the fixture prints 4 decimals (±5e-5); the closed form is well conditioned (a few rounded terms)
    assert abs(abs(thesis_filter_response(sigma)) - gain) <= 5e-5 + roundoff(ops=10)


def test_response_matches_dft_and_properties():
    s = np.linspace(0.0, 0.5, 2001)
    w = 2 * np.pi * s
    dft = np.sum(THESIS_KERNEL[:, None] * np.exp(1j * np.outer(np.arange(6), w)), axis=0)
    H = thesis_filter_response(s)
    # two evaluations of a 6-term sum of weights summing to 1 (|terms| <= 1): rounding only
    assert np.abs(dft - np.exp(2.5j * w) * H).max() <= roundoff(ops=10)  # linear phase: 2.5-sample advance
    assert thesis_filter_response(0.0) == pytest.approx(1.0, abs=roundoff(ops=5))
    # half-power and half-amplitude points of the spec, printed to 4 decimals: the condition holds
    # somewhere within ±5e-5 of the printed sigma
    for sigma, power, target in ((0.0936, 2, 0.5), (0.1293, 1, 0.5)):
        lo, hi = sorted(np.abs(thesis_filter_response([sigma - 5e-5, sigma + 5e-5])) ** power)
        assert lo - roundoff(ops=10) <= target <= hi + roundoff(ops=10), sigma
    stop = s > 0.26
    k = np.argmax(np.abs(H[stop]))
    # the spec prints the stop-band peak to 4 decimals and 3 decimals (±5e-5, ±5e-4); the grid finds
    # its location within half a step (1.25e-4) and its height within |H''|/2 · step² (~4e-7)
    assert np.abs(H[stop][k]) == pytest.approx(0.0547, abs=5e-5 + 1e-6)
    assert s[stop][k] == pytest.approx(0.418, abs=5e-4 + 1.25e-4)


def test_thesis_filter_timestamps_and_length():
    t = 1.0 + np.arange(20) * 0.1
    tau, h = thesis_filter(t, np.column_stack([t, t**2]))
    assert tau.shape == (15,) and h.shape == (15, 2)
    # 6-term weighted sums (weights summing to 1) of values <= 2.9: rounding only
    assert abs_err(tau, t[:15] + 0.25) <= roundoff(scale=t.max(), ops=6)
    assert abs_err(h[:, 0], tau) <= roundoff(scale=t.max(), ops=6)  # a ramp is reproduced at the filtered stamps


def test_thesis_filter_errors_and_gaps():
    with pytest.raises(InsufficientSamples):
        thesis_filter(np.arange(5.0), np.arange(5.0))
    t = np.array([0, 1, 2, 3, 4, 5.5, 6, 7])
    with pytest.raises(NonUniformSampling) as e:
        thesis_filter(t, t)
    assert isinstance(e.value, AlgorithmError) and "uniform" in str(e.value)
    with pytest.raises(NonMonotonicTime):
        thesis_filter(np.array([0, 1, 1, 2, 3, 4, 5.0]), np.zeros(7))
    x = np.arange(20.0)
    x[10] = np.nan
    _, h = thesis_filter(np.arange(20.0), x)
    assert np.isnan(h[5:11]).all() and np.isfinite(h[:5]).all() and np.isfinite(h[11:]).all()


@settings(max_examples=25, deadline=None)
@given(c=st.floats(-1e4, 1e4), m=st.floats(-1e3, 1e3), n=st.integers(20, 120))
def test_filters_preserve_constants_and_ramps(c, m, n):
    t = np.arange(n) / 100.0
    const = np.full(n, c)
    ramp = c + m * t
    # below the smallest normal number (hypothesis tries subnormal c, m) rounding is absolute,
    # eps · tiny per operation: the relative model holds with the magnitude floored at tiny
    tiny = np.finfo(float).tiny
    size = max(abs(c) + abs(m) * t[-1], tiny)
    # the 6-term kernel (weights summing to 1) keeps constants and lines up to rounding
    _, h = thesis_filter(t, const)
    assert abs_err(h, c) <= roundoff(scale=max(abs(c), tiny), ops=6)
    tau, h = thesis_filter(t, ramp)
    assert abs_err(h, c + m * tau) <= roundoff(scale=size, ops=8)
    # a constant starts both passes in their steady state: rounding only, accumulated at most
    # linearly over the stable recursion's n steps
    assert abs_err(butterworth(t, const, cutoff=6.0), c) <= roundoff(scale=max(abs(c), tiny), ops=n)
    # the spline reproduces a line; GCV on exact data may pick any lambda in (0, n), where the
    # solve is ill-conditioned (tests/derived_bounds.py)
    assert abs_err(smoothing_spline(t, ramp), ramp) <= smoothing_spline_rounding(t, ramp, 0)
    # zero-phase Butterworth with odd padding keeps a ramp only approximately: the start-up
    # transients of the sosfiltfilt initial conditions, per sample by its distance from the ends
    # (tests/derived_bounds.py), plus the recursion's rounding
    err = np.abs(butterworth(t, ramp, cutoff=6.0) - ramp)
    from_end = np.minimum(np.arange(n), n - 1 - np.arange(n))
    assert (err <= butterworth_ramp_transient(m, 100.0, 6.0, n, from_end) + roundoff(scale=size, ops=n)).all()


def test_butterworth_attenuates_noise_runs_and_uneven():
    rng = np.random.default_rng(3)
    t = np.arange(600) / 200.0
    clean = 50 * np.sin(2 * np.pi * 1.2 * t)
    x = clean + rng.normal(0, 1.0, t.size)
    x[300:340] = np.nan
    y = butterworth(t, x, cutoff=8.0)
    assert np.isnan(y[300:340]).all()
    ok = np.isfinite(y)
    # statistics of unit white noise through filtfilt (|H|² of order 4, 8 Hz at 200 Hz): noise
    # bandwidth ~8.2 Hz of 100, so rms ~ sqrt(0.082) = 0.29 (fixed seed); the sine (1.2 Hz) passes
    assert np.sqrt(np.mean((y[ok] - clean[ok]) ** 2)) < 0.5
    fc = residual_cutoff(t, np.where(np.isnan(x), clean, x))
    assert 2.0 < float(fc) < 25.0           # Winter's residual pick: above the signal, below the noise band
    yr = butterworth(t, x, cutoff="residual")
    assert np.sqrt(np.nanmean((yr - clean) ** 2)) < 0.6   # as above, with the picked (higher) cutoff
    with pytest.raises(NonUniformSampling):
        butterworth(np.cumsum(np.r_[0, np.full(50, 0.01), 0.02, np.full(50, 0.01)]), np.zeros(102), 5.0)


def test_fill_gaps_only_short_and_interior():
    t = np.arange(30) * 0.01
    x = np.column_stack([np.sin(t), np.cos(t)])
    x[3:5] = np.nan  # 2-sample gap
    x[10:20, 0] = np.nan  # 10-sample gap in channel 0 only
    x[-2:] = np.nan  # trailing gap: never extrapolated
    y = fill_gaps(t, x, max_gap=3)
    # cubic-spline fill: 5/384 H⁴ |f⁗| = 1e-8 over the 0.03 s gap, plus the 0.11 s gap's larger
    # error (1.9e-6) decayed by 0.27 per knot over the 5 knots between them (3e-9); 1e-7 covers both
    assert np.allclose(y[3:5], np.column_stack([np.sin(t), np.cos(t)])[3:5], rtol=0, atol=1e-7)
    assert np.isnan(y[10:20, 0]).all() and np.isfinite(y[10:20, 1]).all()
    assert np.isnan(y[-2:]).all()
    assert np.isnan(fill_gaps(t, x, max_gap_s=0.02)[3:5]).all()  # 0.03 s between valid samples
    assert np.isfinite(fill_gaps(t, x, max_gap_s=0.03)[3:5]).all()
    assert np.isnan(fill_gaps(t, x)[3:5]).all()  # nothing filled unless asked


def test_smoothing_spline_runs_and_uneven_sampling():
    rng = np.random.default_rng(5)
    t = np.cumsum(rng.uniform(0.005, 0.015, 300))
    clean = 10 * np.sin(3 * t)
    x = clean + rng.normal(0, 0.05, t.size)
    x[100:103] = np.nan
    x[200] = np.nan
    y = smoothing_spline(t, x)
    assert np.isnan(y[100:103]).all() and np.isnan(y[200])
    # GCV smoothing of noise sigma = 0.05: the error rms is sigma · sqrt(df / n) for the fit's few
    # effective degrees of freedom (a sine over 3 s: df ~ 10 of n ~ 100 per run, so ~0.016)
    assert np.sqrt(np.nanmean((y - clean) ** 2)) < 0.03

    y2 = smoothing_spline(t, x, max_gap=3)
    assert np.isfinite(y2[100:103]).all()
