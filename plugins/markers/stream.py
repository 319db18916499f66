"""Detection on a stack of frames: NaN-padded (frames, K_max, 2) arrays plus per-frame counts."""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .detect import detect_markers
from .errors import InvalidImage


@dataclass(frozen=True)
class StreamDetections:
    """Detections of F frames, NaN-padded to the largest count K_max.

    Attributes
    ----------
    xy : (F, K_max, 2) px, NaN beyond ``counts[f]``.
    counts : (F,) int, markers found per frame.
    area, eccentricity, contrast : (F, K_max), NaN-padded.
    """

    xy: NDArray[np.float64]
    counts: NDArray[np.int64]
    area: NDArray[np.float64]
    eccentricity: NDArray[np.float64]
    contrast: NDArray[np.float64]


def detect_stream(frames: Iterable[np.ndarray], *, progress: Callable[[int, int | None], None] | None = None,
                  total: int | None = None, **options: Any) -> StreamDetections:
    """Run :func:`~mirrorlab.plugins.markers.detect_markers` on every frame.

    Parameters
    ----------
    frames : (F, H, W) array or an iterable of 2-D frames.
    progress : optional ``progress(done, total)`` called every 64 frames and at the end.
    total : number of frames for ``progress`` when ``frames`` has no ``len``.
    **options : passed to ``detect_markers`` (``method``, ``threshold``, ...).

    Returns
    -------
    StreamDetections

    Raises
    ------
    InvalidImage
        A frame is not an image; the message names the frame index.

    Examples
    --------
    >>> f = np.zeros((2, 30, 30), np.uint8); f[0, 5:8, 5:8] = 255; f[1, 10:13, 20:23] = 255
    >>> out = detect_stream(f)
    >>> out.counts.tolist(), out.xy[1, 0].tolist()
    ([1, 1], [21.0, 11.0])
    """
    if total is None and hasattr(frames, "__len__"):
        total = len(frames)  # type: ignore[arg-type]
    results = []
    for i, frame in enumerate(frames):
        try:
            results.append(detect_markers(frame, **options))
        except InvalidImage as exc:
            raise InvalidImage(f"frame {i}: {exc}") from None
        if progress is not None and (i + 1) % 64 == 0:
            progress(i + 1, total)
    if progress is not None:
        progress(len(results), total)
    f = len(results)
    counts = np.array([len(r) for r in results], np.int64)
    k = int(counts.max()) if f else 0
    xy = np.full((f, k, 2), np.nan)
    area, ecc, con = (np.full((f, k), np.nan) for _ in range(3))
    for i, r in enumerate(results):
        n = len(r)
        xy[i, :n], area[i, :n], ecc[i, :n], con[i, :n] = r.xy, r.area, r.eccentricity, r.contrast
    return StreamDetections(xy, counts, area, ecc, con)
