"""The camera's projection matrix, a mirror's image outline, and direct/mirror detection split.

A calibrated camera (pinhole, or the thesis plane map with its centre ``F1``) projects a world
point ``X`` along the ray from ``F1``; :func:`camera_projection` returns the 3 x 4 matrix ``P``
that does it (exact for a pinhole without distortion and for a projective plane map without
radial terms, the best linear fit otherwise), with its sign chosen so that points in front of the
camera have ``w > 0``: that is what the mirror epipole's ordering rule needs
(:func:`mirrorlab.plugins.pairing.mirror_epipole`). :func:`mirror_outline` projects the corners of
a mirror's rectangle, and :func:`split_views` lists the detections inside those outlines as
candidate mirror images (a marker standing in front of the mirror is inside the outline too, so
pairing, :func:`~mirrorlab.plugins.pipeline.tracks.assign_views`, makes the final split).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from mirrorlab.plugins.pairing import mirror_of_points
from mirrorlab.plugins.photogrammetry import PinholeCamera
from mirrorlab.plugins.photogrammetry.camera_arrays import camera_from_arrays
from numpy.typing import ArrayLike, NDArray

from .errors import ViewSplitError

__all__ = ["camera_projection", "mirror_outline", "split_views"]

FloatArray = NDArray[np.float64]


def camera_projection(camera: Mapping[str, Any] | Any) -> FloatArray:
    """The 3 x 4 projection matrix (px) of a calibrated camera, ``w > 0`` in front of it.

    Parameters
    ----------
    camera : camera arrays (``camera_matrix``, ``rotation``, ``translation``... or the plane-map
        arrays, see :mod:`mirrorlab.plugins.photogrammetry.camera_arrays`) or a camera model.

    Examples
    --------
    >>> P = camera_projection({"camera_matrix": np.diag([800., 800., 1.]), "dist_coeffs": np.zeros(5),
    ...                        "rotation": np.eye(3), "translation": np.zeros(3)})
    >>> x = P @ [100., 50., 1000., 1.]; (x[:2] / x[2]).round(6).tolist(), bool(x[2] > 0)
    ([80.0, 40.0], True)
    """
    cam = camera_from_arrays(camera) if isinstance(camera, Mapping) else camera
    if isinstance(cam, PinholeCamera):
        return np.asarray(cam.K, float) @ np.c_[np.asarray(cam.R, float), np.asarray(cam.t, float).reshape(3)]
    # plane map: points on rays through a window of the calibrated image region, DLT
    F = np.asarray(cam.camera_center, float)
    g = np.linspace(-1.0, 1.0, 5)
    u, v = np.meshgrid(g, g)
    img = np.asarray(cam.center, float) + float(cam.scale) * np.c_[u.ravel(), v.ravel()]
    plane = np.c_[cam.map_to_plane(img), np.full(len(img), float(cam.plane_z))]
    X = np.concatenate([F + s * (plane - F) for s in (0.4, 0.7, 1.0, 1.3)])
    x = cam.project(X)
    # normalise for a well-conditioned DLT
    mx, sx = x.mean(axis=0), x.std() or 1.0
    mX, sX = X.mean(axis=0), X.std() or 1.0
    xn, Xn = (x - mx) / sx, (X - mX) / sX
    Xh = np.c_[Xn, np.ones(len(Xn))]
    A = np.zeros((2 * len(X), 12))
    A[0::2, 0:4], A[0::2, 8:12] = Xh, -xn[:, :1] * Xh
    A[1::2, 4:8], A[1::2, 8:12] = Xh, -xn[:, 1:] * Xh
    Pn = np.linalg.svd(A)[2][-1].reshape(3, 4)
    Tx = np.array([[sx, 0, mx[0]], [0, sx, mx[1]], [0, 0, 1.0]])
    TX = np.eye(4)
    TX[:3, :3] /= sX
    TX[:3, 3] = -mX / sX
    P = Tx @ Pn @ TX
    if np.median(np.c_[X, np.ones(len(X))] @ P[2]) < 0:
        P = -P
    return P / np.linalg.norm(P[2, :3])


def mirror_outline(P: ArrayLike, corners: ArrayLike) -> FloatArray:
    """Image polygon (V, 2) px of a mirror's corners (V, 3) mm, projected by ``P`` (3, 4).

    Examples
    --------
    >>> P = np.c_[np.diag([100., 100., 1.]), np.zeros(3)]
    >>> mirror_outline(P, [[0, 0, 10], [10, 0, 10], [10, 10, 10]]).tolist()
    [[0.0, 0.0], [100.0, 0.0], [100.0, 100.0]]
    """
    c = np.asarray(corners, float)
    if c.ndim != 2 or c.shape[1] != 3 or len(c) < 3:
        raise ViewSplitError(f"mirror corners must be (V >= 3, 3) mm, got shape {c.shape}")
    x = np.c_[c, np.ones(len(c))] @ np.asarray(P, float).T
    if np.any(x[:, 2] <= 0):
        raise ViewSplitError("a mirror corner lies behind the camera; the outline cannot be projected "
                             "(check the surveyed corners and the calibration)")
    return x[:, :2] / x[:, 2:]


def split_views(xy: ArrayLike, regions: Sequence[ArrayLike]) -> tuple[FloatArray, NDArray[np.int64],
                                                                     NDArray[np.int64], NDArray[np.int64]]:
    """Detections (F, K, 2) that may be mirror images: those inside a mirror's image outline.

    A detection outside every outline is a direct image. One inside an outline is a mirror image
    *or* a marker seen directly in front of the mirror (on the thesis rig the mechanism stands
    between the camera and the mirror), so it stays a candidate for both roles until pairing
    decides (:func:`assign_views`).

    Parameters
    ----------
    xy : (F, K, 2) px, NaN-padded detections.
    regions : one image polygon (V, 2) px per mirror (:func:`mirror_outline`).

    Returns
    -------
    virtual : (F, M, 2) px, the candidates, NaN-padded (in detection order).
    virtual_mirror : (F, M) mirror whose outline holds each candidate, -1 in padding.
    virtual_row : (F, M) row of each candidate in ``xy``, -1 in padding.
    view : (F, K) -1 outside every outline, k inside mirror k's outline, -2 for padding rows.

    Examples
    --------
    >>> det = np.array([[[5., 5.], [50., 5.], [np.nan, np.nan]]])
    >>> virt, vm, rows, view = split_views(det, [[[0, 0], [10, 0], [10, 10], [0, 10]]])
    >>> virt.tolist(), vm.tolist(), rows.tolist(), view.tolist()
    ([[[5.0, 5.0]]], [[0]], [[0]], [[0, -1, -2]])
    """
    d = np.asarray(xy, float)
    if d.ndim != 3 or d.shape[2] != 2:
        raise ViewSplitError(f"detections must be (F, K, 2) px, got shape {d.shape}; use detect_markers' xy")
    F, K = d.shape[:2]
    ok = np.all(np.isfinite(d), axis=2)
    view = np.full((F, K), -2, np.int64)
    if ok.any():
        view[ok] = mirror_of_points(d[ok], [np.asarray(r, float) for r in regions])
    inside = view >= 0
    n = int(inside.sum(axis=1).max()) if F and K else 0
    order = np.argsort(~inside, axis=1, kind="stable")[:, :n]           # candidates first, in order
    take = np.take_along_axis(inside, order, axis=1)
    frames = np.broadcast_to(np.arange(F)[:, None], (F, n))
    virtual = np.where(take[..., None], d[frames, order], np.nan)
    virtual_mirror = np.where(take, view[frames, order], -1)
    virtual_row = np.where(take, order, -1)
    return virtual, virtual_mirror.astype(np.int64), virtual_row.astype(np.int64), view
