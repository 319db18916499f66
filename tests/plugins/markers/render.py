"""Test images with known marker centres: supersampled anti-aliased ellipses, Gaussian blur, noise.

Convention (the same as :mod:`mirrorlab.plugins.markers`): x to the right, y down, the centre of
pixel ``image[row, col]`` at ``(x, y) = (col, row)``.

Each marker is drawn with ``cv2.ellipse`` (``LINE_AA``, sub-pixel ``shift``) on a canvas ``ss``
times finer and reduced with ``cv2.INTER_AREA`` (exact box averaging), so edge pixels carry their
area coverage. Fine-canvas coordinates map to image coordinates as ``x = (X + 0.5) / ss - 0.5``.
"""

from __future__ import annotations

import cv2
import numpy as np
from numpy.typing import NDArray

SHIFT = 8  # sub-pixel bits of cv2.ellipse on the fine canvas


def render_markers(shape: tuple[int, int], centers: NDArray, radii: NDArray | float, *,
                   axes_ratio: NDArray | float = 1.0, angle_deg: NDArray | float = 0.0,
                   background: float = 30.0, foreground: float = 220.0, blur: float = 0.0,
                   noise: float = 0.0, ss: int = 8, rng: np.random.Generator | None = None,
                   dtype: type = np.uint8) -> NDArray:
    """Grey image (H, W) of bright elliptical markers on a dark background.

    ``radii`` are semi-major axes in px, ``axes_ratio`` minor/major, ``blur`` the Gaussian sigma
    in px, ``noise`` the sigma of additive Gaussian noise in grey levels. ``dtype=np.uint8``
    rounds and clips like a camera; ``np.float64`` keeps the exact values.
    """
    h, w = shape
    centers = np.atleast_2d(np.asarray(centers, float))
    n = len(centers)
    radii = np.broadcast_to(np.asarray(radii, float), (n,))
    ratio = np.broadcast_to(np.asarray(axes_ratio, float), (n,))
    angle = np.broadcast_to(np.asarray(angle_deg, float), (n,))
    canvas = np.zeros((h * ss, w * ss), np.uint8)
    one = 1 << SHIFT
    for (x, y), r, q, a in zip(centers, radii, ratio, angle, strict=False):
        cx, cy = (x + 0.5) * ss - 0.5, (y + 0.5) * ss - 0.5
        cv2.ellipse(canvas, (int(round(cx * one)), int(round(cy * one))),
                    (int(round(r * ss * one)), int(round(r * q * ss * one))), float(a), 0.0, 360.0, 255,
                    thickness=-1, lineType=cv2.LINE_AA, shift=SHIFT)
    cover = cv2.resize(canvas.astype(np.float32) / 255.0, (w, h), interpolation=cv2.INTER_AREA)
    image = background + (foreground - background) * cover.astype(np.float64)
    if blur > 0:
        image = cv2.GaussianBlur(image, (0, 0), blur, borderType=cv2.BORDER_REPLICATE)
    if noise > 0:
        rng = rng or np.random.default_rng(0)
        image = image + rng.normal(0.0, noise, image.shape)
    if dtype == np.uint8:
        return np.clip(np.rint(image), 0, 255).astype(np.uint8)
    return image.astype(dtype)


def random_centers(rng: np.random.Generator, shape: tuple[int, int], n: int, radius: float,
                   spacing: float | None = None, margin: float | None = None) -> NDArray:
    """``n`` random sub-pixel centres at least ``spacing`` apart and ``margin`` from the border."""
    h, w = shape
    margin = 2 * radius + 8 if margin is None else margin
    spacing = 4 * radius + 12 if spacing is None else spacing
    out: list[NDArray] = []
    for _ in range(200 * n):
        p = rng.uniform([margin, margin], [w - 1 - margin, h - 1 - margin])
        if all(np.hypot(*(p - q)) >= spacing for q in out):
            out.append(p)
            if len(out) == n:
                return np.array(out)
    raise RuntimeError(f"could not place {n} markers of radius {radius} px in {w}x{h}")


def binary_disc_frame(shape: tuple[int, int], centers: NDArray, radii: NDArray | float) -> NDArray:
    """Binary 0/255 frame (like a scanner frame): pixel set when its centre is inside the disc."""
    h, w = shape
    yy, xx = np.mgrid[0:h, 0:w]
    out = np.zeros(shape, bool)
    for (x, y), r in zip(np.atleast_2d(centers), np.broadcast_to(radii, (len(np.atleast_2d(centers)),)), strict=False):
        out |= (xx - x) ** 2 + (yy - y) ** 2 <= r * r
    return out.astype(np.uint8) * np.uint8(255)
