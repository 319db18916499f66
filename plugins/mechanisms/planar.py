"""Planar geometry of rigid links: circle fits, 2-D poses, poles and circumcentres.

Units: mm and rad; positions are ``(..., 2)`` arrays, NaN where missing.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .errors import DegenerateGeometry

__all__ = ["apply_pose", "circumcentre", "common_centre", "pole", "pose2d", "rotation2d", "to_body"]

FloatArray = NDArray[np.float64]


def rotation2d(angle: ArrayLike) -> FloatArray:
    """Rotation matrices ``(..., 2, 2)`` for angles (rad)."""
    a = np.asarray(angle, dtype=float)
    c, s = np.cos(a), np.sin(a)
    return np.stack([np.stack([c, -s], -1), np.stack([s, c], -1)], -2)


def common_centre(points: ArrayLike) -> tuple[FloatArray, FloatArray, float]:
    """Least-squares centre shared by several markers each moving on its own circle.

    Algebraic (Kasa) fit: ``|p|^2 = 2 c . p + k_m`` for every sample of marker ``m``, linear in
    the centre ``c`` and ``k_m = r_m^2 - |c|^2``; one marker gives the ordinary circle fit.

    Parameters
    ----------
    points : (T, m, 2) or (T, 2) positions, mm, NaN where missing.

    Returns
    -------
    centre : (2,) mm.
    radii : (m,) mm.
    rms : RMS of ``|p - c| - r_m`` over all samples, mm.

    Raises
    ------
    DegenerateGeometry
        Fewer than 3 samples, or the samples lie on a line (no curvature to fit).

    Examples
    --------
    >>> a = np.linspace(0, 2, 9)
    >>> p = np.stack([np.stack([1 + 5 * np.cos(a), 2 + 5 * np.sin(a)], -1),
    ...               np.stack([1 + 3 * np.cos(a + 1), 2 + 3 * np.sin(a + 1)], -1)], 1)
    >>> c, r, rms = common_centre(p)
    >>> c.round(9).tolist(), r.round(9).tolist(), rms < 1e-9
    ([1.0, 2.0], [5.0, 3.0], True)
    """
    p = np.asarray(points, dtype=float)
    if p.ndim == 2:
        p = p[:, None]
    T, m, _ = p.shape
    ok = np.isfinite(p).all(-1)
    if ok.sum() < 3 or (ok.sum(0) < 1).any():
        raise DegenerateGeometry(f"a circle fit needs at least 3 samples and each marker seen once; got {ok.sum(0)}")
    rows, rhs = [], []
    for j in range(m):
        q = p[ok[:, j], j]
        onehot = np.zeros((len(q), m))
        onehot[:, j] = 1.0
        rows.append(np.hstack([2.0 * q, onehot]))
        rhs.append(np.sum(q**2, -1))
    A, b = np.vstack(rows), np.concatenate(rhs)
    scale = np.abs(A[:, :2]).max() or 1.0
    A[:, :2] /= scale
    sol, _, rank, sv = np.linalg.lstsq(A, b, rcond=None)
    if rank < m + 2 or sv[-1] < 1e-10 * sv[0]:
        raise DegenerateGeometry("the samples lie on a straight line (or one point): no circle centre; "
                                 "the link barely rotated over these frames")
    c = sol[:2] / scale
    r2 = sol[2:] + c @ c
    radii = np.sqrt(np.maximum(r2, 0.0))
    resid = np.linalg.norm(p - c, axis=-1) - radii
    return c, radii, float(np.sqrt(np.mean(resid[ok] ** 2)))


def pose2d(reference: ArrayLike, points: ArrayLike) -> tuple[FloatArray, FloatArray]:
    """Least-squares rigid motion per frame: ``points[k] ~ R(angle[k]) @ reference + shift[k]``.

    Closed-form 2-D Procrustes over the markers seen in each frame (at least two).

    Parameters
    ----------
    reference : (m, 2) body coordinates, mm.
    points : (T, m, 2) world positions, mm, NaN where missing.

    Returns
    -------
    angle : (T,) rad, NaN where fewer than two markers are seen.
    shift : (T, 2) mm.

    Examples
    --------
    >>> q = np.array([[0.0, 0.0], [10.0, 0.0], [0.0, 5.0]])
    >>> p = q @ rotation2d(0.3).T + [1.0, 2.0]
    >>> a, t = pose2d(q, p[None])
    >>> round(float(a[0]), 12), t[0].round(12).tolist()
    (0.3, [1.0, 2.0])
    """
    q = np.asarray(reference, dtype=float)
    p = np.asarray(points, dtype=float)
    w = np.isfinite(p).all(-1) & np.isfinite(q).all(-1)[None]
    n = w.sum(1)
    p0 = np.where(w[..., None], p, 0.0)
    q0 = np.where(w[..., None], q[None], 0.0)
    with np.errstate(invalid="ignore", divide="ignore"):
        pc = p0.sum(1) / n[:, None]
        qc = q0.sum(1) / n[:, None]
    dp = np.where(w[..., None], p0 - pc[:, None], 0.0)
    dq = np.where(w[..., None], q0 - qc[:, None], 0.0)
    s = np.sum(dq[..., 0] * dp[..., 1] - dq[..., 1] * dp[..., 0], 1)
    c = np.sum(dq * dp, axis=(1, 2))
    angle = np.where(n >= 2, np.arctan2(s, c), np.nan)
    shift = pc - np.einsum("tij,tj->ti", rotation2d(np.nan_to_num(angle)), qc)
    shift[n < 2] = np.nan
    return angle, shift


def apply_pose(angle: ArrayLike, shift: ArrayLike, body: ArrayLike) -> FloatArray:
    """Body coordinates to world for poses ``(T,)``: ``body`` is ``(T, ..., 2)`` (per frame) mm."""
    b = np.asarray(body, dtype=float)
    R = rotation2d(angle)
    return np.einsum("tij,t...j->t...i", R, b) + np.asarray(shift, float).reshape((R.shape[0],) + (1,) * (b.ndim - 2)
                                                                                  + (2,))


def to_body(angle: ArrayLike, shift: ArrayLike, points: ArrayLike) -> FloatArray:
    """World positions ``(T, ..., 2)`` into body coordinates for poses ``(T,)`` (inverse of the pose)."""
    R = rotation2d(angle)
    p = np.asarray(points, dtype=float)
    extra = p.ndim - 2
    d = p - np.asarray(shift, dtype=float).reshape((R.shape[0],) + (1,) * extra + (2,))
    return np.einsum("tji,t...j->t...i", R, d)


def pole(P1: ArrayLike, P2: ArrayLike, Q1: ArrayLike, Q2: ArrayLike, rcond: float = 1e-6) -> FloatArray:
    """Pole of the finite displacement carrying P1, Q1 to P2, Q2 (``analysis.md`` §4.1).

    The intersection of the perpendicular bisectors of P1P2 and Q1Q2 as a linear solve (the
    thesis's slope-intercept subroutine 7030 fails for horizontal displacements).

    Raises
    ------
    DegenerateGeometry
        The bisectors are (nearly) parallel: a pure translation, or too small a displacement.

    Examples
    --------
    >>> (pole([1, 0], [0, 1], [0, 2], [-2, 0]).round(12) + 0.0).tolist()
    [0.0, 0.0]
    """
    P1, P2, Q1, Q2 = (np.asarray(v, dtype=float) for v in (P1, P2, Q1, Q2))
    A = np.array([P2 - P1, Q2 - Q1])
    b = 0.5 * np.array([P2 @ P2 - P1 @ P1, Q2 @ Q2 - Q1 @ Q1])
    sv = np.linalg.svd(A, compute_uv=False)
    if not np.all(np.isfinite(A)) or sv[-1] <= rcond * max(sv[0], 1e-300):
        raise DegenerateGeometry(f"the displacement has no finite pole (bisectors parallel; singular values "
                                 f"{sv[0]:.3g}, {sv[-1]:.3g}); choose frames further apart")
    return np.linalg.solve(A, b)


def circumcentre(a: ArrayLike, b: ArrayLike, c: ArrayLike) -> FloatArray:
    """Centre of the circle through three points (the pole construction of P→Q→R).

    Examples
    --------
    >>> (circumcentre([3, 2], [2, 3], [1, 2]).round(12) + 0.0).tolist()
    [2.0, 2.0]
    """
    a, b, c = (np.asarray(v, dtype=float) for v in (a, b, c))
    return pole(a, b, b, c)
