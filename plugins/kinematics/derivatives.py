"""Smoothed value, velocity and acceleration of sampled time series (one entry point).

:func:`derivatives` dispatches to the thesis procedure (parametric spline, §3.3), a GCV
smoothing spline, or a zero-phase Butterworth filter followed by central differences. All
results are returned on the **input** time grid, time along axis 0, NaN where a quantity is
undefined (gaps, and the ends the thesis filter consumes).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .errors import InsufficientSamples
from .filters import (
    _apply_runs,
    _channel_groups,
    _prepare,
    butterworth,
    check_uniform,
    contiguous_runs,
    fit_smoothing_spline,
    thesis_filter,
)
from .thesis_spline import ParametricSpline

__all__ = ["derivatives", "METHODS"]

FloatArray = NDArray[np.float64]
METHODS = ("thesis_spline", "smoothing_spline", "butterworth")


def _inside(tq: FloatArray, lo: float, hi: float, period: float) -> tuple[NDArray[np.bool_], FloatArray]:
    eps = 1e-9 * period
    m = (tq >= lo - eps) & (tq <= hi + eps)
    return m, np.clip(tq, lo, hi)


def _thesis_run(t: FloatArray, x: FloatArray, prefilter: bool) -> tuple[FloatArray, FloatArray, FloatArray]:
    out = [np.full_like(x, np.nan) for _ in range(3)]
    if not prefilter:
        s1 = ParametricSpline(t, x)
        vel = s1.evaluate(t, 1)
        s2 = ParametricSpline(t, vel)
        return x.copy(), vel, s2.evaluate(t, 1)
    period = float(np.mean(np.diff(t)))
    tau, h = thesis_filter(t, x)
    s1 = ParametricSpline(tau, h)
    m, tq = _inside(t, tau[0], tau[-1], period)
    out[0][m] = s1.evaluate(tq[m], 0)
    out[1][m] = s1.evaluate(tq[m], 1)
    vel_tau = s1.evaluate(tau, 1)
    tau2, vf = thesis_filter(tau, vel_tau)
    s2 = ParametricSpline(tau2, vf)
    m2, tq2 = _inside(t, tau2[0], tau2[-1], period)
    out[2][m2] = s2.evaluate(tq2[m2], 1)
    return out[0], out[1], out[2]


def derivatives(
    t: ArrayLike,
    x: ArrayLike,
    method: str = "smoothing_spline",
    **params: object,
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Smoothed values, first and second time derivatives along axis 0.

    Parameters
    ----------
    t : array_like, shape (T,)
        Strictly increasing sample times in s.
    x : array_like, shape (T, ...)
        Samples (any unit, e.g. mm or rad), any trailing shape, NaN where missing. Each contiguous
        run of finite samples of each channel is processed on its own; gaps are bridged only when
        ``max_gap`` (samples) or ``max_gap_s`` (s) is given.
    method : {"smoothing_spline", "thesis_spline", "butterworth"}
        * ``"thesis_spline"`` -- thesis §3.3: 1-2-3-3-2-1 filter, parametric spline (3.37) for the
          velocity, re-filtered velocity splined again for the acceleration. Needs uniform
          sampling unless ``prefilter=False``. The filter consumes the ends: value and velocity
          are NaN for the first and last 3 samples (2.5 rounded up), the acceleration for the
          first and last 5 samples of every run. Runs need >= 13 samples (3 without prefilter).
        * ``"smoothing_spline"`` (default) -- cubic smoothing spline, ``lam`` by GCV per channel
          (param ``lam``; 0 = interpolating natural spline); uneven sampling allowed; runs need
          >= 5 samples.
        * ``"butterworth"`` -- zero-phase Butterworth (params ``cutoff`` in Hz or "residual",
          ``order``), then second-order central differences (``numpy.gradient``). Needs uniform
          sampling.
    **params
        Method parameters listed above, plus ``max_gap`` / ``max_gap_s``.

    Returns
    -------
    x_smooth, velocity, acceleration : ndarray, each shape (T, ...)
        Value (unit), velocity (unit/s), acceleration (unit/s²) on the input grid.

    Raises
    ------
    NonUniformSampling
        Butterworth or the filtered thesis method on uneven sampling.
    InsufficientSamples
        Unknown method or parameters.

    Examples
    --------
    >>> t = np.linspace(0.0, 2.0, 201)
    >>> x = np.column_stack([np.sin(t), t ** 2])
    >>> xs, v, a = derivatives(t, x, method="smoothing_spline", lam=0.0)
    >>> bool(np.allclose(v[10:-10], np.column_stack([np.cos(t), 2 * t])[10:-10], atol=1e-5))
    True
    """
    p = dict(params)
    max_gap = p.pop("max_gap", None)
    max_gap_s = p.pop("max_gap_s", None)
    tt, xx = _prepare(t, x, max_gap, max_gap_s)  # type: ignore[arg-type]
    shape = xx.shape
    x2 = xx.reshape(shape[0], -1)
    outs = [np.full_like(x2, np.nan) for _ in range(3)]

    if method == "thesis_spline":
        prefilter = bool(p.pop("prefilter", True))
        _no_extra(p, method)
        if prefilter:
            check_uniform(tt)
        min_len = 13 if prefilter else 3
        for cols, mask in _channel_groups(x2):
            for a, b in contiguous_runs(mask):
                if b - a >= min_len:
                    res = _thesis_run(tt[a:b], x2[a:b][:, cols], prefilter)
                    for o, r in zip(outs, res):
                        o[a:b, cols] = r
    elif method == "smoothing_spline":
        lam = p.pop("lam", None)
        _no_extra(p, method)
        for cols, mask in _channel_groups(x2):
            for a, b in contiguous_runs(mask):
                if b - a >= 5:
                    spl = fit_smoothing_spline(tt[a:b], x2[a:b][:, cols], lam)  # type: ignore[arg-type]
                    for nu, o in enumerate(outs):
                        o[a:b, cols] = spl(tt[a:b], nu=nu)
    elif method == "butterworth":
        cutoff = p.pop("cutoff", "residual")
        order = int(p.pop("order", 2))  # type: ignore[call-overload]
        _no_extra(p, method)
        period = check_uniform(tt)
        xs = butterworth(tt, x2, cutoff=cutoff, order=order)  # type: ignore[arg-type]
        outs[0] = xs

        def grad(tr: FloatArray, xr: FloatArray) -> FloatArray:
            return np.gradient(xr, period, axis=0, edge_order=2)

        outs[1] = _apply_runs(tt, xs, grad, 3)
        outs[2] = _apply_runs(tt, outs[1], grad, 3)
    else:
        raise InsufficientSamples(f"unknown derivative method {method!r}; choose one of {METHODS}")
    return tuple(o.reshape(shape) for o in outs)  # type: ignore[return-value]


def _no_extra(p: dict[str, object], method: str) -> None:
    if p:
        raise InsufficientSamples(
            f"unknown parameter(s) {sorted(p)} for method {method!r}; see derivatives() docstring"
        )
