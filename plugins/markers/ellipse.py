"""Sub-pixel edge points of a blob and an ellipse fitted to them (``cv2.fitEllipse``)."""

from __future__ import annotations

import cv2
import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]


def edge_points(roi: NDArray, region: NDArray[np.bool_], level: float) -> FloatArray:
    """Points (N, 2) ``(x, y)`` in ROI pixels where the grey level crosses ``level``.

    Crossings are found between horizontally and vertically adjacent pixels whose values lie on
    either side of ``level`` (at least one of them inside ``region``) and placed by linear
    interpolation, so a blurred edge gives sub-pixel points. On a binary image the points fall
    half-way between the two pixels.

    Examples
    --------
    >>> roi = np.array([[0, 0, 0, 0], [0, 200, 200, 0], [0, 0, 0, 0]], float)
    >>> edge_points(roi, roi > 100, 100.0).tolist()
    [[0.5, 1.0], [2.5, 1.0], [1.0, 0.5], [2.0, 0.5], [1.0, 1.5], [2.0, 1.5]]
    """
    v = np.asarray(roi, np.float64) - level
    out = []
    for axis in (1, 0):  # along rows (x crossings), then along columns (y crossings)
        a = v[:, :-1] if axis == 1 else v[:-1, :]
        b = v[:, 1:] if axis == 1 else v[1:, :]
        ra = region[:, :-1] if axis == 1 else region[:-1, :]
        rb = region[:, 1:] if axis == 1 else region[1:, :]
        hit = (np.signbit(a) != np.signbit(b)) & (ra | rb)
        r, c = np.nonzero(hit)
        t = a[r, c] / (a[r, c] - b[r, c])
        pts = np.c_[c + t, r.astype(float)] if axis == 1 else np.c_[c.astype(float), r + t]
        out.append(pts)
    return np.concatenate(out)


def fit_ellipse(points: FloatArray) -> tuple[FloatArray, FloatArray, float] | None:
    """Least-squares ellipse through ``points`` (N ≥ 6): centre (2,), semi-axes (major, minor), angle.

    The angle (rad, in [0, π)) is the major-axis direction from +x toward +y. Returns ``None``
    for fewer than six points or a degenerate fit.

    Examples
    --------
    >>> t = np.linspace(0, 2 * np.pi, 40, endpoint=False)
    >>> c, ax, ang = fit_ellipse(np.c_[10 + 5 * np.cos(t), 20 + 2 * np.sin(t)])
    >>> np.round(c, 6).tolist(), np.round(ax, 6).tolist(), round(ang, 6)
    ([10.0, 20.0], [5.0, 2.0], 0.0)
    """
    if len(points) < 6:
        return None
    (cx, cy), (d1, d2), deg = cv2.fitEllipseDirect(np.asarray(points, np.float32).reshape(-1, 1, 2))
    if not (np.isfinite(cx) and np.isfinite(cy)) or min(d1, d2) <= 0:
        return None
    ang = np.deg2rad(deg) if d1 >= d2 else np.deg2rad(deg) + 0.5 * np.pi
    return np.array([cx, cy], float), 0.5 * np.array([max(d1, d2), min(d1, d2)]), float(np.mod(ang, np.pi))
