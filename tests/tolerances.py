"""Tolerances derived from the computation, not from what one machine printed.

A floating-point result differs between CPUs, BLAS kernels and library versions by rounding, and
by no more than its *forward error bound*: for a backward-stable computation, relative error
≲ c · κ · ε, where ε is the unit roundoff of float64 (2.2e-16), κ the condition number of the
problem (how much a relative change of the input moves the output) and c a modest constant of the
algorithm (the number of rounded operations along the critical path, a few per step of an
iteration). A test compares with such a bound; it may be looser than the bound (a check of the
method, not of rounding), never tighter.

Use:

* :func:`roundoff` for an explicit error estimate ``safety · ops · κ · ε · scale``;
* :func:`cond` for κ of a matrix (2-norm) when the problem is a linear solve or a least-squares
  fit;
* :func:`rel_err` / :func:`abs_err` to measure, with NaN treated as an error unless both sides are
  NaN.

Where the error is not rounding but the method (a discretisation, a spline of noisy data, a
tracker's gate), the tolerance comes from the method's own error term; say which in a comment
next to the assertion (e.g. "O(h²) central difference, h = 0.01 s: 1e-4 · |x'''|").
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

#: Unit roundoff of float64 (machine epsilon).
EPS = float(np.finfo(float).eps)

#: Default safety factor over the first-order bound: covers the constants of backward-stable
#: algorithms (LAPACK's bounds carry factors of the order of the dimension) and summation order
#: differences between BLAS kernels.
SAFETY = 100.0


def roundoff(*, cond: float = 1.0, scale: float = 1.0, ops: float = 1.0, safety: float = SAFETY) -> float:
    """Rounding error bound ``safety · ops · cond · ε · scale``.

    Parameters
    ----------
    cond : float
        Condition number κ of the problem (1 for a well-conditioned evaluation).
    scale : float
        Magnitude of the result (absolute tolerance) or 1 (relative tolerance), in the result's
        units.
    ops : float
        Rounded operations along the critical path (e.g. the length of a sum, the number of
        steps of an iteration that accumulates error).
    safety : float
        Factor over the first-order bound; see :data:`SAFETY`.

    Examples
    --------
    >>> f"{roundoff(cond=1e3, scale=500.0):.1e}"   # a 500 mm result of a problem with κ = 1000
    '1.1e-08'
    """
    return safety * ops * max(cond, 1.0) * EPS * scale


def cond(matrix: ArrayLike) -> float:
    """2-norm condition number of ``matrix`` (σ_max / σ_min; ``inf`` if singular)."""
    return float(np.linalg.cond(np.asarray(matrix, dtype=float)))


def abs_err(actual: ArrayLike, expected: ArrayLike) -> float:
    """Largest absolute difference; a NaN on one side only counts as an infinite error."""
    a, b = np.broadcast_arrays(np.asarray(actual, dtype=float), np.asarray(expected, dtype=float))
    both_nan = np.isnan(a) & np.isnan(b)
    diff = np.where(both_nan, 0.0, np.abs(a - b))
    diff = np.where(np.isnan(diff), np.inf, diff)
    return float(diff.max()) if diff.size else 0.0


def rel_err(actual: ArrayLike, expected: ArrayLike) -> float:
    """Largest absolute difference relative to the largest magnitude of ``expected``."""
    b = np.asarray(expected, dtype=float)
    norm = float(np.nanmax(np.abs(b))) if np.any(np.isfinite(b)) else 1.0
    return abs_err(actual, expected) / (norm or 1.0)
