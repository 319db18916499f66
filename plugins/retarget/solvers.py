"""Minimisers of the evaluation function, vectorised over a batch of independent rows.

* :func:`levenberg_marquardt` — simultaneous least squares on the stacked residual with the
  analytic Jacobian (spec §6). Hand-vectorised over rows because scipy's ``least_squares``
  solves one problem per call, and its per-call overhead (about 1 ms) would dominate problems
  with 4–6 unknowns; ``benchmarks/bench_retarget.py`` measures both.
* :func:`paper_sweeps` — the paper's per-joint Newton scheme (spec §5): Gauss–Seidel sweeps,
  one Newton step per angle with the Gauss–Newton curvature, step ≤ 0.3 rad, halved until f
  does not increase, clamped to the joint limits.
* :func:`multistart` — best of a fixed set of starts, for the fallback of spec §6.

Angles rad, lengths mm, f mm². Joint limits are enforced by projection (clamping).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from .objective import Arms, Objective

__all__ = ["Solution", "levenberg_marquardt", "paper_sweeps", "multistart", "start_points"]

FloatArray = NDArray[np.float64]

#: Largest per-angle step of a Newton update (spec §5), rad.
MAX_STEP = 0.3
#: Halvings of a per-joint step before it is given up (the angle then stays where it is).
MAX_HALVINGS = 40


@dataclass
class Solution:
    """Angles q (B, dof) rad, f (B,) mm² and iterations (LM iterations or sweeps) per row."""

    q: FloatArray
    f: FloatArray
    iterations: NDArray[np.int64]


def _rows(R_b: FloatArray, p_b: FloatArray, rows: NDArray[np.int64]) -> tuple[FloatArray, FloatArray]:
    return (R_b[rows] if R_b.ndim == 3 else R_b), (p_b[rows] if p_b.ndim == 2 else p_b)


def levenberg_marquardt(obj: Objective, q0: FloatArray, arms: Arms, R_b: FloatArray, p_b: FloatArray,
                        max_iter: int = 20, ftol: float = 1e-12, xtol: float = 1e-10) -> Solution:
    """Levenberg–Marquardt with Marquardt scaling, vectorised over rows.

    Parameters
    ----------
    obj : Objective
    q0 : ndarray (B, dof)
        Starting angles, rad.
    arms : Arms
        Input arms of the B rows.
    R_b, p_b : ndarray
        Output base per row ((3, 3) or (B, 3, 3); (3,) or (B, 3)).
    max_iter : int
        Iterations (Jacobian evaluations) at most.
    ftol : float
        Stop a row when an accepted step lowers f by at most ``ftol · f`` (relative), or f < 1e-30 mm².
    xtol : float
        Stop a row when an accepted step is shorter than this (rad, max norm).

    Returns
    -------
    Solution
        Per row: angles (within the limits), f and the iterations used.
    """
    chain = obj.output
    q = chain.clip(np.array(q0, float))
    B, m = q.shape
    r, dr, _ = obj.residuals_jacobian(q, arms, R_b, p_b)
    f = np.einsum("bpi,bpi->b", r, r)
    lam = np.full(B, 1e-3)
    active = np.ones(B, bool)
    iters = np.zeros(B, np.int64)
    eye = np.eye(m)
    for _ in range(max_iter):
        rows = np.flatnonzero(active)
        if rows.size == 0:
            break
        iters[rows] += 1
        Jr = dr[rows].reshape(rows.size, -1, m)
        A = np.einsum("bki,bkj->bij", Jr, Jr)
        g = np.einsum("bki,bk->bi", Jr, r[rows].reshape(rows.size, -1))
        diag = np.einsum("bii->bi", A)
        scale = diag + 1e-9 * diag.max(axis=1, keepdims=True) + 1e-300
        step = -np.linalg.solve(A + lam[rows, None, None] * scale[:, :, None] * eye, g[..., None])[..., 0]
        q_new = chain.clip(q[rows] + step)
        a_rows, Rr, pr = (arms, R_b, p_b) if rows.size == B else (arms.take(rows), *_rows(R_b, p_b, rows))
        r_new, dr_new, _ = obj.residuals_jacobian(q_new, a_rows, Rr, pr)
        f_new = np.einsum("bpi,bpi->b", r_new, r_new)
        accept = f_new < f[rows]
        acc = rows[accept]
        gain = f[acc] - f_new[accept]
        moved = np.abs(q_new[accept] - q[acc]).max(axis=1)
        q[acc], f[acc], r[acc], dr[acc] = q_new[accept], f_new[accept], r_new[accept], dr_new[accept]
        lam[acc] = np.maximum(lam[acc] / 3.0, 1e-12)
        lam[rows[~accept]] *= 4.0
        done = (gain <= ftol * f[acc]) | (moved < xtol) | (f[acc] < 1e-30)
        active[acc[done]] = False
        active[rows[~accept][lam[rows[~accept]] > 1e12]] = False   # no descent direction left: a minimum
    return Solution(q, f, iters)


def paper_sweeps(obj: Objective, q0: FloatArray, arms: Arms, R_b: FloatArray, p_b: FloatArray,
                 sweeps: int | None = 3, ftol: float = 1e-12, max_sweeps: int = 5000) -> Solution:
    """The paper's per-joint Newton iteration (spec §5) as Gauss–Seidel sweeps, vectorised over rows.

    Each sweep visits the angles in order; angle ``r`` takes one Newton step
    ``Δ = −(∂f/∂q_r) / (∂²f/∂q_r²)`` with the Gauss–Newton curvature ``2 Σ |∂r/∂q_r|²`` (a gradient
    step when that is 0), ``|Δ| ≤ 0.3`` rad, halved until f does not increase, then clamped to
    the limits. So f never increases.

    Parameters
    ----------
    sweeps : int or None
        Sweeps per call (the streaming mode's K); ``None`` sweeps until a sweep lowers f by at most
        ``ftol · f`` (or f < 1e-30), at most ``max_sweeps`` times.

    Returns
    -------
    Solution
        ``iterations`` counts sweeps.
    """
    chain = obj.output
    q = chain.clip(np.array(q0, float))
    B, m = q.shape
    f = obj.value(q, arms, R_b, p_b)
    active = np.ones(B, bool)
    iters = np.zeros(B, np.int64)
    for _ in range(sweeps if sweeps is not None else max_sweeps):
        rows = np.flatnonzero(active)
        if rows.size == 0:
            break
        iters[rows] += 1
        a_rows = arms.take(rows)
        Rr, pr = _rows(R_b, p_b, rows)
        qr, fr = q[rows], f[rows]
        f_start = fr.copy()
        for k in range(m):
            r, dr, _ = obj.residuals_jacobian(qr, a_rows, Rr, pr)
            col = dr[..., k]
            grad = 2.0 * np.einsum("bpi,bpi->b", r, col)
            curv = 2.0 * np.einsum("bpi,bpi->b", col, col)
            delta = np.clip(np.where(curv > 0, -grad / np.where(curv > 0, curv, 1.0), -grad), -MAX_STEP, MAX_STEP)
            pending = np.ones(rows.size, bool)
            for _ in range(MAX_HALVINGS):
                trial = qr.copy()
                trial[:, k] += delta
                trial = chain.clip(trial)
                f_trial = obj.value(trial, a_rows, Rr, pr)
                ok = pending & (f_trial <= fr)
                qr[ok], fr[ok] = trial[ok], f_trial[ok]
                pending &= ~ok
                if not pending.any():
                    break
                delta = np.where(pending, delta / 2.0, 0.0)
        q[rows], f[rows] = qr, fr
        if sweeps is None:
            active[rows[(f_start - fr <= ftol * fr) | (fr < 1e-30)]] = False
    return Solution(q, f, iters)


def start_points(obj: Objective, n: int, seed: int = 0) -> FloatArray:
    """``n`` fixed start angles (n, dof): uniform within the limits, or in [−π, π) where unlimited."""
    lim = obj.output.limits
    lo = np.where(np.isfinite(lim[:, 0]), lim[:, 0], -np.pi)
    hi = np.where(np.isfinite(lim[:, 1]), lim[:, 1], np.pi)
    return lo + (hi - lo) * np.random.default_rng(seed).random((n, lim.shape[0]))


def multistart(obj: Objective, starts: FloatArray, arms: Arms, R_b: FloatArray, p_b: FloatArray,
               extra: FloatArray | None = None, max_iter: int = 200) -> Solution:
    """Best LM solution per row over the common ``starts`` (S, dof) and an optional extra start per row.

    Returns the lowest f per row (ties, within 1e-12 relative, go to the earliest start, the
    extra start first); ``iterations`` sums the LM iterations of all starts.
    """
    B = arms.start.shape[0]
    S = np.broadcast_to(starts, (B,) + starts.shape)
    if extra is not None:
        S = np.concatenate([np.asarray(extra, float)[:, None, :], S], axis=1)
    n = S.shape[1]
    rows = np.repeat(np.arange(B), n)
    Rr, pr = _rows(R_b, p_b, rows)
    sol = levenberg_marquardt(obj, S.reshape(B * n, -1), arms.take(rows), Rr, pr, max_iter=max_iter)
    f = sol.f.reshape(B, n)
    best = np.argmax(f <= f.min(axis=1, keepdims=True) * (1 + 1e-12) + 1e-30, axis=1)
    q = sol.q.reshape(B, n, -1)[np.arange(B), best]
    return Solution(q, f[np.arange(B), best], sol.iterations.reshape(B, n).sum(axis=1))
