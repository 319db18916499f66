"""Chunks of frames: where to cut a recording, and how to put the chunks' outputs back together.

Pure numpy functions. An algorithm whose frames are computed independently
(:meth:`Algorithm.frame_wise <mirrorlab.core.algorithms.Algorithm.frame_wise>`) gives, for frames
``[a, b)``, outputs whose first axis is those frames; concatenated in frame order they equal the
outputs of one run on all frames, once every chunk is padded to the widest chunk along the other
axes (a chunk whose frames hold fewer markers is narrower).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np


def chunk_bounds(frames: int, size: int) -> list[tuple[int, int]]:
    """``[(start, stop), ...]`` covering ``range(frames)`` in order, each at most ``size`` frames.

    >>> chunk_bounds(10, 4)
    [(0, 4), (4, 8), (8, 10)]
    >>> chunk_bounds(0, 4)
    []
    """
    if size < 1:
        raise ValueError(f"chunk size {size}: must be at least 1 frame")
    return [(start, min(start + size, frames)) for start in range(0, frames, size)]


def pad_to(array: np.ndarray, shape: Sequence[int], fill: Any) -> np.ndarray:
    """``array`` padded at the end of each axis to ``shape`` with ``fill`` (returned as is if it fits).

    >>> pad_to(np.array([[1.0], [2.0]]), (2, 3), np.nan).tolist()
    [[1.0, nan, nan], [2.0, nan, nan]]
    """
    if array.shape == tuple(shape):
        return array
    out = np.full(shape, fill, dtype=array.dtype)
    out[tuple(slice(0, n) for n in array.shape)] = array
    return out


def merge_frames(parts: Sequence[Mapping[str, Any]], fill: Mapping[str, Any] | None = None) -> dict[str, np.ndarray]:
    """Concatenate the outputs of consecutive chunks along their first axis (frames), in order.

    Parameters
    ----------
    parts
        Each chunk's outputs (name -> array whose first axis is that chunk's frames), in frame order.
    fill
        Padding value per output for chunks narrower than the widest one; floating outputs not
        listed are padded with NaN (the NaN-for-missing convention).

    Raises
    ------
    ValueError
        An output that is not per frame (0-d), differs in dimensions between chunks, or needs
        padding without a fill value; the message names it.

    Examples
    --------
    >>> a = {"xy": np.array([[[1.0, 2.0]]]), "counts": np.array([1])}
    >>> b = {"xy": np.array([[[3.0, 4.0], [5.0, 6.0]]]), "counts": np.array([2])}
    >>> out = merge_frames([a, b])
    >>> out["xy"].shape, out["counts"].tolist(), bool(np.isnan(out["xy"][0, 1]).all())
    ((2, 2, 2), [1, 2], True)
    """
    fill = fill or {}
    merged = {}
    for name in parts[0]:
        arrays = [np.asarray(p[name]) for p in parts]
        if arrays[0].ndim == 0 or len({a.ndim for a in arrays}) != 1:
            raise ValueError(f"output {name!r} is not an array over frames in every chunk "
                             f"(shapes {[a.shape for a in arrays]}); its algorithm cannot run in chunks")
        widest = np.max([a.shape[1:] for a in arrays], axis=0).astype(int).tolist()
        if name in fill:
            value = fill[name]
        elif np.issubdtype(arrays[0].dtype, np.floating):
            value = np.nan
        elif any(list(a.shape[1:]) != widest for a in arrays):
            raise ValueError(f"output {name!r} ({arrays[0].dtype}) differs in shape between chunks and its "
                             "algorithm declares no padding for it (Algorithm.frame_fill)")
        else:
            value = 0
        merged[name] = np.concatenate([pad_to(a, (a.shape[0], *widest), value) for a in arrays], axis=0)
    return merged
