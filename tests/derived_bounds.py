"""Error bounds derived from the problem, for the kinematics, mechanism and retarget tests.

Complements :mod:`tests.tolerances` (which this module does not change) with the bounds of a few
computations whose conditioning is not a single matrix's:

* :func:`smoothing_spline_rounding` -- scipy's GCV smoothing spline on exact data (and
  :func:`spline_derivative_norm`, the gain of its derivative);
* :func:`natural_end_error` -- an interpolating natural spline's derivative near a run end;
* :func:`butterworth_ramp_transient` -- the zero-phase Butterworth filter's start-up error on a line;
* :func:`kabsch_cond` -- rotation fit (Kabsch / polar factor) to rounded marker positions;
* :func:`perturbation_rounding` -- any pipeline's rounding, from its measured sensitivity;
* :data:`F32` -- one rounding to float32 (C3D float storage).

Smoothing spline. scipy solves ``(X + λ W⁻¹E) c = y`` in the natural-spline basis (Woltring's
formulation) by banded LU, then evaluates derivatives of the spline. A backward-stable solve
perturbs the matrix by ``‖δA‖∞ ≲ ε ‖A‖∞``, so the ν-th derivative moves by ``D_ν,λ δA c`` with
``D_ν,λ = E_ν A⁻¹`` the *linear map* from data to ν-th derivative at fixed λ (a public quantity: the
smoothing spline of the unit vectors), giving

    |δ s⁽ᵛ⁾| ≤ ε · ‖D_ν,λ‖∞ · ‖A_λ‖∞ · ‖c‖∞.

On a uniform grid of step h, rows of ``X`` (B-spline values) sum to 1 and rows of ``W⁻¹E`` (6 × the
5-point divided difference scaled by x_{j+2} - x_{j-2}) are ``(1, -4, 6, -4, 1) / h³``, so
``‖A_λ‖∞ ≤ 1 + 16 λ / h³``: a large λ makes the solve ill-conditioned. On noise-free data whose
smooth part the spline reproduces exactly (a straight line), the GCV criterion is flat up to
rounding and its minimiser is anywhere in scipy's search interval ``(0, n)`` (and differs between
CPUs), so the bound must be the worst case, at λ = n.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.interpolate import make_smoothing_spline

from tests.tolerances import roundoff

FloatArray = NDArray[np.float64]

#: Relative error of one rounding to float32 (half its machine epsilon, with a factor 2 margin):
#: a coordinate stored in a float C3D file comes back within ``F32 · |x|``.
F32 = float(np.finfo(np.float32).eps)


def spline_derivative_norm(t: ArrayLike, nu: int, lam: float, interior: slice = slice(None)) -> float:
    """‖D_ν,λ‖∞: how much the ``nu``-th derivative of ``make_smoothing_spline(t, ·, lam)`` at ``t``
    (rows ``interior``) can grow from a perturbation of the data (unit of data / s**nu per unit).

    Computed as the spline of the n unit vectors: column k of D is the response to y_k = 1.
    """
    tt = np.asarray(t, dtype=float)
    response = make_smoothing_spline(tt, np.eye(tt.size), lam=lam)(tt, nu=nu)[interior]
    return float(np.abs(response).sum(axis=1).max())


def smoothing_spline_rounding(t: ArrayLike, y: ArrayLike, nu: int, lam: float | None = None,
                              interior: slice = slice(None)) -> float:
    """Rounding bound on the ``nu``-th derivative of ``make_smoothing_spline(t, y, lam)`` at ``t``.

    Parameters
    ----------
    t : array_like, shape (n,)
        Uniform sample times (s).
    y : array_like, shape (n,)
        The data (any unit).
    nu : int
        Derivative order (0 = the smoothed value).
    lam : float, optional
        The regularisation used; None (GCV) means the worst case over scipy's GCV interval (0, n).
    interior : slice
        Samples where the result is compared (the derivative map's norm over these rows).

    Returns
    -------
    float
        Absolute bound, unit of ``y`` / s**nu, with :data:`tests.tolerances.SAFETY`.
    """
    tt = np.asarray(t, dtype=float)
    yy = np.asarray(y, dtype=float)
    h = np.diff(tt)
    if not np.allclose(h, h[0], rtol=1e-9, atol=0.0):
        raise ValueError("smoothing_spline_rounding: the penalty row sum 16/h³ needs a uniform grid")
    n = tt.size
    lam_max = float(n) if lam is None else float(lam)
    norm_d = spline_derivative_norm(tt, nu, lam_max, interior)
    norm_a = 1.0 + 16.0 * lam_max / h[0] ** 3
    # natural-basis coefficients: the B-spline ones, except the two end slopes scipy converts as
    # c_[0] - c_[1] = c0 (x1 - x0) and c_[-1] - c_[-2] = c_end (x[-1] - x[-2])
    cb = make_smoothing_spline(tt, yy, lam=lam_max).c
    slopes = np.array([(cb[0] - cb[1]) / h[0], (cb[-1] - cb[-2]) / h[-1]])
    # floored at the smallest normal number, below which rounding is absolute (eps · tiny)
    norm_c = float(max(np.abs(cb).max(), np.abs(slopes).max(), np.finfo(float).tiny))
    return roundoff(scale=norm_d * norm_a * norm_c)


def butterworth_ramp_transient(slope: float, fs: float, cutoff: float, n: int, k: ArrayLike = 0,
                               order: int = 2) -> FloatArray:
    """Start-up error of the zero-phase Butterworth filter on a straight line, ``k`` samples from a run end.

    ``sosfiltfilt`` pads the run with its odd extension (still the same line) and starts each pass
    in the steady state for a *constant* input; a line has a steady-state lag of ``slope · τ``
    (τ = group delay at DC), so each pass starts with a homogeneous transient of that size, which
    decays with the largest pole modulus r per sample over the padding and then the run. The two
    passes lag in opposite directions (no error in the middle); at an end the error is at most
    ``2 · |slope| · τ · r^(padlen + k)`` (the factor 2 covers the non-normal growth of a
    second-order section, ≤ 1/√(1-ζ²) = 1.41 for ζ = 0.707, times the other pass's gain, ≤ 1.1).

    Parameters
    ----------
    slope : float
        Rise of the line per second (unit of the data / s).
    fs, cutoff : float
        Sampling rate and single-pass cutoff (Hz).
    n : int
        Samples in the run (the padding is shortened to n - 1 for short runs, as in
        ``mirrorlab.plugins.kinematics.filters``).
    k : array_like of int
        Distance (samples) from the nearest end of the run.
    order : int
        Single-pass order (one second-order section for order 2).

    Returns
    -------
    ndarray
        Bound (unit of the data), same shape as ``k``.
    """
    from scipy.signal import butter

    sos = butter(order, cutoff, fs=fs, output="sos")
    if len(sos) != 1:
        raise ValueError("butterworth_ramp_transient: derived for one second-order section (order 2)")
    b, a = sos[0, :3], sos[0, 3:]
    idx = np.arange(3)
    tau = (idx @ b) / b.sum() - (idx @ a) / a.sum()          # DC group delay, samples
    r = float(np.abs(np.roots(a)).max())
    padlen = min(3 * (2 * len(sos) + 1), n - 1)
    return 2.0 * abs(slope) * (tau / fs) * r ** (padlen + np.asarray(k, dtype=float))


def kabsch_cond(reference: ArrayLike, markers: ArrayLike) -> float:
    """Condition number of the Kabsch rotation fit of ``reference`` to ``markers``, worst frame.

    Rounding moves each marker coordinate by ~ε·M (M the largest marker magnitude, which the
    centring subtracts); ``H = Σ p qᵀ`` then moves by ≤ √n ‖p‖_F ε M and its polar factor R by
    ≤ 2 ‖δH‖ / (σ₂ + σ₃)(H), with σ(H) = σ(p)² for exact data (p: the visible reference points,
    centred). So ``‖δR‖ ≤ ε · κ`` with ``κ = 2 √n ‖p‖_F M / (s₂² + s₃²)``; the fitted origin and the
    residuals move by ≤ ε · κ · (M + max |reference|).

    Parameters
    ----------
    reference : array_like, shape (M, 3)
        Body-frame marker positions (mm).
    markers : array_like, shape (T, M, 3) or (M, 3)
        Measured positions (mm), NaN where missing; frames with < 3 visible markers are skipped.

    Returns
    -------
    float
        κ (dimensionless; multiply by the magnitude for the origin).
    """
    ref = np.asarray(reference, dtype=float)
    m = np.asarray(markers, dtype=float).reshape(-1, *ref.shape)
    magnitude = float(np.nanmax(np.abs(m)))
    worst = 1.0
    for mask in {tuple(np.isfinite(f).all(axis=1)) for f in m}:
        vis = np.asarray(mask)
        if vis.sum() < 3:
            continue
        p = ref[vis] - ref[vis].mean(axis=0)
        s = np.linalg.svd(p, compute_uv=False)
        worst = max(worst, 2.0 * np.sqrt(vis.sum()) * np.linalg.norm(p) * magnitude / (s[1] ** 2 + s[2] ** 2))
    return worst


def natural_end_error(h: float, curvature: float, k: ArrayLike) -> FloatArray:
    """Error of an interpolating natural cubic spline's first derivative ``k`` samples from a run end.

    The natural condition sets s'' = 0 where f'' ≠ 0; the difference from the exact-end spline is a
    spline that vanishes at the knots, with slopes m_i = m_0 (-(2 - √3))^i and, from the end row
    2 m_0 + m_1 = h f''/2, ``|m_0| = h |f''| / (2√3)``. Away from the ends the interpolation error
    itself is far smaller (superconvergent at the knots: h⁴/180 |f⁽⁵⁾|).

    Parameters
    ----------
    h : float
        Sample step (s).
    curvature : float
        Bound on |f''| at the run ends (unit / s²).
    k : array_like
        Distance from the nearest run end (samples).
    """
    return h * curvature / (2.0 * np.sqrt(3.0)) * (2.0 - np.sqrt(3.0)) ** np.asarray(k, dtype=float)


def perturbation_rounding(func: Callable[[FloatArray], ArrayLike], points: ArrayLike, ops: float = 10,
                          delta: float = 1e-6, seed: int = 0) -> FloatArray:
    """Rounding bound on ``func(points)`` for exact ``points``, from its measured sensitivity.

    Rounding perturbs every coordinate by a few eps · |coordinate|, in no particular direction; the
    response of ``func`` to a random Gaussian perturbation of every coordinate by ``delta`` (linear
    regime, far above rounding) is its response to such a perturbation per unit, so the bound is
    ``|func(p + delta g) - func(p)| / delta · roundoff(scale=max |p|, ops=ops)`` per output. This is
    the conditioning of a pipeline (grouping, pose fits, least squares, closed forms) computed
    rather than guessed; SAFETY covers the spread between one random direction and another.

    Parameters
    ----------
    func : callable
        Maps the points (any shape, NaN kept) to the outputs compared (array_like).
    points : array_like
        The exact input coordinates.
    ops : float
        Rounded operations producing the coordinates' error (see :func:`tests.tolerances.roundoff`).
    delta, seed : float, int
        Perturbation size (unit of ``points``) and its random direction.

    Returns
    -------
    ndarray
        Absolute bound per output (unit of the output), same shape as ``func(points)``.
    """
    p = np.asarray(points, dtype=float)
    g = np.random.default_rng(seed).standard_normal(p.shape)
    base = np.asarray(func(p), dtype=float)
    moved = np.asarray(func(p + delta * g), dtype=float)
    per_unit = roundoff(scale=float(np.nanmax(np.abs(p))), ops=ops) / delta
    return np.abs(moved - base) * per_unit
