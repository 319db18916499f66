"""Match detected calibration-grid blobs to the points of a square grid of known pitch.

A flat grid seen by a camera maps to the image by a homography ``H`` (lattice index ``(i, j)`` →
pixels). :func:`match_grid` grows that map from the blob nearest the middle of the image: its two
shortest non-parallel neighbour vectors give an affine start, then every blob within a growing
lattice radius whose back-projection ``H⁻¹ x`` is within ``tol`` of an integer lattice point is
accepted and ``H`` is refitted (normalised DLT, least squares) until nothing changes.

The lattice numbering is relative to the seed blob and its axes are arbitrary (signs, order), so
two **reference discs** fix it, as the thesis operator numbered the grid points on the film: grid
point ``(X, Y)`` appears near pixel ``(u, v)``. The lattice symmetry (one of the 8 signed axis
permutations) that maps the references' lattice step onto their grid step is the numbering; when
both references lie on one grid line, two symmetries fit and handedness decides: seen from the
+Z side (the camera side of a right-handed X, Y, Z), +X turns to +Y clockwise in the y-down image.
(An automatic corner rule was tried first: on the thesis camera the grid's corner disc is in view
but only one of its edges can be shown to be an edge, the other runs along the image border.)
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial import cKDTree

from .errors import GridMatchError

__all__ = ["GridMatch", "match_grid"]

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class GridMatch:
    """Result of :func:`match_grid`.

    Attributes
    ----------
    image_xy : (N, 2) px, the matched blobs.
    plane_xy : (N, 2) mm, their grid points (X, Y on the grid plane).
    lattice : (N, 2) int, grid indices ``round((X, Y) / pitch)``.
    blob_index : (N,) int, row of each match in the input blobs.
    homography : (3, 3) plane mm → image px.
    residual : (N,) px, distance of each blob from its grid point mapped by ``homography``.
    """

    image_xy: FloatArray
    plane_xy: FloatArray
    lattice: NDArray[np.int64]
    blob_index: NDArray[np.int64]
    homography: FloatArray
    residual: FloatArray


def _apply(H: FloatArray, p: FloatArray) -> FloatArray:
    q = np.c_[p, np.ones(len(p))] @ H.T
    return q[:, :2] / q[:, 2:]


def _homography(src: FloatArray, dst: FloatArray) -> FloatArray:
    """Least-squares homography src → dst by the normalised DLT in float64 (``cv2.findHomography``
    works in single precision here: ~1e-5 px on exact data)."""
    def norm(p: FloatArray) -> FloatArray:
        m, s = p.mean(axis=0), np.sqrt(2.0) / max(np.linalg.norm(p - p.mean(axis=0), axis=1).mean(), 1e-300)
        return np.array([[s, 0.0, -s * m[0]], [0.0, s, -s * m[1]], [0.0, 0.0, 1.0]])

    Ts, Td = norm(src), norm(dst)
    a = np.c_[src, np.ones(len(src))] @ Ts.T
    b = np.c_[dst, np.ones(len(dst))] @ Td.T
    A = np.zeros((2 * len(a), 9))
    A[0::2, 0:3], A[0::2, 6:9] = a, -b[:, :1] * a
    A[1::2, 3:6], A[1::2, 6:9] = a, -b[:, 1:2] * a
    Hn = np.linalg.svd(A, full_matrices=False)[2][-1].reshape(3, 3)
    H = np.linalg.inv(Td) @ Hn @ Ts
    return H / H[2, 2]


def _seed(xy: FloatArray, tree: cKDTree) -> tuple[int, FloatArray, FloatArray]:
    """Blob nearest the middle and its two shortest non-parallel neighbour vectors."""
    s = int(tree.query(np.median(xy, axis=0))[1])
    _, nb = tree.query(xy[s], k=min(9, len(xy)))
    vecs = xy[nb[1:]] - xy[s]
    a = vecs[0]
    for b in vecs[1:]:
        if abs(a[0] * b[1] - a[1] * b[0]) > 0.5 * np.linalg.norm(a) * np.linalg.norm(b):
            return s, a, b
    raise GridMatchError("the blobs do not form a 2-D grid around the middle of the image (all neighbours "
                         "are on one line); check the calibration frame and the detection threshold")


def _grow(xy: FloatArray, tol: float) -> tuple[NDArray[np.int64], NDArray[np.int64], FloatArray]:
    """Lattice indices of the accepted blobs, their rows, and ``H`` (lattice → px)."""
    tree = cKDTree(xy)
    s, a, b = _seed(xy, tree)
    H = np.array([[a[0], b[0], xy[s, 0]], [a[1], b[1], xy[s, 1]], [0.0, 0.0, 1.0]])
    radius, accepted = 2.5, np.zeros(0, np.int64)
    for _ in range(60):
        lat = _apply(np.linalg.inv(H), xy)
        ij = np.round(lat)
        ok = (np.linalg.norm(lat - ij, axis=1) < tol) & (np.abs(ij).max(axis=1) <= radius)
        rows = np.flatnonzero(ok)
        keys = ij[rows].astype(np.int64)
        _, first, counts = np.unique(keys, axis=0, return_index=True, return_counts=True)
        rows = rows[np.sort(first[counts == 1])]            # a lattice point claimed twice is dropped
        if len(rows) >= 4:
            H = _homography(ij[rows], xy[rows])
        done = radius > np.abs(ij).max() and np.array_equal(rows, accepted)
        accepted = rows
        if done:
            break
        radius *= 1.5
    lat = np.round(_apply(np.linalg.inv(H), xy[accepted])).astype(np.int64)
    return lat, accepted, H


def _symmetries() -> list[NDArray[np.int64]]:
    """The 8 signed permutation matrices of the square lattice."""
    out = []
    for perm in ((0, 1), (1, 0)):
        for sx in (1, -1):
            for sy in (1, -1):
                m = np.zeros((2, 2), np.int64)
                m[0, perm[0]], m[1, perm[1]] = sx, sy
                out.append(m)
    return out


def match_grid(xy: ArrayLike, pitch: float, references: ArrayLike, *, tol: float = 0.25,
               min_points: int = 12) -> GridMatch:
    """Match blobs of one calibration frame to the grid points.

    Parameters
    ----------
    xy : (K, 2) px, detected blob centres (NaN rows ignored).
    pitch : grid pitch, mm.
    references : (2, 4) ``X, Y, u, v`` of two grid discs identified on the frame: grid point
        (X, Y) mm appears near pixel (u, v) (within a third of the local pitch). Two discs not on
        one grid line fix the numbering alone; two on one line need the handedness rule.
    tol : largest distance of a blob from its lattice point, in pitches.
    min_points : fewest matches accepted.

    Returns
    -------
    GridMatch

    Raises
    ------
    GridMatchError
        Too few blobs or matches, a reference not near a matched blob, or references that
        contradict the grid (the message says which and what to do).

    Examples
    --------
    >>> i, j = np.meshgrid(np.arange(6), np.arange(5), indexing="ij")
    >>> plane = np.c_[i.ravel(), j.ravel()] * 60.0 - [120.0, 0.0]
    >>> H = np.array([[0.5, 0.05, 100.0], [0.02, -0.45, 300.0], [1e-4, 2e-4, 1.0]])
    >>> img = np.c_[plane, np.ones(30)] @ H.T; img = img[:, :2] / img[:, 2:]
    >>> refs = [[-120.0, 0.0, *img[0].round()], [60.0, 60.0, *img[16].round()]]
    >>> m = match_grid(img[::-1], 60.0, refs)
    >>> len(m.plane_xy), bool(np.allclose(m.plane_xy, plane[::-1][m.blob_index]))
    (30, True)
    """
    p = np.asarray(xy, float).reshape(-1, 2)
    refs = np.asarray(references, float)
    if refs.shape != (2, 4) or not np.all(np.isfinite(refs)):
        raise GridMatchError(f"references must be two rows X, Y, u, v (mm, mm, px, px), got shape {refs.shape}")
    rows0 = np.flatnonzero(np.all(np.isfinite(p), axis=1))
    if len(rows0) < min_points:
        raise GridMatchError(f"only {len(rows0)} blob{'s' * (len(rows0) != 1)} detected in the calibration frame (need at least "
                             f"{min_points}); check that the grid frame was recorded and the detection threshold")
    lat, acc, H = _grow(p[rows0], tol)
    if len(acc) < min_points:
        raise GridMatchError(f"only {len(acc)} blob{'s' * (len(acc) != 1)} fit one grid (need at least {min_points}); "
                             "the blobs may not be a square grid, or lens distortion is too strong for a homography")
    image = p[rows0[acc]]
    ref_lat = []
    for k, (X, Y, u, v) in enumerate(refs):
        d = np.linalg.norm(image - [u, v], axis=1)
        n = int(np.argmin(d))
        step = np.linalg.norm(_apply(H, lat[n:n + 1] + [[1.0, 0.0]]) - image[n])
        if d[n] > step / 3:
            raise GridMatchError(f"reference {k} (grid point {X:g}, {Y:g} mm near pixel {u:g}, {v:g}): the "
                                 f"nearest matched disc is {d[n]:.1f} px away (pitch {step:.1f} px); give its pixel "
                                 "position within a third of the pitch")
        ref_lat.append(lat[n])
    dl = ref_lat[1] - ref_lat[0]
    dw = (refs[1, :2] - refs[0, :2]) / float(pitch)
    if not np.allclose(dw, np.round(dw), atol=1e-6) or not np.any(dl):
        raise GridMatchError("the two references must be different grid points, a whole number of pitches "
                             f"apart; got {refs[0, :2].tolist()} and {refs[1, :2].tolist()} mm")
    fits = [m for m in _symmetries() if np.array_equal(m @ dl, np.round(dw).astype(np.int64))]
    if len(fits) > 1:   # references on one grid line: keep the right-handed numbering
        fits = [m for m in fits if _right_handed(H, m)]
    if len(fits) != 1:
        raise GridMatchError(f"the references do not fit the grid: they are {dl.tolist()} lattice steps apart in "
                             f"the image but {np.round(dw).astype(int).tolist()} pitches apart on the grid; "
                             "check their pixel positions")
    lattice = (lat - ref_lat[0]) @ fits[0].T + np.round(refs[0, :2] / float(pitch)).astype(np.int64)
    plane = lattice * float(pitch) + (refs[0, :2] - np.round(refs[0, :2] / float(pitch)) * float(pitch))
    Hp = _homography(plane, image)
    residual = np.linalg.norm(_apply(Hp, plane) - image, axis=1)
    return GridMatch(image, plane, lattice.astype(np.int64), rows0[acc].astype(np.int64), Hp, residual)


def _right_handed(H: FloatArray, m: NDArray[np.int64]) -> bool:
    """Whether lattice symmetry ``m`` makes +X turn to +Y clockwise in the y-down image (camera on +Z)."""
    inv = np.linalg.inv(m)
    o = _apply(H, np.zeros((1, 2)))[0]
    ex = _apply(H, inv[:, :1].T.astype(float))[0] - o
    ey = _apply(H, inv[:, 1:].T.astype(float))[0] - o
    return bool(ex[0] * ey[1] - ex[1] * ey[0] < 0)
