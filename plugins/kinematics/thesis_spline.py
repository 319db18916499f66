"""The thesis's parametric cubic spline (eqs 3.26-3.38, Appendix 1) and its derivative procedure.

Time and value are both coordinates of a plane curve ``(t(u), theta(u))`` with one unit of the
parameter ``u`` per sample interval. Tangents come from the natural-end tridiagonal system
(3.31)-(3.33); a query time is converted to ``u`` by inverting the cubic ``t(u)`` (3.35) with a
safeguarded Newton iteration (bisection fallback, at most 50 steps); derivatives follow from the
chain rule (3.37)-(3.38, corrected). :func:`thesis_derivatives` is the full §3.3 procedure:
filter (3.21) -> spline -> velocity -> filter -> spline -> acceleration.

Units: t in s, values in the caller's unit (mm, rad, ...); derivatives per s and per s².
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.linalg import solve_banded

from .errors import InsufficientSamples, NonMonotonicTimeSpline, OutOfRange
from .filters import check_time, thesis_filter

__all__ = ["ParametricSpline", "ThesisDerivatives", "thesis_derivatives", "natural_tangents"]

FloatArray = NDArray[np.float64]


def natural_tangents(p: ArrayLike) -> FloatArray:
    """Solve (3.31)-(3.33): tangents ``t_j`` (w.r.t. u) of the natural-end parametric spline.

    Parameters
    ----------
    p : array_like, shape (n, C)
        Points, one channel per column (n >= 3).

    Returns
    -------
    ndarray, shape (n, C)

    Examples
    --------
    >>> natural_tangents(np.arange(5.0)[:, None]).ravel().round(12).tolist()
    [1.0, 1.0, 1.0, 1.0, 1.0]
    """
    pp = np.asarray(p, dtype=float)
    n = pp.shape[0]
    ab = np.zeros((3, n))
    ab[0, 1:] = 1.0  # super-diagonal
    ab[2, :-1] = 1.0  # sub-diagonal
    ab[1, :] = 4.0
    ab[1, 0] = ab[1, -1] = 2.0
    rhs = np.empty_like(pp)
    rhs[1:-1] = 3.0 * (pp[2:] - pp[:-2])
    rhs[0] = 3.0 * (pp[1] - pp[0])
    rhs[-1] = 3.0 * (pp[-1] - pp[-2])
    return solve_banded((1, 1), ab, rhs)


class ParametricSpline:
    """Parametric natural cubic spline through ``(t_j, values_j)`` (thesis §3.3.2).

    Parameters
    ----------
    t : array_like, shape (n,)
        Strictly increasing sample times in s (n >= 3); uneven spacing allowed.
    values : array_like, shape (n,) or (n, d)
        Data; each column is splined with the same time channel.

    Raises
    ------
    InsufficientSamples
        If n < 3.
    NonMonotonicTime
        If t is not strictly increasing.
    NonMonotonicTimeSpline
        If dt/du <= 0 somewhere on a segment (strongly irregular spacing).

    Examples
    --------
    >>> t = np.linspace(0.0, 1.0, 11)
    >>> s = ParametricSpline(t, t ** 2)
    >>> round(float(s.evaluate(0.5)), 3), round(float(s.evaluate(0.5, derivative=1)), 3)
    (0.25, 1.0)
    """

    def __init__(self, t: ArrayLike, values: ArrayLike) -> None:
        v = np.asarray(values, dtype=float)
        if v.ndim == 0:
            raise InsufficientSamples("values must have a time axis")
        n = v.shape[0]
        if n < 3:
            raise InsufficientSamples(
                f"the parametric spline needs at least 3 samples, got {n}; use a longer series"
            )
        tt = check_time(t, n)
        self._vector = v.ndim == 1
        self._tail = v.shape[1:]
        v2 = v.reshape(n, -1)
        if not np.all(np.isfinite(v2)):
            raise InsufficientSamples(
                "values contain NaN; spline each contiguous run separately (see thesis_derivatives)"
            )
        pts = np.column_stack([tt, v2])  # channel 0 = time (subscript 1 of the thesis)
        tan = natural_tangents(pts)
        P0, P1 = pts[:-1], pts[1:]
        T0, T1 = tan[:-1], tan[1:]
        # (3.30): per segment j and channel
        self.a = 2.0 * (P0 - P1) + T0 + T1
        self.b = 3.0 * (P1 - P0) - 2.0 * T0 - T1
        self.c = T0
        self.d = P0
        self.t = tt
        self._check_monotonic()

    def _check_monotonic(self) -> None:
        a1, b1, c1 = self.a[:, 0], self.b[:, 0], self.c[:, 0]
        # min of t'(u) = 3 a u^2 + 2 b u + c on [0, 1]: endpoints and the vertex
        cand = [c1, 3 * a1 + 2 * b1 + c1]
        with np.errstate(divide="ignore", invalid="ignore"):
            uv = np.where(a1 != 0, -b1 / (3 * a1), -1.0)
        inside = (uv > 0) & (uv < 1)
        cand.append(np.where(inside, 3 * a1 * uv**2 + 2 * b1 * uv + c1, np.inf))
        m = np.min(np.vstack(cand), axis=0)
        bad = np.flatnonzero(m <= 0)
        if bad.size:
            j = int(bad[0])
            raise NonMonotonicTimeSpline(
                f"dt/du <= 0 on spline segment {j} (t={self.t[j]:.6g}..{self.t[j + 1]:.6g} s): the "
                "sampling is too irregular for the parametric spline; resample or use "
                "method='smoothing_spline'"
            )

    def _locate(self, tq: FloatArray) -> tuple[NDArray[np.intp], FloatArray]:
        t = self.t
        span = t[-1] - t[0]
        eps = 1e-12 * max(span, abs(t[-1]))
        out = (tq < t[0] - eps) | (tq > t[-1] + eps) | ~np.isfinite(tq)
        if np.any(out):
            k = int(np.flatnonzero(out)[0])
            raise OutOfRange(
                f"query time {tq[k]:.6g} s is outside the sampled interval "
                f"[{t[0]:.6g}, {t[-1]:.6g}] s; the spline does not extrapolate"
            )
        tq = np.clip(tq, t[0], t[-1])
        j = np.clip(np.searchsorted(t, tq, side="right") - 1, 0, t.size - 2)
        a1, b1, c1, d1 = self.a[j, 0], self.b[j, 0], self.c[j, 0], self.d[j, 0]
        lo = np.zeros_like(tq)
        hi = np.ones_like(tq)
        u = (tq - t[j]) / (t[j + 1] - t[j])  # exact when the time tangents equal the spacing
        tol = 1e-14 * (np.abs(tq) + (t[j + 1] - t[j]))
        for _ in range(50):  # safeguarded Newton; t(u) is strictly increasing on [0, 1]
            f = ((a1 * u + b1) * u + c1) * u + d1 - tq
            done = np.abs(f) <= tol
            if np.all(done):
                break
            hi = np.where(f > 0, u, hi)
            lo = np.where(f < 0, u, lo)
            fp = (3 * a1 * u + 2 * b1) * u + c1
            un = u - f / fp
            bad = ~((un > lo) & (un < hi))
            un = np.where(bad, 0.5 * (lo + hi), un)
            u = np.where(done, u, un)
        return j, u

    def evaluate(self, tq: ArrayLike, derivative: int = 0) -> FloatArray:
        """Value (0), first (3.37) or second (3.38) time derivative at times ``tq``.

        Parameters
        ----------
        tq : array_like
            Query times in s within ``[t[0], t[-1]]``.
        derivative : {0, 1, 2}

        Returns
        -------
        ndarray, shape tq.shape + values.shape[1:]

        Raises
        ------
        OutOfRange
            For a query outside the sampled interval.
        """
        if derivative not in (0, 1, 2):
            raise InsufficientSamples(f"derivative must be 0, 1 or 2, got {derivative}")
        q = np.asarray(tq, dtype=float)
        flat = q.reshape(-1)
        j, u = self._locate(flat)
        u = u[:, None]
        a, b, c, d = self.a[j], self.b[j], self.c[j], self.d[j]
        a1, b1, c1 = a[:, :1], b[:, :1], c[:, :1]
        a2, b2, c2, d2 = a[:, 1:], b[:, 1:], c[:, 1:], d[:, 1:]
        if derivative == 0:
            r = ((a2 * u + b2) * u + c2) * u + d2
        else:
            tu = (3 * a1 * u + 2 * b1) * u + c1
            if derivative == 1:
                r = ((3 * a2 * u + 2 * b2) * u + c2) / tu
            else:
                num = (
                    6 * (b1 * a2 - a1 * b2) * u**2
                    + 6 * (c1 * a2 - a1 * c2) * u
                    + 2 * (c1 * b2 - b1 * c2)
                )
                r = num / tu**3
        if self._vector:
            return r[:, 0].reshape(q.shape)
        return r.reshape(q.shape + self._tail)


@dataclass(frozen=True)
class ThesisDerivatives:
    """Output of :func:`thesis_derivatives` for one contiguous, uniformly sampled run.

    Attributes
    ----------
    t_value : ndarray, shape (N-5,)
        Time stamps of the filtered positions, ``t_k + 2.5 T`` (s).
    value, velocity : ndarray, shape (N-5, ...)
        Filtered values and their spline derivative (3.37) at ``t_value``.
    t_acceleration : ndarray, shape (N-10,)
        Stamps of the re-filtered velocity, ``t_k + 5 T`` (s).
    acceleration : ndarray, shape (N-10, ...)
        Derivative of the spline through the filtered velocity (per s²).
    """

    t_value: FloatArray
    value: FloatArray
    velocity: FloatArray
    t_acceleration: FloatArray
    acceleration: FloatArray


def thesis_derivatives(t: ArrayLike, x: ArrayLike, prefilter: bool = True) -> ThesisDerivatives:
    """Thesis §3.3 procedure: filter -> spline -> velocity -> filter -> spline -> acceleration.

    Parameters
    ----------
    t : array_like, shape (N,)
        Sample times in s (uniform when ``prefilter``; N >= 13).
    x : array_like, shape (N, ...)
        Finite data (one contiguous run).
    prefilter : bool
        Apply the 1-2-3-3-2-1 filter to positions and velocities (thesis). With False the spline
        passes through the raw samples and uneven sampling is allowed.

    Returns
    -------
    ThesisDerivatives

    Examples
    --------
    >>> t = np.arange(40) * 0.05
    >>> r = thesis_derivatives(t, 3.0 * t ** 2)
    >>> bool(np.allclose(r.acceleration[8:-8], 6.0, rtol=1e-4))
    True
    """
    xx = np.asarray(x, dtype=float)
    tt = check_time(t, xx.shape[0] if xx.ndim else None)
    if prefilter:
        if xx.shape[0] < 13:
            raise InsufficientSamples(
                f"the filtered thesis procedure needs at least 13 samples, got {xx.shape[0]}"
            )
        tau, h = thesis_filter(tt, xx)
        s1 = ParametricSpline(tau, h)
        vel = s1.evaluate(tau, 1)
        tau2, vf = thesis_filter(tau, vel)
        s2 = ParametricSpline(tau2, vf)
        return ThesisDerivatives(tau, h, vel, tau2, s2.evaluate(tau2, 1))
    s1 = ParametricSpline(tt, xx)
    vel = s1.evaluate(tt, 1)
    s2 = ParametricSpline(tt, vel)
    return ThesisDerivatives(tt, xx.copy(), vel, tt, s2.evaluate(tt, 1))
