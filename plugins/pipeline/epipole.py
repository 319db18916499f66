"""The mirror epipole estimated from unpaired direct and mirror images (no geometry needed).

Every marker's direct image ``p`` and mirror image ``q`` lie on a line through the mirror epipole
``e`` (:mod:`mirrorlab.plugins.pairing.epipole`), in every frame. Before the mirror normal is
known, the pairs are not: :func:`estimate_epipole` takes, frame by frame, the lines through every
direct/mirror combination, intersects lines of different frames to propose epipoles (RANSAC with
a fixed seed), keeps the proposal that the most combinations pass within ``tol`` of (symmetric
epipolar distance, as :func:`mirrorlab.plugins.pairing.epipolar_distance`), and refines it by least
squares on those inliers. Wrong combinations change direction from frame to frame and do not meet
in one point; true pairs all do. The sign of the homogeneous result follows the ordering rule of
the pairing module: ``e[2] > 0`` when the mirror images lie between the direct images and ``e``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .errors import EpipoleError

__all__ = ["EpipoleEstimate", "estimate_epipole"]

FloatArray = NDArray[np.float64]

#: distances (candidates x combinations) scored at once: a chunk makes about a dozen float64 temporaries of 8 MB
_SCORE_BLOCK = 1 << 20


@dataclass(frozen=True)
class EpipoleEstimate:
    """Result of :func:`estimate_epipole`.

    Attributes
    ----------
    epipole : (3,) homogeneous px, unit length, sign as in ``mirror_epipole``.
    inliers : number of direct/mirror combinations within ``tol`` of it.
    rms : RMS symmetric epipolar distance of the inliers, px.
    """

    epipole: FloatArray
    inliers: int
    rms: float


def _combinations(real: FloatArray, virtual: FloatArray) -> tuple[FloatArray, FloatArray, NDArray[np.int64]]:
    F, N, M = real.shape[0], real.shape[1], virtual.shape[1]
    p = np.broadcast_to(real[:, :, None, :], (F, N, M, 2))
    q = np.broadcast_to(virtual[:, None, :, :], (F, N, M, 2))
    frame = np.broadcast_to(np.arange(F)[:, None, None], (F, N, M))
    ok = np.all(np.isfinite(p), axis=3) & np.all(np.isfinite(q), axis=3)
    ok &= np.any(p != q, axis=3)           # a detection listed in both roles is not a pair
    return p[ok], q[ok], frame[ok]


def _distance(p: FloatArray, q: FloatArray, e: FloatArray) -> FloatArray:
    """(C, Q) symmetric epipolar distance of combinations (Q,) for candidate epipoles e (C, 3)."""
    ph, qh = np.c_[p, np.ones(len(p))], np.c_[q, np.ones(len(q))]
    lp = np.cross(ph[None], e[:, None])            # (C, Q, 3) lines p-e
    lq = np.cross(qh[None], e[:, None])
    det = np.abs(np.einsum("cqk,qk->cq", lp, qh))
    with np.errstate(divide="ignore", invalid="ignore"):
        d = 0.5 * det * (1.0 / np.hypot(lp[..., 0], lp[..., 1]) + 1.0 / np.hypot(lq[..., 0], lq[..., 1]))
    return np.nan_to_num(d, nan=np.inf)


def estimate_epipole(real: ArrayLike, virtual: ArrayLike, *, tol: float = 1.0, samples: int = 2000,
                     seed: int = 0) -> EpipoleEstimate:
    """Mirror epipole from direct images (F, N, 2) and mirror images (F, M, 2) of the same frames.

    Parameters
    ----------
    real, virtual : px, NaN-padded; pairs unknown.
    tol : inlier distance, px.
    samples : RANSAC proposals (pairs of lines from different frames).
    seed : random seed of the proposals (results are reproducible).

    Raises
    ------
    EpipoleError
        Fewer than two frames with both kinds of image, or no proposal supported by combinations
        of at least two frames.

    Examples
    --------
    >>> e = np.array([400.0, -300.0])
    >>> rng = np.random.default_rng(1)
    >>> p = rng.uniform(0, 300, (6, 2, 2)); q = p + 0.3 * (e - p)
    >>> est = estimate_epipole(p, q[:, ::-1])
    >>> (est.epipole[:2] / est.epipole[2]).round(6).tolist(), est.inliers
    ([400.0, -300.0], 12)
    """
    r, v = np.asarray(real, float), np.asarray(virtual, float)
    if r.ndim != 3 or v.ndim != 3 or r.shape[2] != 2 or v.shape[2] != 2 or len(r) != len(v):
        raise EpipoleError(f"real and virtual must be (F, N, 2) and (F, M, 2) px with the same F, got "
                           f"{r.shape} and {v.shape}")
    p, q, frame = _combinations(r, v)
    if len(np.unique(frame)) < 2:
        raise EpipoleError("need direct and mirror images in at least two frames to find the mirror epipole; "
                           "check the mirror outline (split_views) and the detections")
    lines = np.cross(np.c_[p, np.ones(len(p))], np.c_[q, np.ones(len(q))])
    lines /= np.hypot(lines[:, 0], lines[:, 1])[:, None]
    rng = np.random.default_rng(seed)
    a, b = rng.integers(0, len(lines), (2, samples))
    keep = frame[a] != frame[b]
    cand = np.cross(lines[a[keep]], lines[b[keep]])
    cand = cand[np.linalg.norm(cand, axis=1) > 0]
    if len(cand) == 0:
        raise EpipoleError("every direct/mirror line is parallel to the others; cannot locate the epipole")
    cand /= np.linalg.norm(cand, axis=1)[:, None]
    best = None
    # candidates scored in chunks of about _SCORE_BLOCK distances: memory stays bounded however many frames
    per_chunk = max(1, _SCORE_BLOCK // len(p))
    for chunk in np.array_split(cand, max(1, -(-len(cand) // per_chunk))):
        count = (_distance(p, q, chunk) < tol).sum(axis=1)
        i = int(np.argmax(count))
        if best is None or count[i] > best[0]:
            best = (int(count[i]), chunk[i])
    assert best is not None
    e = best[1]
    for _ in range(3):                        # refine: least-squares point of the inlier lines
        inl = _distance(p, q, e[None])[0] < tol
        if inl.sum() < 2:
            break
        e = np.linalg.svd(lines[inl], full_matrices=False)[2][-1]  # thin: (n, 3) in, no n x n factor
    d = _distance(p, q, e[None])[0]
    inl = d < tol
    if len(np.unique(frame[inl])) < 2:
        raise EpipoleError(f"no mirror epipole is supported by pairs of two frames within {tol:g} px; "
                           "raise tol, or check that the mirror images were split from the direct ones")
    # sign: e[2] > 0 when q lies between p and e (direction (q - p) . (e_xy - e2 p) > 0)
    s = np.einsum("qk,qk->q", q[inl] - p[inl], e[None, :2] - e[2] * p[inl])
    if np.sum(s > 0) < np.sum(s < 0):
        e = -e
    return EpipoleEstimate(e / np.linalg.norm(e), int(inl.sum()), float(np.sqrt(np.mean(d[inl] ** 2))))
