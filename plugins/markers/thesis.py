"""Thesis detector (§5.3.2 Steps 1–4, Appendix 4.4; spec analysis.md §1.1): weighted filters and hill climbing.

On a binary image ``b`` (0/1):

1. **Raster search** over ``y = 8 … H-13``, ``x = 8 … W-13`` (the listing's \\$008–\\$14B and
   \\$008–\\$1F3 for 512 × 344 frames): the first set pixel ``(x0, y0)`` starts a marker.
2. **Horizontal filter** :math:`R_H(x)=\\sum_{y'\\ge y_0}\\sum_j w^H_j\\,b(x-11+j,y')`, the row loop
   stopping at the first row whose windowed sum is 0. Climb from ``x0`` with +1 while ``R_H``
   increases, else with −1; ``xc`` is the last improving position.
3. **Vertical filter** :math:`R_V(y)=\\sum_{x'}\\sum_j w^V_j\\,b(x',y-11+j)`, ``x'`` running right
   from ``xc`` and left from ``xc-1`` while the windowed column sum is non-zero. Climb from ``y0``
   with +1 only; ``yc`` is the last improving position.
4. Store the marker, clear the 24 × 24 box ``[xc-11, xc+12] × [yc-11, yc+12]``, resume Step 1 on row
   ``y0`` at ``x = xc + 13``.

A window placed at ``x`` covers ``x-11 … x+12``, i.e. it is centred at ``x + 0.5``; the reported
centre is therefore ``(xc + 0.5, yc + 0.5)`` (the thesis stored the window index).

The weights of Fig. 5.10 are not legible in the source: the default is the symmetric triangle
``1, 2, …, 12, 12, …, 2, 1`` (spec §1.1, §10); it is **not** the thesis's table. The listing of the
vertical set-up (``WSETV``) is missing; Step 3 follows the text and ``WSETH`` by symmetry. The
listing's skipping of whole zero bytes in Step 1 is a speed-up without effect on the result and
is not reproduced.

Documented limits (tested): integer output (quantisation RMS ≈ 1/√12 px per axis); plateaus stop
the climb; markers larger than 24 px are split or mis-centred, markers closer than 13 px on one
row are merged or lost, and markers within 8 px of the border are not searched.

Each filter value is one small vectorised product over the current (partly cleared) image, so the
work per marker is a few dozen array operations — no loop over pixels.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .errors import InvalidDetectionParameter

#: Default 24-tap weights (spec §1.1): symmetric triangle; NOT the illegible values of Fig. 5.10.
DEFAULT_WEIGHTS = np.r_[np.arange(1, 13), np.arange(12, 0, -1)].astype(np.int64)
TAPS = 24
HALF = 11  # window at x covers x-11 … x+12
MARGIN = 8  # Step 1 searches 8 … size-13
PAD = 2 * TAPS


def check_weights(weights: ArrayLike | None, name: str) -> NDArray[np.int64]:
    """24 non-negative integer taps (default :data:`DEFAULT_WEIGHTS`)."""
    if weights is None:
        return DEFAULT_WEIGHTS
    w = np.asarray(weights)
    if w.shape != (TAPS,) or not np.all(np.isfinite(w)) or np.any(w < 0) or np.any(w != np.round(w)):
        raise InvalidDetectionParameter(f"{name} must be {TAPS} non-negative integers (the 8-bit table "
                                        f"`WEIGHT`), got shape {w.shape}: {w!r}")
    if not np.any(w):
        raise InvalidDetectionParameter(f"{name} are all zero; give at least one positive tap")
    return w.astype(np.int64)


def _run_sum(values: NDArray[np.int64]) -> int:
    """Sum of ``values`` up to (not including) the first zero."""
    stop = np.flatnonzero(values == 0)
    return int(values[: stop[0]].sum()) if stop.size else int(values.sum())


def thesis_centres(binary: NDArray, weights_h: ArrayLike | None = None,
                   weights_v: ArrayLike | None = None) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Marker centres of a binary image by the thesis's hill climbing (Steps 1–4).

    Parameters
    ----------
    binary : (H, W) array, non-zero = marker pixel.
    weights_h, weights_v : 24 non-negative integer taps each (default triangular, see module notes).

    Returns
    -------
    xy : (K, 2) float, px — ``(xc + 0.5, yc + 0.5)``, pixel centres at integer coordinates.
    boxes : (K, 4) int — the cleared box ``x_first, y_first, x_last, y_last`` (inclusive) per marker.

    Examples
    --------
    >>> b = np.zeros((40, 40), np.uint8)
    >>> b[15:25, 10:20] = 1                       # a 10 × 10 square centred at (14.5, 19.5)
    >>> xy, boxes = thesis_centres(b)
    >>> xy.tolist()
    [[14.5, 19.5]]
    """
    wh, wv = check_weights(weights_h, "weights_h"), check_weights(weights_v, "weights_v")
    b = np.asarray(binary) != 0
    h, w = b.shape
    P = np.zeros((h + 2 * PAD, w + 2 * PAD), np.int64)  # padded working copy, cleared as we go
    P[PAD:PAD + h, PAD:PAD + w] = b
    ys, ye, xs, xe = MARGIN, h - 13, MARGIN, w - 13  # inclusive search bounds
    if ye < ys or xe < xs:
        return np.zeros((0, 2)), np.zeros((0, 4), np.int64)
    S = b[ys:ye + 1, xs:xe + 1].copy()  # search region, raster-ordered
    flat, sw = S.ravel(), xe - xs + 1

    def r_h(x: int, y0: int) -> int:
        cols = P[PAD + y0:PAD + h + 1, PAD + x - HALF:PAD + x - HALF + TAPS] @ wh
        return _run_sum(cols)

    def r_v(y: int, xc: int) -> int:
        row = wv @ P[PAD + y - HALF:PAD + y - HALF + TAPS, :]
        return _run_sum(row[PAD + xc:]) + _run_sum(row[PAD + xc - 1::-1])

    centres, boxes, start = [], [], 0
    while start < flat.size:
        hit = int(np.argmax(flat[start:]))
        if not flat[start + hit]:
            break
        y0, x0 = divmod(start + hit, sw)
        y0, x0 = y0 + ys, x0 + xs
        # Step 2: horizontal hill climbing
        xc, best = x0, r_h(x0, y0)
        step = 1 if r_h(x0 + 1, y0) > best else -1
        while (cand := r_h(xc + step, y0)) > best:
            xc, best = xc + step, cand
        # Step 3: vertical hill climbing, downward only
        yc, best = y0, r_v(y0, xc)
        while (cand := r_v(yc + 1, xc)) > best:
            yc, best = yc + 1, cand
        centres.append((xc + 0.5, yc + 0.5))
        bx0, by0, bx1, by1 = xc - HALF, yc - HALF, xc + HALF + 1, yc + HALF + 1
        boxes.append((max(bx0, 0), max(by0, 0), min(bx1, w - 1), min(by1, h - 1)))
        # Step 4: clear the 24 x 24 box in the working image and the search region
        P[PAD + by0:PAD + by1 + 1, PAD + bx0:PAD + bx1 + 1] = 0
        S[max(by0 - ys, 0):max(by1 - ys + 1, 0), max(bx0 - xs, 0):max(bx1 - xs + 1, 0)] = False
        start = (y0 - ys) * sw + min(max(xc + 13 - xs, 0), sw)  # resume on row y0 at xc + 13
    return np.array(centres, float).reshape(-1, 2), np.array(boxes, np.int64).reshape(-1, 4)
