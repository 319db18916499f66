"""Which mirror's image region each detection falls in (to split real and mirror-image detections)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from matplotlib.path import Path
from numpy.typing import ArrayLike, NDArray

from .errors import InvalidPairingInput


def mirror_of_points(xy: ArrayLike, regions: Sequence[ArrayLike]) -> NDArray[np.int64]:
    """Index of the first image polygon containing each point, −1 for none (a direct image).

    Parameters
    ----------
    xy : (K, 2) px.
    regions : one (V, 2) polygon per mirror, px — e.g. the projected corners of the mirror's
        rectangle (``PinholeCamera.project``).

    Examples
    --------
    >>> mirror_of_points([[5., 5.], [50., 5.]], [[[0, 0], [10, 0], [10, 10], [0, 10]]]).tolist()
    [0, -1]
    """
    p = np.asarray(xy, float).reshape(-1, 2)
    out = np.full(len(p), -1, np.int64)
    for k in range(len(regions) - 1, -1, -1):
        poly = np.asarray(regions[k], float)
        if poly.ndim != 2 or poly.shape[1] != 2 or len(poly) < 3:
            raise InvalidPairingInput(f"regions[{k}] must be a (V >= 3, 2) polygon in pixels, got {poly.shape}")
        out[Path(poly).contains_points(p)] = k
    return out
