"""OpenCV renderer of the virtual lab: grey uint8 frames of bright elliptical markers.

Each marker is drawn from its projected outline (a polygon of points around the marker circle,
projected through the camera with its distortion, so the ellipse is exact up to the polygon). The
coverage of every pixel is computed on a small supersampled patch around the marker (``supersample``²
sub-pixels, vertex positions to 1/16 sub-pixel) and averaged with ``cv2.resize(INTER_AREA)``, which
anti-aliases the edge so that intensity centroids are accurate to a few thousandths of a pixel.

Frame model (grey levels 0-255), in this order:

1. base = ``background`` x illumination, with clutter (static, drawn once per renderer);
2. markers: ``value = base (1 - a) + level x illumination x a`` with coverage ``a``;
3. Gaussian blur of ``blur_sigma`` px (lens / focus);
4. Gaussian noise of ``noise_sigma`` grey levels (``cv2.randn``), seeded by ``(seed, frame index)``;
5. rounded and clipped to uint8.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

__all__ = ["RenderSettings", "Renderer", "outline_circles"]

FloatArray = NDArray[np.float64]
_SHIFT = 4                              # cv2 fixed-point fraction bits of the polygon vertices


@dataclass(frozen=True)
class RenderSettings:
    """How frames look.

    Attributes
    ----------
    background : grey level of the dark background (0-255).
    marker : grey level of a marker seen directly under even light.
    mirror_reflectance : fraction of the marker level seen in a mirror.
    blur_sigma : Gaussian blur, px (0 = none).
    noise_sigma : Gaussian noise, grey levels (0 = none).
    illumination : relative amplitude of the smooth uneven-light field (0 = even; 0.3 = ±30 %).
    clutter : number of random non-marker shapes (bars, lines, grey blobs, dark patches).
    supersample : sub-pixels per pixel side for the marker coverage.
    outline_points : polygon vertices per marker outline.
    seed : seed of the clutter, the light field and the noise.
    """

    background: float = 12.0
    marker: float = 235.0
    mirror_reflectance: float = 0.85
    blur_sigma: float = 0.0
    noise_sigma: float = 0.0
    illumination: float = 0.0
    clutter: int = 0
    supersample: int = 8
    outline_points: int = 64
    seed: int = 0

    def __post_init__(self) -> None:
        for name in ("blur_sigma", "noise_sigma", "illumination", "clutter"):
            if getattr(self, name) < 0:
                raise ValueError(f"render setting {name} must be >= 0 (got {getattr(self, name)})")
        if not 1 <= self.supersample <= 32 or self.outline_points < 8:
            raise ValueError("supersample must be 1..32 and outline_points >= 8")


def outline_circles(centres: FloatArray, normals: FloatArray, radii: FloatArray, n: int) -> FloatArray:
    """Points ``(Q, n, 3)`` on circles of ``radii`` about ``centres`` normal to ``normals`` (mm).

    The polygon radius is enlarged so that the ``n``-gon has the circle's area (its centroid is the
    circle's centre either way).

    Examples
    --------
    >>> p = outline_circles(np.zeros((1, 3)), np.array([[0.0, 0.0, 1.0]]), np.array([2.0]), 8)
    >>> p.shape, bool(np.allclose(p[0, :, 2], 0.0))
    ((1, 8, 3), True)
    """
    nrm = normals / np.linalg.norm(normals, axis=-1, keepdims=True)
    helper = np.where(np.abs(nrm[:, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    a = np.cross(nrm, helper)
    a /= np.linalg.norm(a, axis=-1, keepdims=True)
    b = np.cross(nrm, a)
    phi = 2 * np.pi * np.arange(n) / n
    scale = np.sqrt((2 * np.pi / n) / np.sin(2 * np.pi / n))
    r = (radii * scale)[:, None, None]
    return centres[:, None] + r * (np.cos(phi)[None, :, None] * a[:, None] + np.sin(phi)[None, :, None] * b[:, None])


class Renderer:
    """Renders frames of a fixed size; the static layer (light field, clutter) is built once.

    Parameters
    ----------
    image_size : (width, height), px
    settings : RenderSettings

    Examples
    --------
    >>> r = Renderer((64, 48), RenderSettings())
    >>> square = np.array([[[20.0, 20.0], [30.0, 20.0], [30.0, 30.0], [20.0, 30.0]]])
    >>> img = r.render(square, np.array([200.0]))
    >>> img.dtype, img.shape, int(img[25, 25]), int(img[5, 5])
    (dtype('uint8'), (48, 64), 200, 12)
    """

    def __init__(self, image_size: tuple[int, int], settings: RenderSettings = RenderSettings()) -> None:
        self.width, self.height = (int(v) for v in image_size)
        self.settings = settings
        rng = np.random.default_rng([settings.seed, 0x11AB])
        self.light = self._light_field(rng)
        base = np.full((self.height, self.width), settings.background, np.float32)
        if settings.clutter:
            self._draw_clutter(base, rng)
        self.base = base * self.light
        self._work: NDArray[np.float32] | None = None
        self._spare: NDArray[np.float32] | None = None

    # -- static layer -------------------------------------------------------------------------------
    def _light_field(self, rng: np.random.Generator) -> NDArray[np.float32]:
        amp = self.settings.illumination
        if amp == 0:
            return np.ones((self.height, self.width), np.float32)
        coarse = rng.normal(size=(4, 6)).astype(np.float32)
        field = cv2.resize(coarse, (self.width, self.height), interpolation=cv2.INTER_CUBIC)
        yy, xx = np.mgrid[0:self.height, 0:self.width].astype(np.float32)
        r2 = ((xx - self.width / 2) / (self.width / 2)) ** 2 + ((yy - self.height / 2) / (self.height / 2)) ** 2
        field = field - field.mean() - 0.5 * r2                         # random smooth field + vignetting
        field /= max(float(np.abs(field).max()), 1e-6)
        return (1.0 + amp * field).clip(0.05, None).astype(np.float32)

    def _draw_clutter(self, img: NDArray[np.float32], rng: np.random.Generator) -> None:
        """Bars, lines, large low-contrast blobs and dark patches: shapes that are not markers."""
        s = self.settings
        size = max(self.width, self.height) / 1920.0
        grey_max = s.background + 0.4 * (s.marker - s.background)
        for _ in range(s.clutter):
            kind = rng.integers(4)
            cx, cy = rng.uniform(0, self.width), rng.uniform(0, self.height)
            level = float(rng.uniform(s.background, grey_max))
            if kind == 0:      # a bar (a link, a stand)
                length, width = rng.uniform(60, 500) * size, rng.uniform(4, 30) * size
                box = ((float(cx), float(cy)), (float(length), float(width)), float(rng.uniform(0, 180)))
                cv2.fillPoly(img, [np.round(cv2.boxPoints(box)).astype(np.int32)], level, cv2.LINE_AA)
            elif kind == 1:    # a thin line (a cable, an edge)
                a = rng.uniform(0, np.pi)
                d = rng.uniform(100, 800) * size * np.array([np.cos(a), np.sin(a)])
                p0 = (int(cx - d[0] / 2), int(cy - d[1] / 2))
                p1 = (int(cx + d[0] / 2), int(cy + d[1] / 2))
                cv2.line(img, p0, p1, level, int(rng.integers(1, 4)), cv2.LINE_AA)
            elif kind == 2:    # a large low-contrast blob
                axes = (int(rng.uniform(40, 160) * size), int(rng.uniform(25, 120) * size))
                cv2.ellipse(img, (int(cx), int(cy)), axes, float(rng.uniform(0, 180)), 0, 360,
                            s.background + 0.5 * (level - s.background), -1, cv2.LINE_AA)
            else:              # a dark patch (shadow)
                w, h = rng.uniform(30, 200, 2) * size
                cv2.rectangle(img, (int(cx), int(cy)), (int(cx + w), int(cy + h)), 0.4 * s.background, -1)

    # -- frames -----------------------------------------------------------------------------------
    def coverage(self, polygon: FloatArray) -> tuple[int, int, NDArray[np.float32]] | None:
        """Pixel coverage of one polygon (N, 2) px: ``(x0, y0, patch)`` or ``None`` if off the frame."""
        S = self.settings.supersample
        lo = np.floor(polygon.min(axis=0)).astype(int) - 1
        hi = np.ceil(polygon.max(axis=0)).astype(int) + 2
        x0, y0 = max(lo[0], 0), max(lo[1], 0)
        x1, y1 = min(hi[0], self.width), min(hi[1], self.height)
        if x1 <= x0 or y1 <= y0:
            return None
        # sub-pixel centres on integers: x -> (x - x0 + 0.5) S - 0.5
        pts = np.round(((polygon - [x0, y0] + 0.5) * S - 0.5) * (1 << _SHIFT)).astype(np.int32)
        patch = np.zeros(((y1 - y0) * S, (x1 - x0) * S), np.uint8)
        cv2.fillPoly(patch, [pts], 255, cv2.LINE_8, _SHIFT)
        small = cv2.resize(patch, (x1 - x0, y1 - y0), interpolation=cv2.INTER_AREA) if S > 1 else patch
        return x0, y0, small.astype(np.float32) * np.float32(1.0 / 255.0)

    def render(self, polygons: Sequence[FloatArray] | FloatArray, levels: NDArray, index: int = 0) -> NDArray[np.uint8]:
        """One frame: markers given as outline polygons (Q, N, 2) px with grey ``levels`` (Q,).

        ``index`` seeds the frame's noise together with ``settings.seed`` (the same index gives
        the same frame in any order and thread). Work buffers are reused: use one renderer per thread.
        """
        s = self.settings
        if self._work is None:
            self._work = np.empty_like(self.base)
            self._spare = np.empty_like(self.base)
        img, spare = self._work, self._spare
        np.copyto(img, self.base)
        for poly, level in zip(polygons, np.asarray(levels, float)):
            if not np.all(np.isfinite(poly)):
                continue
            cov = self.coverage(np.asarray(poly, float))
            if cov is None:
                continue
            x0, y0, a = cov
            roi = img[y0:y0 + a.shape[0], x0:x0 + a.shape[1]]
            target = np.float32(level) * self.light[y0:y0 + a.shape[0], x0:x0 + a.shape[1]]
            roi += a * (target - roi)
        if s.blur_sigma > 0:
            cv2.GaussianBlur(img, (0, 0), s.blur_sigma, dst=spare, borderType=cv2.BORDER_REPLICATE)
            img, spare = spare, img
        if s.noise_sigma > 0:
            # cv2's generator is thread-local: seeding it right before drawing makes the frame deterministic
            cv2.setRNGSeed(int(np.random.SeedSequence([s.seed, int(index)]).generate_state(1)[0] & 0x7FFFFFFF))
            cv2.randn(spare, 0.0, float(s.noise_sigma))
            cv2.add(img, spare, dst=img)
        cv2.add(img, 0.5, dst=img)
        np.clip(img, 0.0, 255.0, out=img)
        return img.astype(np.uint8)
