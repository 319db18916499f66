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

FIXTURE_GAINS = {0.02: 0.9850, 0.05: 0.9087, 0.10: 0.6715, 0.15: 0.3798, 0.20: 0.1348,
                 0.25: 0.0, 1 / 3: 0.0, 0.40: 0.0515, 0.50: 0.0}


def test_kernel_is_convolution_of_moving_averages():
    assert np.allclose(THESIS_KERNEL, np.convolve(np.ones(3) / 3, np.ones(4) / 4), atol=1e-16)


@pytest.mark.parametrize("sigma,gain", sorted(FIXTURE_GAINS.items()))
def test_response_fixture_gains(sigma, gain):
    assert abs(abs(thesis_filter_response(sigma)) - gain) < 5e-5


def test_response_matches_dft_and_properties():
    s = np.linspace(0.0, 0.5, 2001)
    w = 2 * np.pi * s
    dft = np.sum(THESIS_KERNEL[:, None] * np.exp(1j * np.outer(np.arange(6), w)), axis=0)
    H = thesis_filter_response(s)
    assert np.allclose(dft, np.exp(2.5j * w) * H, atol=1e-14)  # linear phase: 2.5-sample advance
    assert thesis_filter_response(0.0) == pytest.approx(1.0, abs=1e-15)
    # half-power and half-amplitude points of the spec
    assert abs(thesis_filter_response(0.0936)) ** 2 == pytest.approx(0.5, abs=2e-3)
    assert abs(thesis_filter_response(0.1293)) == pytest.approx(0.5, abs=1e-3)
    stop = s > 0.26
    k = np.argmax(np.abs(H[stop]))
    assert np.abs(H[stop][k]) == pytest.approx(0.0547, abs=2e-4)
    assert s[stop][k] == pytest.approx(0.418, abs=3e-3)


def test_thesis_filter_timestamps_and_length():
    t = 1.0 + np.arange(20) * 0.1
    tau, h = thesis_filter(t, np.column_stack([t, t**2]))
    assert tau.shape == (15,) and h.shape == (15, 2)
    assert np.allclose(tau, t[:15] + 0.25)
    assert np.allclose(h[:, 0], tau)  # a ramp is reproduced at the filtered stamps


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
    _, h = thesis_filter(t, const)
    assert np.allclose(h, c, rtol=1e-12, atol=1e-9)
    tau, h = thesis_filter(t, ramp)
    assert np.allclose(h, c + m * tau, rtol=1e-12, atol=1e-8)
    assert np.allclose(butterworth(t, const, cutoff=6.0), c, rtol=1e-9, atol=1e-7)
    # GCV on exact data is ill-conditioned: round-off of ~1e-8 relative (measured 1.4e-8 at c = 4520)
    assert np.allclose(smoothing_spline(t, ramp), ramp, rtol=1e-7, atol=1e-6 * (1 + abs(m)))
    # zero-phase Butterworth with odd padding keeps a ramp only approximately (start-up
    # transients of the sosfiltfilt initial conditions): < 2 % of the rise at the ends and
    # < 0.2 % in the middle third (measured 1.4 % / 0.12 % at n = 20, 0.2 % / 5e-8 at n = 120)
    err = np.abs(butterworth(t, ramp, cutoff=6.0) - ramp)
    tol = 1e-9 * (1 + abs(c) + abs(m))
    assert err.max() <= 2e-2 * abs(m) * t[-1] + tol
    assert err[n // 3 : -(n // 3)].max() <= 2e-3 * abs(m) * t[-1] + tol


def test_butterworth_attenuates_noise_runs_and_uneven():
    rng = np.random.default_rng(3)
    t = np.arange(600) / 200.0
    clean = 50 * np.sin(2 * np.pi * 1.2 * t)
    x = clean + rng.normal(0, 1.0, t.size)
    x[300:340] = np.nan
    y = butterworth(t, x, cutoff=8.0)
    assert np.isnan(y[300:340]).all()
    ok = np.isfinite(y)
    assert np.sqrt(np.mean((y[ok] - clean[ok]) ** 2)) < 0.5
    fc = residual_cutoff(t, np.where(np.isnan(x), clean, x))
    assert 2.0 < float(fc) < 25.0
    yr = butterworth(t, x, cutoff="residual")
    assert np.sqrt(np.nanmean((yr - clean) ** 2)) < 0.6
    with pytest.raises(NonUniformSampling):
        butterworth(np.cumsum(np.r_[0, np.full(50, 0.01), 0.02, np.full(50, 0.01)]), np.zeros(102), 5.0)


def test_fill_gaps_only_short_and_interior():
    t = np.arange(30) * 0.01
    x = np.column_stack([np.sin(t), np.cos(t)])
    x[3:5] = np.nan  # 2-sample gap
    x[10:20, 0] = np.nan  # 10-sample gap in channel 0 only
    x[-2:] = np.nan  # trailing gap: never extrapolated
    y = fill_gaps(t, x, max_gap=3)
    assert np.allclose(y[3:5], np.column_stack([np.sin(t), np.cos(t)])[3:5], atol=1e-7)
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
    assert np.sqrt(np.nanmean((y - clean) ** 2)) < 0.03
    y2 = smoothing_spline(t, x, max_gap=3)
    assert np.isfinite(y2[100:103]).all()
