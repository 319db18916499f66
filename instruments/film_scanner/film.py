"""The film strip the simulated scanner reads (``instruments.md`` §1.4).

Strip coordinates (mm): ``y`` runs along the strip (the feed direction), ``x`` across it with 0 at
the frame centre. Frame ``k`` is preceded by a clear inter-frame band:

* band ``k``:  ``k * PITCH_MM <= y < k * PITCH_MM + BAND_MM`` (clear base, transmittance 0.95)
* frame ``k``: ``k * PITCH_MM + BAND_MM <= y < (k + 1) * PITCH_MM`` (the image, 24 mm x 18 mm)

After the last frame comes one more band and then the end of the strip; outside the strip
(``y < 0`` and past the end) there is no film in the gate, so the back-light reaches the sensor
unattenuated: heading then never finds a dark frame edge and reports ``E11 no frame``.
Each frame is held as a transmittance texture at ``OVERSAMPLE`` times the scan resolution,
already averaged over the 46.875 µm pixel aperture (28 µm photodiode imaged at m = 0.597), so a
bilinear lookup returns what one photodiode integrates.
"""

from __future__ import annotations

from collections import OrderedDict
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import cv2
import numpy as np

PIXEL_MM = 0.046875          # scan pixel (and line) pitch on the film: 18 mm / 384
FRAME_W_MM = 24.0            # 35 mm cine frame width, imaged onto the 512 photodiodes
FRAME_H_MM = 18.0
PITCH_MM = 19.0              # 4-perforation pitch; not in the thesis (spec §7)
BAND_MM = PITCH_MM - FRAME_H_MM
OVERSAMPLE = 4               # texture texels per scan pixel (spec: >= 4x)
TEXEL_MM = PIXEL_MM / OVERSAMPLE
TEX_W = int(round(FRAME_W_MM / TEXEL_MM))   # 2048
TEX_H = int(round(FRAME_H_MM / TEXEL_MM))   # 1536

T_DARK = 0.03                # image value 0   -> transmittance (dark background, density ~1.5)
T_BRIGHT = 0.90              # image value 255 -> transmittance (white marker)
T_BAND = 0.95                # clear inter-frame band
T_NOFILM = 1.0               # no film in the gate (before and after the strip)

# Pixel-aperture kernel at texel resolution: a box exactly OVERSAMPLE texels wide, centred (an
# even-sized box would shift the image by half a texel and bias every centroid).
_APERTURE = np.array([0.5, 1.0, 1.0, 1.0, 0.5], dtype=np.float32) / OVERSAMPLE


@dataclass(frozen=True)
class Marker:
    """A circular marker of the ground-truth scene, in frame millimetres.

    ``x_mm`` is measured from the frame centre across the strip, ``y_mm`` from the frame's top
    edge along the feed; ``radius_mm`` is the circle radius.
    """

    frame: int
    ident: int
    x_mm: float
    y_mm: float
    radius_mm: float

    @property
    def col_px(self) -> float:
        """Sensor pixel coordinate (pixel i is centred at (i - 255.5) * 46.875 µm)."""
        return self.x_mm / PIXEL_MM + 255.5

    @property
    def row_px(self) -> float:
        """Line coordinate counted from the frame's top edge (line l centred at (l + 0.5) pitch)."""
        return self.y_mm / PIXEL_MM - 0.5


class Film:
    """A strip of frames built from greyscale images or from a generator.

    Parameters
    ----------
    frames
        Greyscale images (uint8 0-255, or floats 0-1), one per frame; white = clear film. Any
        size: each is resized to the 24 mm x 18 mm frame (aspect not preserved).
    generator
        Alternatively a function ``k -> image`` called lazily for frames ``0 .. n_frames-1``.
    n_frames
        Number of frames when ``generator`` is given.
    markers
        Ground truth of the scene (for ``SIM:TRUTH?``); empty for arbitrary images.
    cache
        Number of frame textures kept in memory (each is 12.6 MB).
    """

    def __init__(self, frames: Sequence[np.ndarray] | None = None, *,
                 generator: Callable[[int], np.ndarray] | None = None, n_frames: int | None = None,
                 markers: Sequence[Marker] = (), cache: int = 3) -> None:
        if (frames is None) == (generator is None):
            raise ValueError("give either frames or generator")
        if frames is not None:
            images = list(frames)
            if not images:
                raise ValueError("a film needs at least one frame image")
            self._images: list[np.ndarray] | None = images
            self._generator = None
            self.n_frames = len(images)
        else:
            if not n_frames or n_frames < 1:
                raise ValueError("a generated film needs n_frames >= 1")
            self._images = None
            self._generator = generator
            self.n_frames = int(n_frames)
        self.markers = list(markers)
        self._cache: OrderedDict[int, np.ndarray] = OrderedDict()
        self._cache_size = max(1, cache)

    # -- geometry -------------------------------------------------------------------------------
    @staticmethod
    def frame_top_mm(k: int) -> float:
        """Strip position of frame ``k``'s top edge (first image row), mm."""
        return k * PITCH_MM + BAND_MM

    @property
    def length_mm(self) -> float:
        """Strip length up to the end of the band after the last frame, mm."""
        return self.n_frames * PITCH_MM + BAND_MM

    # -- textures -------------------------------------------------------------------------------
    def image(self, k: int) -> np.ndarray:
        """The source image of frame ``k`` as given (or generated)."""
        if self._images is not None:
            return self._images[k]
        assert self._generator is not None
        return self._generator(k)

    def texture(self, k: int) -> np.ndarray:
        """Aperture-averaged transmittance of frame ``k``, float32 ``(TEX_H, TEX_W)``."""
        tex = self._cache.get(k)
        if tex is not None:
            self._cache.move_to_end(k)
            return tex
        img = np.asarray(self.image(k))
        if img.ndim == 3:
            img = cv2.cvtColor(img, cv2.COLOR_BGR2GRAY)
        grey = img.astype(np.float32) / (255.0 if img.dtype == np.uint8 or img.max() > 1.0 else 1.0)
        if grey.shape != (TEX_H, TEX_W):
            shrink = grey.shape[0] > TEX_H or grey.shape[1] > TEX_W
            grey = cv2.resize(grey, (TEX_W, TEX_H), interpolation=cv2.INTER_AREA if shrink else cv2.INTER_LINEAR)
        trans = T_DARK + (T_BRIGHT - T_DARK) * np.clip(grey, 0.0, 1.0)
        tex = cv2.sepFilter2D(trans, cv2.CV_32F, _APERTURE, _APERTURE, borderType=cv2.BORDER_REPLICATE)
        self._cache[k] = tex
        if len(self._cache) > self._cache_size:
            self._cache.popitem(last=False)
        return tex

    def rows(self, ys_mm: np.ndarray) -> np.ndarray:
        """Transmittance rows at strip positions ``ys_mm``: ``(len(ys), TEX_W)`` float32.

        Rows inside a frame are interpolated linearly between texture rows; bands are clear and
        no film outside the strip is fully clear.
        """
        ys = np.asarray(ys_mm, dtype=np.float64)
        out = np.full((ys.size, TEX_W), T_NOFILM, dtype=np.float32)
        k = np.floor(ys / PITCH_MM).astype(np.int64)
        local = ys - k * PITCH_MM
        band = (local < BAND_MM) & (k >= 0) & (k <= self.n_frames)
        out[band] = T_BAND
        in_frame = (local >= BAND_MM) & (k >= 0) & (k < self.n_frames)
        for frame in np.unique(k[in_frame]):
            sel = np.nonzero(in_frame & (k == frame))[0]
            tex = self.texture(int(frame))
            r = (local[sel] - BAND_MM) / TEXEL_MM - 0.5
            r0 = np.clip(np.floor(r).astype(np.int64), 0, TEX_H - 1)
            r1 = np.clip(r0 + 1, 0, TEX_H - 1)
            frac = np.clip(r - r0, 0.0, 1.0).astype(np.float32)[:, None]
            out[sel] = tex[r0] * (1.0 - frac) + tex[r1] * frac
        return out

    # -- constructors ---------------------------------------------------------------------------
    @classmethod
    def from_images(cls, images: Sequence[np.ndarray]) -> Film:
        """A film whose frames are the given greyscale images (no marker truth)."""
        return cls(frames=images)

    @classmethod
    def generated(cls, n_frames: int = 8, n_markers: int = 4, seed: int = 0) -> Film:
        """The default film: white circular markers moving on a dark background (§5.5.1).

        Markers (radius 0.25-0.5 mm, i.e. 10.7-21 px across) move smoothly from frame to frame and
        stay inside the scanned part of the frame (3.5-16 mm from the top edge, |x| <= 10.5 mm),
        so heading always finds a clean all-dark line at the frame's top.
        """
        rng = np.random.default_rng(seed)
        # One lane per marker across the frame, amplitudes below half the lane spacing minus the
        # largest radius, so markers never touch and stay separate blobs after binarisation.
        lane = 18.0 / max(n_markers, 1)
        x0 = np.linspace(-9.0 + lane / 2, 9.0 - lane / 2, n_markers) + rng.uniform(-0.1, 0.1, n_markers)
        y0 = rng.uniform(8.5, 11.0, n_markers)
        ax = rng.uniform(0.2, 0.45, n_markers) * max(lane - 1.2, 0.0)
        ay = rng.uniform(0.5, 2.5, n_markers)
        phase = rng.uniform(0.0, 2 * np.pi, n_markers)
        radius = rng.uniform(0.25, 0.5, n_markers)
        markers: list[Marker] = []
        for k in range(n_frames):
            w = 2 * np.pi * k / 12.0 + phase
            for m in range(n_markers):
                x, y = _snap(x0[m] + ax[m] * np.cos(w[m]), y0[m] + ay[m] * np.sin(w[m]))
                markers.append(Marker(k, m, x, y, float(radius[m])))

        def render(k: int) -> np.ndarray:
            return render_markers([mk for mk in markers if mk.frame == k])

        return cls(generator=render, n_frames=n_frames, markers=markers)


_SHIFT = 4                    # cv2 fixed-point fraction bits: centres to 1/16 texel (0.73 µm)


def _snap(x_mm: float, y_mm: float) -> tuple[float, float]:
    """Round a centre to the fixed-point grid cv2 draws on, so the truth is exactly what is drawn."""
    s = float(1 << _SHIFT)
    cx = round(((x_mm + FRAME_W_MM / 2) / TEXEL_MM - 0.5) * s) / s
    cy = round((y_mm / TEXEL_MM - 0.5) * s) / s
    return (cx + 0.5) * TEXEL_MM - FRAME_W_MM / 2, (cy + 0.5) * TEXEL_MM


def render_markers(markers: Sequence[Marker]) -> np.ndarray:
    """Render anti-aliased white discs on black at texture resolution (uint8 ``(TEX_H, TEX_W)``)."""
    img = np.zeros((TEX_H, TEX_W), dtype=np.uint8)
    s = 1 << _SHIFT
    for mk in markers:
        # cv2 puts pixel centres on integer coordinates: texel j covers [j, j+1) * TEXEL_MM.
        cx = int(round(((mk.x_mm + FRAME_W_MM / 2) / TEXEL_MM - 0.5) * s))
        cy = int(round((mk.y_mm / TEXEL_MM - 0.5) * s))
        cv2.circle(img, (cx, cy), int(round(mk.radius_mm / TEXEL_MM * s)), 255, -1, cv2.LINE_AA, _SHIFT)
    return img
