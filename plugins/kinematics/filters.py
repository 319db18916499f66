"""Low-pass filters for marker and angle time series, with NaN-gap handling.

Three filters, all applied along axis 0 (time) and vectorised over any trailing axes:

* :func:`thesis_filter` -- the thesis's 1-2-3-3-2-1 /12 kernel (eq. 3.21), its frequency response
  in :func:`thesis_filter_response` (eq. 3.25 corrected);
* :func:`butterworth` -- zero-phase Butterworth (``scipy.signal.butter`` + ``sosfiltfilt``), with an
  optional Winter residual-analysis cutoff (:func:`residual_cutoff`);
* :func:`smoothing_spline` -- GCV smoothing spline (``scipy.interpolate.make_smoothing_spline``).

Gaps (NaN) are never bridged silently: every contiguous run of finite samples of a channel is
filtered on its own; :func:`fill_gaps` bridges gaps of at most ``max_gap`` samples (or
``max_gap_s`` seconds) by a cubic spline, and only when the caller asks for it.

Units: times in s, frequencies in Hz, values in the caller's unit (typically mm or rad).
"""

from __future__ import annotations

from collections.abc import Callable, Iterator

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.interpolate import BSpline, CubicSpline, make_smoothing_spline

from .errors import GapTooLong, InsufficientSamples, NonMonotonicTime, NonUniformSampling

__all__ = [
    "THESIS_KERNEL",
    "check_time",
    "check_uniform",
    "contiguous_runs",
    "fill_gaps",
    "thesis_filter",
    "thesis_filter_response",
    "butterworth",
    "residual_cutoff",
    "smoothing_spline",
]

#: The 1-2-3-3-2-1 /12 kernel of eq. (3.21) = [1,1,1]/3 * [1,1,1,1]/4.
THESIS_KERNEL: NDArray[np.float64] = np.array([1.0, 2.0, 3.0, 3.0, 2.0, 1.0]) / 12.0

FloatArray = NDArray[np.float64]


# ----------------------------------------------------------------------------------------------
# time-axis helpers
# ----------------------------------------------------------------------------------------------
def check_time(t: ArrayLike, n: int | None = None) -> FloatArray:
    """Validate sample times: 1-D, finite, strictly increasing, and of length ``n`` if given.

    Parameters
    ----------
    t : array_like, shape (T,)
        Sample times in s.
    n : int, optional
        Required length (the length of axis 0 of the data).

    Returns
    -------
    ndarray, shape (T,)
        ``t`` as float64.

    Raises
    ------
    NonMonotonicTime
        If ``t`` is not strictly increasing or not finite.

    Examples
    --------
    >>> check_time([0.0, 0.1, 0.2]).tolist()
    [0.0, 0.1, 0.2]
    """
    tt = np.asarray(t, dtype=float)
    if tt.ndim != 1:
        raise NonMonotonicTime(f"time must be 1-D, got shape {tt.shape}; pass one stamp per frame")
    if n is not None and tt.shape[0] != n:
        raise NonMonotonicTime(
            f"time has {tt.shape[0]} stamps but the data have {n} frames along axis 0; "
            "pass one stamp per frame"
        )
    if not np.all(np.isfinite(tt)):
        raise NonMonotonicTime("time contains NaN/inf; time stamps must all be known")
    bad = np.flatnonzero(np.diff(tt) <= 0)
    if bad.size:
        raise NonMonotonicTime(
            f"time is not strictly increasing at frame {bad[0] + 1} "
            f"(t={tt[bad[0]]:.6g} s then {tt[bad[0] + 1]:.6g} s); sort or de-duplicate the frames"
        )
    return tt


def check_uniform(t: ArrayLike, tol: float = 0.05) -> float:
    """Return the mean sampling period and check that sampling is uniform.

    Parameters
    ----------
    t : array_like, shape (T,)
        Strictly increasing sample times in s.
    tol : float
        Allowed deviation of any interval from the mean period, relative to it (spec: 0.05).

    Returns
    -------
    float
        Mean sampling period T in s.

    Raises
    ------
    NonUniformSampling
        If ``max |t[k+1]-t[k]-T| > tol*T``.

    Examples
    --------
    >>> round(check_uniform([0.0, 0.01, 0.02, 0.03]), 6)
    0.01
    """
    tt = check_time(t)
    if tt.size < 2:
        raise InsufficientSamples("need at least 2 time stamps to determine the sampling period")
    dt = np.diff(tt)
    period = float(dt.mean())
    dev = np.abs(dt - period)
    k = int(np.argmax(dev))
    if dev[k] > tol * period:
        raise NonUniformSampling(
            f"sampling is not uniform: interval {k}->{k + 1} is {dt[k]:.6g} s against a mean of "
            f"{period:.6g} s (tolerance {tol:.0%}); resample to a uniform grid or use "
            "method='smoothing_spline'"
        )
    return period


def contiguous_runs(valid: ArrayLike) -> list[tuple[int, int]]:
    """Return ``(start, stop)`` index pairs of the runs of True in a 1-D boolean array.

    Examples
    --------
    >>> contiguous_runs([False, True, True, False, True])
    [(1, 3), (4, 5)]
    """
    v = np.asarray(valid, dtype=bool).astype(np.int8)
    d = np.diff(np.concatenate(([0], v, [0])))
    starts = np.flatnonzero(d == 1)
    stops = np.flatnonzero(d == -1)
    return [(int(a), int(b)) for a, b in zip(starts, stops)]


def _channel_groups(x2: FloatArray) -> Iterator[tuple[NDArray[np.intp], NDArray[np.bool_]]]:
    """Group the columns of a (T, C) array that share the same finite-sample mask."""
    fin = np.isfinite(x2)
    groups: dict[bytes, list[int]] = {}
    for c in range(x2.shape[1]):
        groups.setdefault(np.packbits(fin[:, c]).tobytes(), []).append(c)
    for cols in groups.values():
        yield np.asarray(cols, dtype=np.intp), fin[:, cols[0]]


def _apply_runs(
    t: FloatArray,
    x: FloatArray,
    fn: Callable[[FloatArray, FloatArray], FloatArray],
    min_len: int,
) -> FloatArray:
    """Apply ``fn(t_run, x_run)`` to every contiguous finite run (>= min_len) of every channel.

    ``x`` has time on axis 0; the result has the same shape, NaN where no run was long enough.
    """
    shape = x.shape
    x2 = x.reshape(shape[0], -1)
    out = np.full_like(x2, np.nan)
    for cols, mask in _channel_groups(x2):
        for a, b in contiguous_runs(mask):
            if b - a >= min_len:
                out[a:b, cols] = fn(t[a:b], x2[a:b][:, cols])
    return out.reshape(shape)


def _check_gap_limits(max_gap: int | None, max_gap_s: float | None) -> None:
    if max_gap is not None and max_gap < 0:
        raise GapTooLong(f"max_gap must be >= 0 samples, got {max_gap}")
    if max_gap_s is not None and max_gap_s < 0:
        raise GapTooLong(f"max_gap_s must be >= 0 s, got {max_gap_s}")


def fill_gaps(
    t: ArrayLike,
    x: ArrayLike,
    max_gap: int | None = None,
    max_gap_s: float | None = None,
) -> FloatArray:
    """Bridge short interior NaN gaps by a cubic spline; leave longer gaps and the ends NaN.

    Parameters
    ----------
    t : array_like, shape (T,)
        Sample times in s (uneven allowed).
    x : array_like, shape (T, ...)
        Data, time along axis 0; NaN marks a missing sample.
    max_gap : int, optional
        Longest gap to bridge, in missing samples.
    max_gap_s : float, optional
        Longest gap to bridge, as the time between the two valid samples around it, in s.
        If both limits are given, a gap must satisfy both. If neither is given nothing is filled.

    Returns
    -------
    ndarray, shape (T, ...)
        Copy of ``x`` with the short gaps filled. Gaps at the start or end are never filled
        (that would be extrapolation).

    Examples
    --------
    >>> t = np.arange(6.0)
    >>> x = np.array([0.0, 1.0, np.nan, 3.0, np.nan, np.nan])
    >>> fill_gaps(t, x, max_gap=1).round(6).tolist()
    [0.0, 1.0, 2.0, 3.0, nan, nan]
    """
    xx = np.array(x, dtype=float)
    tt = check_time(t, xx.shape[0])
    _check_gap_limits(max_gap, max_gap_s)
    if max_gap is None and max_gap_s is None:
        return xx
    x2 = xx.reshape(xx.shape[0], -1)
    for cols, mask in _channel_groups(x2):
        runs = contiguous_runs(~mask)
        fill = np.zeros(mask.shape, dtype=bool)
        for a, b in runs:
            if a == 0 or b == mask.size:
                continue
            ok = True
            if max_gap is not None and b - a > max_gap:
                ok = False
            if max_gap_s is not None and tt[b] - tt[a - 1] > max_gap_s * (1 + 1e-9):
                ok = False
            fill[a:b] = ok
        if fill.any():
            if mask.sum() < 2:
                continue
            cs = CubicSpline(tt[mask], x2[mask][:, cols], axis=0)
            sub = x2[:, cols]
            sub[fill] = cs(tt[fill])
            x2[:, cols] = sub
    return x2.reshape(xx.shape)


def _prepare(t: ArrayLike, x: ArrayLike, max_gap: int | None, max_gap_s: float | None) -> tuple[FloatArray, FloatArray]:
    xx = np.asarray(x, dtype=float)
    if xx.ndim == 0:
        raise InsufficientSamples("x must have a time axis (axis 0)")
    tt = check_time(t, xx.shape[0])
    if max_gap is not None or max_gap_s is not None:
        xx = fill_gaps(tt, xx, max_gap=max_gap, max_gap_s=max_gap_s)
    return tt, xx


# ----------------------------------------------------------------------------------------------
# thesis 1-2-3-3-2-1 filter
# ----------------------------------------------------------------------------------------------
def thesis_filter(t: ArrayLike, x: ArrayLike, tol: float = 0.05) -> tuple[FloatArray, FloatArray]:
    """Apply the thesis's 1-2-3-3-2-1 /12 low-pass filter (eq. 3.21) along axis 0.

    ``h[k] = (f[k] + 2 f[k+1] + 3 f[k+2] + 3 f[k+3] + 2 f[k+4] + f[k+5]) / 12``; the time stamps
    are filtered identically, so ``tau[k] = t[k] + 2.5 T`` (no lag, no end padding: the output is 5
    samples shorter). A NaN anywhere in a 6-sample window makes that output NaN, i.e. each
    contiguous run is filtered on its own and gaps grow by 5 samples.

    Parameters
    ----------
    t : array_like, shape (N,)
        Uniform sample times in s.
    x : array_like, shape (N, ...)
        Data; time along axis 0, any trailing shape.
    tol : float
        Uniformity tolerance of :func:`check_uniform`.

    Returns
    -------
    tau : ndarray, shape (N-5,)
        Time stamps of the filtered samples in s.
    h : ndarray, shape (N-5, ...)
        Filtered data.

    Raises
    ------
    InsufficientSamples
        If N < 6.
    NonUniformSampling
        If the sampling is not uniform within ``tol``.

    Examples
    --------
    >>> tau, h = thesis_filter(np.arange(8) * 0.1, np.arange(8.0))
    >>> tau.round(3).tolist(), h.round(6).tolist()
    ([0.25, 0.35, 0.45], [2.5, 3.5, 4.5])
    """
    xx = np.asarray(x, dtype=float)
    if xx.ndim == 0 or xx.shape[0] < 6:
        n = 0 if xx.ndim == 0 else xx.shape[0]
        raise InsufficientSamples(
            f"the 1-2-3-3-2-1 filter needs at least 6 samples, got {n}; record a longer series"
        )
    tt = check_time(t, xx.shape[0])
    check_uniform(tt, tol)
    n = xx.shape[0] - 5
    h = sum(w * xx[i : i + n] for i, w in enumerate(THESIS_KERNEL))
    tau = sum(w * tt[i : i + n] for i, w in enumerate(THESIS_KERNEL))
    return np.asarray(tau), np.asarray(h)


def thesis_filter_response(sigma: ArrayLike) -> FloatArray:
    """Signed amplitude response of the 1-2-3-3-2-1 filter (eqs 3.24-3.25, corrected).

    ``H(sigma) = (1 + 2 cos w) sin 2w / (12 sin(w/2))`` with ``w = 2 pi sigma``; the full complex
    response is ``exp(i 5w/2) H`` (a pure advance of 2.5 samples). ``|H|**2`` is eq. (3.25).

    Parameters
    ----------
    sigma : array_like
        Frequency in cycles per sampling interval (``f*T``; Nyquist = 0.5).

    Returns
    -------
    ndarray
        Real, signed gain; ``H(0) = 1``; zeros at 1/4, 1/3, 1/2.

    Examples
    --------
    >>> np.abs(thesis_filter_response([0.0, 0.1, 0.25, 0.4])).round(4).tolist()
    [1.0, 0.6715, 0.0, 0.0515]
    """
    s = np.asarray(sigma, dtype=float)
    w = 2.0 * np.pi * s
    half = np.sin(w / 2.0)
    small = np.abs(half) < 1e-12
    safe = np.where(small, 1.0, half)
    # limit at w -> 0 (mod 4 pi): sin2w/sin(w/2) -> 4 cos(2w)/(0.5 cos(w/2)) = 4 when w = 0
    ratio = np.where(small, 4.0 * np.cos(2 * w) / np.cos(w / 2.0), np.sin(2.0 * w) / safe)
    return (1.0 + 2.0 * np.cos(w)) * ratio / 12.0


# ----------------------------------------------------------------------------------------------
# Butterworth
# ----------------------------------------------------------------------------------------------
def _butter_run(t: FloatArray, x: FloatArray, sos: FloatArray) -> FloatArray:
    n = x.shape[0]
    default = 3 * (2 * len(sos) + 1 - min(int((sos[:, 2] == 0).sum()), int((sos[:, 5] == 0).sum())))
    from scipy.signal import sosfiltfilt  # scipy.signal costs ~1 s to import: only when used

    return sosfiltfilt(sos, x, axis=0, padlen=min(default, n - 1))


def butterworth(
    t: ArrayLike,
    x: ArrayLike,
    cutoff: float | str = "residual",
    order: int = 2,
    *,
    max_gap: int | None = None,
    max_gap_s: float | None = None,
    tol: float = 0.05,
) -> FloatArray:
    """Zero-phase low-pass Butterworth filter along axis 0 (``butter`` + ``sosfiltfilt``).

    The forward-backward pass doubles the order (``order=2`` gives Winter's 4th-order zero-lag
    filter); the gain at ``cutoff`` is 0.5 (-6 dB). Each contiguous finite run of each channel is
    filtered separately (odd padding shortened for short runs); runs shorter than
    ``3`` samples cannot be filtered and come back NaN.

    Parameters
    ----------
    t : array_like, shape (T,)
        Uniform sample times in s.
    x : array_like, shape (T, ...)
        Data, NaN where missing.
    cutoff : float or "residual"
        Cutoff frequency in Hz, or ``"residual"`` to pick it per channel by Winter's residual
        analysis (:func:`residual_cutoff`).
    order : int
        Order of the single-pass Butterworth design.
    max_gap, max_gap_s : optional
        Bridge gaps up to this length (samples / s) by :func:`fill_gaps` before filtering.
    tol : float
        Uniformity tolerance.

    Returns
    -------
    ndarray, shape (T, ...)
        Filtered data; NaN where the input was missing (and not bridged).

    Raises
    ------
    NonUniformSampling
        If the sampling is uneven (resample first or use the smoothing spline).
    InsufficientSamples
        If the cutoff is not below the Nyquist frequency.

    Examples
    --------
    >>> t = np.arange(200) / 100.0
    >>> y = butterworth(t, np.ones(200) * 3.0, cutoff=6.0)
    >>> bool(np.allclose(y, 3.0))
    True
    """
    tt, xx = _prepare(t, x, max_gap, max_gap_s)
    period = check_uniform(tt, tol)
    fs = 1.0 / period
    if isinstance(cutoff, str):
        if cutoff != "residual":
            raise InsufficientSamples(f"cutoff must be a frequency in Hz or 'residual', got {cutoff!r}")
        fc = residual_cutoff(tt, xx, order=order)
        x2 = xx.reshape(xx.shape[0], -1)
        out = np.empty_like(x2)
        for c, f in enumerate(np.ravel(fc)):
            if not np.isfinite(f):
                out[:, c] = np.nan
                continue
            sos = _butter_sos(order, f, fs=fs, output="sos")
            out[:, c] = _apply_runs(tt, x2[:, c], lambda tr, xr, sos=sos: _butter_run(tr, xr, sos), 3)
        return out.reshape(xx.shape)
    if not 0 < cutoff < fs / 2:
        raise InsufficientSamples(
            f"cutoff {cutoff} Hz must lie between 0 and the Nyquist frequency {fs / 2:.6g} Hz"
        )
    sos = _butter_sos(order, cutoff, fs=fs, output="sos")
    return _apply_runs(tt, xx, lambda tr, xr, sos=sos: _butter_run(tr, xr, sos), 3)


def residual_cutoff(
    t: ArrayLike,
    x: ArrayLike,
    order: int = 2,
    f_min: float | None = None,
    f_max: float | None = None,
    n_freq: int = 60,
    noise_band: tuple[float, float] = (0.6, 1.0),
) -> FloatArray:
    """Choose Butterworth cutoffs by Winter's residual analysis, per channel.

    The residual ``R(fc) = rms(x - filtered(x, fc))`` is computed on a frequency grid from
    ``f_min`` (default 0.5 % of fs) to ``f_max`` (default 0.45 fs). A straight line fitted to
    ``R`` over the upper ``noise_band`` fraction of the grid models pure noise; its intercept
    ``a`` at fc = 0 is the noise rms, and the cutoff is the lowest grid frequency with
    ``R(fc) <= a`` (Winter, *Biomechanics and Motor Control of Human Movement*, §3.4.4.3).

    Parameters
    ----------
    t : array_like, shape (T,)
        Uniform sample times in s.
    x : array_like, shape (T, ...)
        Data, NaN where missing (runs are filtered separately).
    order : int
        Single-pass Butterworth order.
    f_min, f_max : float, optional
        Frequency grid limits in Hz.
    n_freq : int
        Number of grid frequencies.
    noise_band : (float, float)
        Fractions of the grid (0 = f_min, 1 = f_max) used to fit the noise line.

    Returns
    -------
    ndarray, shape x.shape[1:]
        Cutoff in Hz per channel (NaN for a channel with too few samples).

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> t = np.arange(1000) / 200.0
    >>> x = np.sin(2 * np.pi * 1.0 * t) * 100 + rng.normal(0, 1, t.size)
    >>> fc = float(residual_cutoff(t, x))
    >>> 2.0 < fc < 20.0
    True
    """
    xx = np.asarray(x, dtype=float)
    tt = check_time(t, xx.shape[0])
    fs = 1.0 / check_uniform(tt)
    lo = 0.005 * fs if f_min is None else f_min
    hi = 0.45 * fs if f_max is None else f_max
    freqs = np.linspace(lo, hi, n_freq)
    x2 = xx.reshape(xx.shape[0], -1)
    res = np.empty((n_freq, x2.shape[1]))
    for i, f in enumerate(freqs):
        sos = _butter_sos(order, f, fs=fs, output="sos")
        y = _apply_runs(tt, x2, lambda tr, xr, sos=sos: _butter_run(tr, xr, sos), 3)
        res[i] = np.sqrt(np.nanmean((x2 - y) ** 2, axis=0))
    i0 = int(round(noise_band[0] * (n_freq - 1)))
    i1 = int(round(noise_band[1] * (n_freq - 1))) + 1
    out = np.full(x2.shape[1], np.nan)
    for c in range(x2.shape[1]):
        r = res[:, c]
        if not np.all(np.isfinite(r)):
            continue
        slope, intercept = np.polyfit(freqs[i0:i1], r[i0:i1], 1)
        below = np.flatnonzero(r <= intercept)
        out[c] = freqs[below[0]] if below.size else freqs[-1]
    return out.reshape(xx.shape[1:])


# ----------------------------------------------------------------------------------------------
# GCV smoothing spline
# ----------------------------------------------------------------------------------------------
def fit_smoothing_spline(t: FloatArray, y: FloatArray, lam: float | None = None) -> BSpline:
    """Fit ``make_smoothing_spline`` to one run ``y`` (n, C); GCV per column when ``lam`` is None.

    Returns a BSpline with the columns as batch dimension.
    """
    if lam is not None or y.ndim == 1 or y.shape[1] == 1:
        return make_smoothing_spline(t, y, lam=lam, axis=0)
    parts = [make_smoothing_spline(t, y[:, c], lam=None) for c in range(y.shape[1])]
    coef = np.stack([p.c for p in parts], axis=1)
    return BSpline(parts[0].t, coef, parts[0].k, extrapolate=False)


def smoothing_spline(
    t: ArrayLike,
    x: ArrayLike,
    lam: float | None = None,
    *,
    max_gap: int | None = None,
    max_gap_s: float | None = None,
) -> FloatArray:
    """Smooth along axis 0 with a cubic smoothing spline (GCV choice of ``lam`` per channel).

    Uneven sampling is allowed. Each contiguous finite run (>= 5 samples) of each channel is
    fitted separately; shorter runs come back NaN.

    Parameters
    ----------
    t : array_like, shape (T,)
        Sample times in s.
    x : array_like, shape (T, ...)
        Data, NaN where missing.
    lam : float, optional
        Regularisation parameter (units value² · s³); None = generalised cross-validation.
        ``lam=0`` gives the interpolating natural cubic spline.
    max_gap, max_gap_s : optional
        Bridge gaps up to this length (samples / s) before smoothing.

    Returns
    -------
    ndarray, shape (T, ...)

    Examples
    --------
    >>> t = np.linspace(0.0, 1.0, 50)
    >>> bool(np.allclose(smoothing_spline(t, 2.0 * t + 1.0), 2.0 * t + 1.0))
    True
    """
    tt, xx = _prepare(t, x, max_gap, max_gap_s)
    return _apply_runs(tt, xx, lambda tr, xr: fit_smoothing_spline(tr, xr, lam)(tr), 5)


def _butter_sos(order: int, cutoff: float, fs: float, output: str = "sos") -> np.ndarray:
    """``scipy.signal.butter`` imported on first use (scipy.signal costs ~1 s to import)."""
    from scipy.signal import butter

    return butter(order, cutoff, fs=fs, output=output)
