"""Pair each marker's image with its mirror image(s) by the mirror-epipole constraint.

For one plane mirror, a marker's image ``p`` and its mirror image ``q`` lie on a line through the
mirror epipole ``e`` (:func:`~mirrorlab.plugins.pairing.epipole.mirror_epipole`), and along that
line the mirror image always lies on the same side: between ``p`` and ``e`` when the virtual camera
is in front of the camera (``e[2] > 0``), beyond ``p`` away from ``e`` when it is behind. So a
candidate pair ``(p, q)`` is feasible when

* its **epipolar distance** — the mean of the distance of ``q`` from the line ``p e`` and of ``p``
  from the line ``q e`` (px; well defined also for a distant or infinite epipole, where the
  distance of the line ``p q`` from ``e`` itself would blow up) — is at most ``tol``, and
* the **ordering** holds.

The pairs minimise the summed cost (epipolar distance, plus a continuity term when the previous
frame's pairs are given) over all one-to-one assignments with the largest number of pairs
(``scipy.optimize.linear_sum_assignment`` with infeasible entries priced out). Several mirrors
are handled together: every real marker has one row per mirror, so it can pair with one image in
each mirror, and each mirror-image detection is used once.

Ambiguity is reported, never guessed: a pair of the optimum is *ambiguous* when forbidding it
still leaves an assignment with as many pairs whose cost is within ``margin`` of the optimum (e.g.
two markers on one epipolar line, ordered so that either pairing fits). Ambiguous pairs are left
out of ``pairs`` and listed with their candidates. Pairs forced by the constraints (the other
candidate is needed elsewhere, or the ordering excludes it) are not ambiguous.

Limits. Whenever another marker lies within ``tol`` of a marker's epipolar line, all four images lie
on (nearly) one line and a single frame cannot tell the two pairings apart: with 25 markers spread
over a 600 × 400 px region and one mirror, about 3 % of the pairs are reported ambiguous at
``tol = 0.5`` px (more with several mirrors and unlabelled mirror images). Continuity with the
previous frame and ``virtual_mirror`` labels resolve most of them. A marker whose own mirror image is
missing (occluded, outside the mirror) can take a detection that happens to lie on its line;
nothing in one frame reveals that.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import linear_sum_assignment

from .errors import InvalidPairingInput

FloatArray = NDArray[np.float64]
_BIG = 1e9


@dataclass(frozen=True)
class AmbiguousPair:
    """A real marker whose mirror image in ``mirror`` cannot be decided among ``candidates``."""

    real: int
    mirror: int
    candidates: tuple[int, ...]


@dataclass(frozen=True)
class MirrorPairs:
    """Result of :func:`pair_mirror`.

    Attributes
    ----------
    pairs : (P, 3) int — ``real index, virtual index, mirror index`` of every decided pair.
    cost : (P,) float, px — epipolar distance of each pair.
    ambiguous : tuple of :class:`AmbiguousPair` — undecided real markers (not in ``pairs``).
    unpaired_real : (.,) int — real markers with no decided image in any mirror.
    unpaired_virtual : (.,) int — mirror-image detections left unexplained (or ambiguous).
    """

    pairs: NDArray[np.int64]
    cost: FloatArray
    ambiguous: tuple[AmbiguousPair, ...]
    unpaired_real: NDArray[np.int64]
    unpaired_virtual: NDArray[np.int64]

    def virtual_index(self, n_real: int, n_mirrors: int) -> NDArray[np.int64]:
        """(n_real, n_mirrors) index of each real marker's image per mirror, −1 where none.

        Examples
        --------
        >>> r = MirrorPairs(np.array([[1, 0, 0]]), np.zeros(1), (), np.array([0]), np.zeros(0, int))
        >>> r.virtual_index(2, 1).tolist()
        [[-1], [0]]
        """
        out = np.full((n_real, n_mirrors), -1, np.int64)
        out[self.pairs[:, 0], self.pairs[:, 2]] = self.pairs[:, 1]
        return out


def _points(xy: ArrayLike, name: str) -> FloatArray:
    a = np.asarray(xy, float)
    if a.ndim != 2 or a.shape[1] != 2:
        raise InvalidPairingInput(f"{name} must have shape (K, 2) pixels, got {a.shape}")
    if not np.all(np.isfinite(a)):
        bad = np.flatnonzero(~np.all(np.isfinite(a), axis=1))
        raise InvalidPairingInput(f"{name}: rows {bad[:8].tolist()} are not finite; drop missing detections first")
    return a


def _epipoles(epipoles: ArrayLike) -> FloatArray:
    e = np.asarray(epipoles, float)
    if e.ndim == 1:
        e = e[None]
    if e.ndim != 2 or e.shape[1] not in (2, 3) or not np.all(np.isfinite(e)):
        raise InvalidPairingInput(f"epipoles must be finite (E, 3) homogeneous or (E, 2) pixel points, got {e.shape}")
    if e.shape[1] == 2:
        e = np.c_[e, np.ones(len(e))]
    if np.any(np.all(e == 0, axis=1)):
        raise InvalidPairingInput("an epipole is (0, 0, 0); compute it with mirror_epipole()")
    return e


def epipolar_distance(real_xy: ArrayLike, virtual_xy: ArrayLike, epipole: ArrayLike) -> FloatArray:
    """(N, M) symmetric epipolar distance (px) of every real/virtual combination for one epipole.

    Examples
    --------
    >>> epipolar_distance([[0., 0.]], [[5., 1.], [5., 0.]], [10., 0., 1.]).round(6).tolist()
    [[1.480581, 0.0]]
    """
    p, q, e = _points(real_xy, "real_xy"), _points(virtual_xy, "virtual_xy"), _epipoles(epipole)[0]
    ph, qh = np.c_[p, np.ones(len(p))], np.c_[q, np.ones(len(q))]
    lp, lq = np.cross(ph, e), np.cross(qh, e)  # lines p-e and q-e
    det = np.abs(lp @ qh.T)
    with np.errstate(divide="ignore"):
        inv_p = 1.0 / np.hypot(lp[:, 0], lp[:, 1])
        inv_q = 1.0 / np.hypot(lq[:, 0], lq[:, 1])
    return 0.5 * det * (inv_p[:, None] + inv_q[None, :])


def ordering_ok(real_xy: ArrayLike, virtual_xy: ArrayLike, epipole: ArrayLike) -> NDArray[np.bool_]:
    """(N, M) True where the mirror image lies on the correct side of the real image (module notes).

    Examples
    --------
    >>> ordering_ok([[0., 0.]], [[5., 0.], [-5., 0.], [20., 0.]], [10., 0., 1.]).tolist()
    [[True, False, False]]
    """
    p, q, e = _points(real_xy, "real_xy"), _points(virtual_xy, "virtual_xy"), _epipoles(epipole)[0]
    v = e[None, :2] - e[2] * p  # (N, 2), direction toward the epipole times e2
    s = np.einsum("nmk,nk->nm", q[None, :, :] - p[:, None, :], v)
    ok = s > 0
    if e[2] > 0:
        ok &= s < (np.einsum("nk,nk->n", v, v) / e[2])[:, None]
    return ok


def _solve(cost: FloatArray) -> tuple[NDArray, NDArray, float]:
    r, c = linear_sum_assignment(cost)
    ok = cost[r, c] < _BIG
    return r[ok], c[ok], float(cost[r[ok], c[ok]].sum())


def pair_mirror(real_xy: ArrayLike, virtual_xy: ArrayLike, epipoles: ArrayLike, *, tol: float = 2.0,
                virtual_mirror: ArrayLike | None = None, previous: tuple[ArrayLike, ArrayLike, ArrayLike] | None = None,
                motion_gate: float = 20.0, margin: float | None = None) -> MirrorPairs:
    """Pair real marker images with their mirror images in one or several plane mirrors.

    Parameters
    ----------
    real_xy : (N, 2) px — images of the markers seen directly (undistorted pixels, see
        :func:`~mirrorlab.plugins.pairing.epipole.undistort_points`).
    virtual_xy : (M, 2) px — mirror-image detections (undistorted).
    epipoles : (E, 3) homogeneous (sign kept, from ``mirror_epipole``) or (E, 2) finite pixels
        (then taken as in front of the camera), one per mirror.
    tol : px — largest accepted epipolar distance.
    virtual_mirror : optional (M,) int — mirror of each virtual detection when known (e.g. from the
        mirror's image region), −1 when unknown.
    previous : optional ``(real_xy, virtual_xy, mirror)`` of the previous frame's pairs, shapes
        (P, 2), (P, 2), (P,): a candidate that continues one of them within ``motion_gate`` px is
        preferred (continuity term ``tol · min(motion / motion_gate, 1)`` added to its cost).
    motion_gate : px — largest image motion between frames for the continuity term.
    margin : px — an alternative assignment within this much of the optimum makes a pair
        ambiguous (default ``tol``).

    Returns
    -------
    MirrorPairs

    Examples
    --------
    >>> r = pair_mirror([[0., 0.], [0., 10.]], [[5., 5.2], [5., 0.1]], [[10., 0., 1.], ])
    >>> r.pairs.tolist(), r.ambiguous          # rows: real, virtual, mirror
    ([[0, 1, 0], [1, 0, 0]], ())
    """
    p, q, e = _points(real_xy, "real_xy"), _points(virtual_xy, "virtual_xy"), _epipoles(epipoles)
    if tol <= 0 or motion_gate <= 0:
        raise InvalidPairingInput(f"tol and motion_gate must be positive, got tol={tol}, motion_gate={motion_gate}")
    margin = tol if margin is None else float(margin)
    n, m, ne = len(p), len(q), len(e)
    vm = np.full(m, -1) if virtual_mirror is None else np.asarray(virtual_mirror, int).reshape(-1)
    if vm.shape != (m,) or np.any((vm < -1) | (vm >= ne)):
        raise InvalidPairingInput(f"virtual_mirror must hold {m} mirror indices in -1…{ne - 1}, got {vm!r}")
    if n == 0 or m == 0:
        return MirrorPairs(np.zeros((0, 3), np.int64), np.zeros(0), (), np.arange(n), np.arange(m))
    dist = np.empty((n, ne, m))
    cost = np.full((n, ne, m), _BIG)
    for k in range(ne):
        dist[:, k] = epipolar_distance(p, q, e[k])
        feasible = (dist[:, k] <= tol) & ordering_ok(p, q, e[k]) & ((vm == -1) | (vm == k))[None, :]
        cost[:, k][feasible] = dist[:, k][feasible]
    if previous is not None:
        pr, pv, pm = (np.asarray(a, float) for a in previous)
        pr, pv, pm = pr.reshape(-1, 2), pv.reshape(-1, 2), pm.reshape(-1).astype(int)
        for k in range(ne):
            sel = pm == k
            if not sel.any():
                continue
            dr = np.linalg.norm(p[:, None, :] - pr[None, sel, :], axis=2)  # (n, P)
            dv = np.linalg.norm(q[:, None, :] - pv[None, sel, :], axis=2)  # (m, P)
            motion = np.maximum(dr[:, None, :], dv[None, :, :]).min(axis=2)  # (n, m)
            ok = cost[:, k] < _BIG
            cost[:, k][ok] += tol * np.minimum(motion[ok] / motion_gate, 1.0)
    flat = cost.reshape(n * ne, m)
    rows, cols, total = _solve(flat)
    feasible = flat < _BIG
    deg_r, deg_c = feasible.sum(1), feasible.sum(0)
    decided, ambiguous = [], []
    for r, c in zip(rows, cols, strict=False):
        if deg_r[r] > 1 or deg_c[c] > 1:
            trial = flat.copy()
            trial[r, c] = _BIG
            r2, _, total2 = _solve(trial)
            if len(r2) == len(rows) and total2 - total <= margin:
                i, k = divmod(int(r), ne)
                cands = np.flatnonzero(feasible[r])
                ambiguous.append(AmbiguousPair(i, k, tuple(int(x) for x in cands)))
                continue
        decided.append((r, c))
    if decided:
        dr_, dc_ = np.array(decided).T
        pairs = np.c_[dr_ // ne, dc_, dr_ % ne].astype(np.int64)
        pcost = dist.reshape(n * ne, m)[dr_, dc_]
    else:
        pairs, pcost = np.zeros((0, 3), np.int64), np.zeros(0)
    order = np.lexsort((pairs[:, 2], pairs[:, 0]))
    pairs, pcost = pairs[order], pcost[order]
    unpaired_real = np.setdiff1d(np.arange(n), pairs[:, 0]).astype(np.int64)
    unpaired_virtual = np.setdiff1d(np.arange(m), pairs[:, 1]).astype(np.int64)
    return MirrorPairs(pairs, pcost, tuple(ambiguous), unpaired_real, unpaired_virtual)
