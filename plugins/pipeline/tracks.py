"""Direct/mirror roles from the pairs, and the pairs carried along tracks: (F, T, 2) real + virtual.

:func:`assign_views` turns the pairs of ``pair_mirror`` (run with every detection as a possible
direct image and the detections inside a mirror outline as possible mirror images) into roles: a
detection chosen as a mirror image is one; every other detection is a direct image.

``pair_mirror`` decides, frame by frame, which mirror image belongs to each direct detection;
``track`` links the direct detections of successive frames into tracks. The reconstruction needs
both per track: :func:`mirror_tracks` gathers them (the mirror image of a track in frame f is the
one paired with the detection the track used in f; NaN where the track is missing or its
detection has no decided pair in that mirror).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .errors import ViewSplitError

__all__ = ["assign_views", "mirror_tracks"]

FloatArray = NDArray[np.float64]


def mirror_tracks(real: ArrayLike, track_index: ArrayLike, paired_xy: ArrayLike,
                  mirror: int = 0) -> tuple[FloatArray, FloatArray]:
    """Direct and mirror image of each track in each frame.

    Parameters
    ----------
    real : (F, N, 2) px, the direct detections the tracks and pairs were computed on.
    track_index : (F, T) row of ``real`` used by each track, -1 where missing (``track`` output ``index``).
    paired_xy : (F, N, E, 2) px, mirror image paired with each direct detection per mirror, NaN
        none (``pair_mirror`` output ``virtual_xy``), or (F, N, 2) for one mirror.
    mirror : which mirror's images to return.

    Returns
    -------
    real_xy, virtual_xy : (F, T, 2) px, NaN where the track or its pair is missing.

    Raises
    ------
    ViewSplitError
        Shapes do not agree (the message gives them).

    Examples
    --------
    >>> real = np.array([[[0., 0.], [9., 9.]], [[8., 8.], [1., 1.]]])
    >>> paired = real[:, :, None] + 100.0
    >>> r, v = mirror_tracks(real, [[0, 1], [1, 0]], paired)
    >>> r[1].tolist(), v[1].tolist()
    ([[1.0, 1.0], [8.0, 8.0]], [[101.0, 101.0], [108.0, 108.0]])
    """
    r = np.asarray(real, float)
    idx = np.asarray(track_index, np.int64)
    pv = np.asarray(paired_xy, float)
    if pv.ndim == 3:
        pv = pv[:, :, None]
    if r.ndim != 3 or idx.ndim != 2 or pv.ndim != 4 or not (len(r) == len(idx) == len(pv)) \
            or pv.shape[1] != r.shape[1] or r.shape[2] != 2 or pv.shape[3] != 2:
        raise ViewSplitError(f"expected real (F, N, 2), track_index (F, T), paired_xy (F, N, E, 2) with the same "
                             f"F and N; got {r.shape}, {idx.shape}, {pv.shape}")
    if not 0 <= mirror < pv.shape[2]:
        raise ViewSplitError(f"mirror {mirror} does not exist; paired_xy has {pv.shape[2]} mirror(s)")
    if idx.size and (idx.max() >= r.shape[1]):
        raise ViewSplitError(f"track_index refers to detection {int(idx.max())} but frames hold {r.shape[1]}; "
                             "track the same detections that were paired")
    F, T = idx.shape
    have = idx >= 0
    safe = np.where(have, idx, 0)
    frames = np.arange(F)[:, None]
    real_xy = np.where(have[..., None], r[frames, safe], np.nan)
    virtual_xy = np.where(have[..., None], pv[frames, safe, mirror], np.nan)
    return real_xy, virtual_xy


def assign_views(xy: ArrayLike, virtual_row: ArrayLike, virtual_index: ArrayLike,
                 paired_xy: ArrayLike) -> tuple[FloatArray, FloatArray, NDArray[np.int64], NDArray[np.int64]]:
    """Direct images and their paired mirror images from a pairing of every detection.

    Parameters
    ----------
    xy : (F, K, 2) px, detections (the ``real`` input of ``pair_mirror``).
    virtual_row : (F, M) row in ``xy`` of each mirror-image candidate (``split_views``), -1 padding.
    virtual_index : (F, K, E) candidate paired with each detection per mirror, -1 none (``pair_mirror``).
    paired_xy : (F, K, E, 2) px, that candidate's position (``pair_mirror`` output ``virtual_xy``).

    Returns
    -------
    real : (F, N, 2) px, the direct images, NaN-padded (in detection order).
    paired : (F, N, E, 2) px, the mirror image of each direct image per mirror, NaN none.
    real_row : (F, N) row of each direct image in ``xy``, -1 padding.
    role : (F, K) -1 direct image, k mirror image in mirror k, -2 padding.

    Examples
    --------
    >>> xy = np.array([[[0., 0.], [5., 0.], [9., 9.]]])
    >>> paired_xy = [[[[5., 0.]], [[np.nan] * 2], [[np.nan] * 2]]]
    >>> real, paired, rows, role = assign_views(xy, [[1, 2]], [[[0], [-1], [-1]]], paired_xy)
    >>> role.tolist(), rows.tolist(), paired[0, :, 0].tolist()
    ([[-1, 0, -1]], [[0, 2]], [[5.0, 0.0], [nan, nan]])
    """
    d = np.asarray(xy, float)
    vr = np.asarray(virtual_row, np.int64)
    vi = np.asarray(virtual_index, np.int64)
    pv = np.asarray(paired_xy, float)
    if d.ndim != 3 or vi.ndim != 3 or pv.ndim != 4 or vr.ndim != 2 or vi.shape[:2] != d.shape[:2] \
            or pv.shape[:3] != vi.shape or len(vr) != len(d):
        raise ViewSplitError(f"expected xy (F, K, 2), virtual_row (F, M), virtual_index (F, K, E), paired_xy "
                             f"(F, K, E, 2); got {d.shape}, {vr.shape}, {vi.shape}, {pv.shape}")
    F, K, E = vi.shape
    ok = np.all(np.isfinite(d), axis=2)
    role = np.where(ok, -1, -2).astype(np.int64)
    f, k, e = np.nonzero(vi >= 0)
    if vr.shape[1] and len(f) and vi.max() >= vr.shape[1]:
        raise ViewSplitError(f"virtual_index refers to candidate {int(vi.max())} but frames hold {vr.shape[1]}; "
                             "pair the candidates that split_views returned")
    rows = vr[f, vi[f, k, e]] if len(f) else np.zeros(0, np.int64)
    role[f, rows] = e
    is_real = role == -1
    n = int(is_real.sum(axis=1).max()) if F and K else 0
    order = np.argsort(~is_real, axis=1, kind="stable")[:, :n]
    take = np.take_along_axis(is_real, order, axis=1)
    frames = np.broadcast_to(np.arange(F)[:, None], (F, n))
    real = np.where(take[..., None], d[frames, order], np.nan)
    paired = np.where(take[..., None, None], pv[frames, order], np.nan)
    real_row = np.where(take, order, -1).astype(np.int64)
    return real, paired, real_row, role
