"""How far a retargeting solver's stopped result may be from the exact optimum (for the tests).

The solvers stop on their own tolerances (``levenberg_marquardt``: an accepted step lowers f by at
most ``ftol · f`` or moves q by less than ``xtol``; ``paper_sweeps``: a sweep lowers f by at most
``ftol · f``). Near a strict minimum f - f* ≈ ½ δqᵀ H δq, so

* f is above f* by at most what the remaining iterations could still gain: both solvers converge
  linearly at a nonzero residual (Gauss-Newton / LM with rate ρ = spectral radius of
  I - (2JᵀJ)⁻¹H; Gauss-Seidel sweeps with that of their splitting of H), so at most
  ``ftol · f · max(1, ρ / (1 - ρ))``, plus the rounding of f;
* q is off by at most ``sqrt(2 (f - f*) / λ_min(H))`` (or LM's ``xtol``, whichever stop fired).

Where the minimum is degenerate (λ_min <= 0) or the iteration does not contract there (ρ >= 1),
no such bound exists and the bound returned is infinite.

H is the Hessian of f at the result (central differences of the analytic gradient), so the bound
carries the conditioning of each frame's problem.
"""

from __future__ import annotations

import inspect
from typing import NamedTuple

import numpy as np
from mirrorlab.plugins.retarget import Objective
from mirrorlab.plugins.retarget.solvers import levenberg_marquardt, paper_sweeps

from tests.tolerances import roundoff

#: The solvers' own stopping tolerances (their defaults, as the code under test uses them).
LM_FTOL = inspect.signature(levenberg_marquardt).parameters["ftol"].default
LM_XTOL = inspect.signature(levenberg_marquardt).parameters["xtol"].default
SWEEP_FTOL = inspect.signature(paper_sweeps).parameters["ftol"].default
#: The solvers' default output base (identity rotation at the origin).
BASE_R, BASE_P = np.eye(3), np.zeros(3)


class OptimumBounds(NamedTuple):
    """Per row: f - f* <= ``f`` (mm²), |q - q*| <= ``q`` (rad), |joint - joint*| <= ``joints`` (mm)."""

    f: np.ndarray
    q: np.ndarray
    joints: np.ndarray


def _gradient(obj: Objective, q: np.ndarray, arms: object, R_b: np.ndarray, p_b: np.ndarray) -> np.ndarray:
    r, J, _ = obj.residuals_jacobian(q, arms, R_b, p_b)
    return 2.0 * np.einsum("bpi,bpij->bj", r, J)


def optimum_bounds(obj: Objective, q: np.ndarray, arms: object, R_b: np.ndarray = BASE_R,
                   p_b: np.ndarray = BASE_P, method: str = "lm") -> OptimumBounds:
    """Bounds on the distance of solver results ``q`` (B, dof) from the exact local minima nearby.

    Parameters
    ----------
    obj, arms, R_b, p_b
        The problem, as given to the solver.
    q : ndarray (B, dof)
        The solver's result per row (rad).
    method : {"lm", "paper"}
        Which solver stopped there (LM's or the sweeps' stopping rule).
    """
    q = np.atleast_2d(np.asarray(q, dtype=float))
    B, m = q.shape
    r, J, pos = obj.residuals_jacobian(q, arms, R_b, p_b)
    f = np.einsum("bpi,bpi->b", r, r)
    h = 1e-6                                                              # rad: O(h²) curvature error
    H = np.stack([(_gradient(obj, q + h * e, arms, R_b, p_b) - _gradient(obj, q - h * e, arms, R_b, p_b)) / (2 * h)
                  for e in np.eye(m)], axis=1)
    H = (H + np.swapaxes(H, 1, 2)) / 2
    lam_min = np.linalg.eigvalsh(H)[:, 0]
    # f = Σ |r|²: each residual component is a difference of positions up to |pos|, so it rounds by
    # ~eps |pos| and f by 2 |r| that, over the P pairs (plus the sum's own rounding)
    size = np.abs(pos).max(axis=(1, 2))
    n_pairs = r.shape[1]
    df_round = np.array([roundoff(scale=2 * np.sqrt(fb * n_pairs) * sb + fb, ops=20) for fb, sb in zip(f, size)])
    eye = np.eye(m)
    JtJ = 2 * np.einsum("bpik,bpil->bkl", J, J)
    if method == "lm":
        M, ftol = JtJ, LM_FTOL                                           # Gauss-Newton's splitting of H
    else:
        M, ftol = np.tril(H, -1) + np.diagonal(JtJ, axis1=1, axis2=2)[:, :, None] * eye, SWEEP_FTOL
    with np.errstate(all="ignore"):
        singular = np.linalg.cond(M) > 1 / np.finfo(float).eps              # no Gauss-Newton step there
        rho = np.where(singular, np.inf, np.abs(np.linalg.eigvals(eye - np.linalg.pinv(M) @ H)).max(axis=1))
        f_gap = np.where(rho < 1, ftol * f * np.maximum(1.0, rho / (1 - rho)), np.inf) + df_round
        q_gap = np.where(lam_min > 0, np.sqrt(2 * f_gap / lam_min), np.inf)
    if method == "lm":
        q_gap = np.maximum(q_gap, LM_XTOL)
    # a joint moves by at most the distance to it along the chain per radian of any angle
    reach = np.linalg.norm(pos - pos[:, :1], axis=-1).max(axis=1)
    return OptimumBounds(f_gap, q_gap, reach * np.sqrt(m) * q_gap + roundoff(scale=1.0, ops=20) * size)
