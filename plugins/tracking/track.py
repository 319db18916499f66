"""Frame-to-frame marker association (spec analysis.md §2).

Two methods, both taking a list of per-frame detections ``(K_i, 2)`` and returning tracks as a
``(frames, tracks, 2)`` array with NaN where a track is missing:

* ``method="nearest"`` — the thesis rule (§5.5.1 Step 2, Appendix 5 lines 1075–1160): the markers
  of the first frame define the tracks; for every track, the detection of the next frame nearest
  to its last position takes its label. There is no exclusivity check (two tracks may take the
  same detection) and a tie goes to the later detection (the listing's ``IF DT > D0``). Valid only
  while every displacement is below half the smallest inter-marker distance. Extensions, off by
  default in spirit: a ``gate`` (no detection within it → NaN for that frame) and ``max_gap``.
* ``method="predictive"`` (default) — constant-velocity prediction from the last two positions
  (extrapolated over gaps), cost = distance to the prediction, global one-to-one assignment
  (``scipy.optimize.linear_sum_assignment``) with a gate; unmatched detections start tracks;
  a track unseen for more than ``max_gap`` frames ends, so ids stay stable across shorter gaps.

New tracks are numbered in order of their first frame and, within a frame, in raster order of
their first detection (``y``, then ``x``, like the thesis's raster search), so the result does not
depend on the order of the detections within a frame.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import linear_sum_assignment
from scipy.spatial.distance import cdist

from .errors import InvalidDetections

FloatArray = NDArray[np.float64]
Method = Literal["predictive", "nearest"]
_BIG = 1e18


@dataclass(frozen=True)
class Tracks:
    """Marker tracks over F frames.

    Attributes
    ----------
    xy : (F, T, 2) px — positions, NaN where the track has no detection.
    index : (F, T) int — index of the detection in its frame, −1 where missing.
    present : (T,) — fraction of frames between the track's first and last frame in which it was
        detected (1.0 for an unbroken track).
    residual : (T,) px — mean distance between detection and prediction (NaN when never predicted).
    first, last : (T,) int — first and last frame of each track.
    method : str
    """

    xy: FloatArray
    index: NDArray[np.int64]
    present: FloatArray
    residual: FloatArray
    first: NDArray[np.int64]
    last: NDArray[np.int64]
    method: str

    @property
    def n_tracks(self) -> int:
        return int(self.xy.shape[1])


def _frames(detections: Sequence[ArrayLike] | NDArray) -> list[FloatArray]:
    """Per-frame (K_i, 2) arrays; a (F, K, 2) NaN-padded array is accepted too (NaN rows dropped)."""
    out = []
    for f, d in enumerate(detections):
        a = np.asarray(d, float)
        if a.size == 0:
            a = a.reshape(0, 2)
        if a.ndim != 2 or a.shape[1] != 2:
            raise InvalidDetections(f"frame {f}: detections must have shape (K, 2) px, got {a.shape}")
        finite = np.all(np.isfinite(a), axis=1)
        if np.any(np.isfinite(a[~finite])):
            raise InvalidDetections(f"frame {f}: a detection has one NaN coordinate; use NaN for both or neither")
        out.append(a[finite])
    return out


def _raster(a: FloatArray) -> NDArray[np.int64]:
    return np.lexsort((a[:, 0], a[:, 1]))


def _nearest(frames: list[FloatArray], gate: float, max_gap: int,
             progress: Callable[[int, int], None] | None) -> tuple[FloatArray, NDArray, FloatArray]:
    n_frames = len(frames)
    first = frames[0][_raster(frames[0])] if n_frames else np.zeros((0, 2))
    order0 = _raster(frames[0]) if n_frames else np.zeros(0, int)
    t = len(first)
    xy = np.full((n_frames, t, 2), np.nan)
    index = np.full((n_frames, t), -1, np.int64)
    residual = np.full((n_frames, t), np.nan)
    if not n_frames or not t:
        return xy, index, residual
    xy[0], index[0] = first, order0
    last, last_f = first.copy(), np.zeros(t, np.int64)
    for f in range(1, n_frames):
        det = frames[f]
        alive = (f - last_f) <= max_gap + 1
        if len(det) and alive.any():
            d = cdist(last[alive], det)
            j = d.shape[1] - 1 - np.argmin(d[:, ::-1], axis=1)  # a tie goes to the later detection
            dj = d[np.arange(len(j)), j]
            ok = dj <= gate
            tr = np.flatnonzero(alive)[ok]
            xy[f, tr], index[f, tr], residual[f, tr] = det[j[ok]], j[ok], dj[ok]
            last[tr], last_f[tr] = det[j[ok]], f
        if progress is not None and f % 1024 == 0:
            progress(f, n_frames)
    return xy, index, residual


def _predictive(frames: list[FloatArray], gate: float, initial_gate: float, max_gap: int,
                progress: Callable[[int, int], None] | None) -> tuple[FloatArray, NDArray, FloatArray]:
    n_frames = len(frames)
    cap = 64
    pos = np.zeros((cap, 2))  # last position
    vel = np.zeros((cap, 2))  # px / frame
    last_f = np.zeros(cap, np.int64)
    seen = np.zeros(cap, np.int64)  # detections so far
    n_t = 0
    rec_f, rec_t, rec_j, rec_xy, rec_res = [], [], [], [], []
    for f in range(n_frames):
        det = frames[f]
        active = np.flatnonzero((f - last_f[:n_t]) <= max_gap + 1)
        matched_det = np.zeros(len(det), bool)
        if len(det) and active.size:
            pred = pos[active] + vel[active] * (f - last_f[active])[:, None]
            d = cdist(pred, det)
            g = np.where(seen[active] >= 2, gate, initial_gate)[:, None]
            cost = np.where(d <= g, d, _BIG)
            r, c = linear_sum_assignment(cost)
            ok = cost[r, c] < _BIG
            r, c = r[ok], c[ok]
            tr = active[r]
            new = det[c]
            has_prev = seen[tr] >= 1
            dt = (f - last_f[tr])[:, None]
            vel[tr] = np.where(has_prev[:, None], (new - pos[tr]) / np.maximum(dt, 1), 0.0)
            pos[tr], last_f[tr] = new, f
            res = np.where(seen[tr] >= 2, d[r, c], np.nan)
            seen[tr] += 1
            matched_det[c] = True
            rec_f.append(np.full(len(tr), f)), rec_t.append(tr), rec_j.append(c), rec_xy.append(new)
            rec_res.append(res)
        fresh = np.flatnonzero(~matched_det)
        if fresh.size:
            fresh = fresh[_raster(det[fresh])]
            if n_t + fresh.size > cap:
                cap = max(2 * cap, n_t + fresh.size)
                pos, vel = np.resize(pos, (cap, 2)), np.resize(vel, (cap, 2))
                last_f, seen = np.resize(last_f, cap), np.resize(seen, cap)
            tr = np.arange(n_t, n_t + fresh.size)
            pos[tr], vel[tr], last_f[tr], seen[tr] = det[fresh], 0.0, f, 1
            n_t += fresh.size
            rec_f.append(np.full(len(tr), f)), rec_t.append(tr), rec_j.append(fresh), rec_xy.append(det[fresh])
            rec_res.append(np.full(len(tr), np.nan))
        if progress is not None and f % 1024 == 0:
            progress(f, n_frames)
    xy = np.full((n_frames, n_t, 2), np.nan)
    index = np.full((n_frames, n_t), -1, np.int64)
    residual = np.full((n_frames, n_t), np.nan)
    if rec_f:
        ff, tt = np.concatenate(rec_f), np.concatenate(rec_t)
        xy[ff, tt], index[ff, tt] = np.concatenate(rec_xy), np.concatenate(rec_j)
        residual[ff, tt] = np.concatenate(rec_res)
    return xy, index, residual


def track(detections: Sequence[ArrayLike] | NDArray, method: Method = "predictive", *, gate: float = 20.0,
          initial_gate: float | None = None, max_gap: int = 5, min_length: int = 1,
          progress: Callable[[int, int], None] | None = None) -> Tracks:
    """Associate per-frame marker detections into tracks.

    Parameters
    ----------
    detections : sequence of F arrays (K_i, 2) px, or a NaN-padded (F, K_max, 2) array.
    method : ``"predictive"`` (default: constant velocity + optimal assignment) or ``"nearest"``
        (the thesis rule; see the module notes).
    gate : px — largest distance between a detection and a track's prediction (``nearest``: its
        last position; use ``np.inf`` for the literal thesis rule).
    initial_gate : px — gate for tracks with a single detection, which have no velocity yet
        (``predictive`` only; default ``2 * gate``).
    max_gap : frames — a track missing for up to this many consecutive frames keeps its id.
    min_length : drop tracks with fewer detections (e.g. 3 to remove spurious one-frame blobs).
    progress : optional ``progress(done, total)`` callback (every 1024 frames).

    Returns
    -------
    Tracks
        ``.xy`` (F, T, 2) with NaN gaps, ``.present`` and ``.residual`` per track.

    Raises
    ------
    InvalidDetections
        A frame's detections are not (K, 2); gates or gap lengths out of range.

    Examples
    --------
    >>> frames = [np.array([[0., 0.], [50., 0.]]), np.array([[52., 1.], [1., 1.]]), np.array([[2., 2.]])]
    >>> t = track(frames)
    >>> t.xy[:, 0].tolist(), t.xy[2, 1].tolist(), t.present.tolist()
    ([[0.0, 0.0], [1.0, 1.0], [2.0, 2.0]], [nan, nan], [1.0, 1.0])
    """
    if method not in ("predictive", "nearest"):
        raise InvalidDetections(f"unknown tracking method {method!r}; use 'predictive' or 'nearest'")
    initial_gate = 2.0 * gate if initial_gate is None else initial_gate
    if not (gate > 0 and initial_gate > 0):
        raise InvalidDetections(f"gate and initial_gate must be positive px, got {gate}, {initial_gate}")
    if max_gap < 0 or min_length < 1:
        raise InvalidDetections(f"need max_gap >= 0 and min_length >= 1, got {max_gap}, {min_length}")
    frames = _frames(detections)
    if method == "nearest":
        xy, index, res = _nearest(frames, gate, max_gap, progress)
    else:
        xy, index, res = _predictive(frames, gate, initial_gate, max_gap, progress)
    have = index >= 0
    count = have.sum(0)
    keep = count >= min_length
    xy, index, res, have, count = xy[:, keep], index[:, keep], res[:, keep], have[:, keep], count[keep]
    n_frames = len(frames)
    first = np.where(count > 0, np.argmax(have, axis=0), 0)
    last = np.where(count > 0, n_frames - 1 - np.argmax(have[::-1], axis=0), -1)
    with np.errstate(invalid="ignore", divide="ignore"):
        present = np.where(count > 0, count / np.maximum(last - first + 1, 1), 0.0)
        n_res = np.isfinite(res).sum(0)
        residual = np.where(n_res > 0, np.nansum(res, axis=0) / np.maximum(n_res, 1), np.nan)
    if progress is not None:
        progress(n_frames, n_frames)
    return Tracks(xy, index, present, residual, first.astype(np.int64), last.astype(np.int64), method)
