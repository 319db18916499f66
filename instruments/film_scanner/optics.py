"""Image formation of one sensor line: ``v_i = G E(x_i) (T ⊛ h_blur)(x_i, y) + noise`` (§1.4).

Everything is vectorised over the 512 pixels: the film is sampled on a small window of texture
rows around ``y``, weighted by the Gaussian blur along the feed, convolved with the same Gaussian
across, and interpolated at the (possibly shifted) pixel positions.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .film import FRAME_W_MM, PIXEL_MM, TEX_W, TEXEL_MM, Film
from .wire import PIXELS

#: Pixel centres on the film across the strip, mm: x_i = (i - 255.5) * 46.875 µm.
PIXEL_X_MM = (np.arange(PIXELS) - 255.5) * PIXEL_MM
_TEX_X = np.arange(TEX_W, dtype=np.float64)

REFERENCE_CLOCK_HZ = 73_000.0   # the clock the thesis chose; exposure is relative to it


@dataclass(frozen=True)
class Optics:
    """Intrinsic (not fault) parameters of the optical chain; defaults are simulator choices.

    Attributes
    ----------
    gain
        Comparator counts for fully clear film at 73 kHz (linear in exposure, saturates at 255).
    lens_blur_mm
        Gaussian sigma of the in-focus lens blur on the film, mm.
    defocus_gain
        Extra blur sigma per unit focus error (object side, ~f/2 macro lens at m = 0.597).
    sensor_noise
        Read noise of the video signal, comparator counts (1 sigma).
    """

    gain: float = 250.0
    lens_blur_mm: float = 0.015
    defocus_gain: float = 0.1
    sensor_noise: float = 2.0

    def blur_sigma_mm(self, defocus_mm: float) -> float:
        """Total blur sigma for a focus error ``defocus_mm`` (mm)."""
        return float(np.hypot(self.lens_blur_mm, self.defocus_gain * defocus_mm))


def _gaussian(sigma_texels: float) -> tuple[np.ndarray, np.ndarray]:
    half = max(1, int(np.ceil(4.0 * sigma_texels)))
    offsets = np.arange(-half, half + 1, dtype=np.float64)
    w = np.exp(-0.5 * (offsets / sigma_texels) ** 2)
    return offsets, w / w.sum()


def blurred_transmittance(film: Film, y_mm: float, dx_mm: float, blur_mm: float) -> np.ndarray:
    """``(T ⊛ h_blur)`` at the 512 pixel positions of a line at strip position ``y_mm``.

    Parameters
    ----------
    y_mm
        Strip position seen by the sensor line, mm.
    dx_mm
        Lateral image shift (vibration, rail), mm; positive moves the image to lower pixel indices.
    blur_mm
        Gaussian sigma on the film, mm (floored at half a texel so the window is well sampled).
    """
    sigma = max(blur_mm / TEXEL_MM, 0.5)
    offsets, w = _gaussian(sigma)
    rows = film.rows(y_mm + offsets * TEXEL_MM)                 # (2m+1, TEX_W)
    line = w.astype(np.float32) @ rows                          # blur along the feed
    half = (offsets.size - 1) // 2
    padded = np.pad(line.astype(np.float64), half, mode="edge")
    line = np.convolve(padded, w, mode="valid")                 # blur across (symmetric kernel)
    cols = (PIXEL_X_MM + dx_mm + FRAME_W_MM / 2) / TEXEL_MM - 0.5
    return np.interp(cols, _TEX_X, line)


def illumination(falloff: float) -> np.ndarray:
    """Back-light profile E(x_i): 1 at the centre, ``1 - falloff`` at the frame edges."""
    return 1.0 - falloff * (PIXEL_X_MM / (FRAME_W_MM / 2)) ** 2


def video_counts(trans: np.ndarray, clock_hz: float, optics: Optics, illum_falloff: float,
                 film_noise: float, rng: np.random.Generator) -> np.ndarray:
    """Video signal in comparator counts (0-255) for one read of a line.

    Exposure is the integration time 512 / f_clk, so the signal scales with 73 kHz / f_clk.
    ``film_noise`` adds density noise (sigma, in transmittance) and dust: bright specks on a
    fraction ``film_noise / 20`` of the pixels (the background noise of Fig. 5.16).
    """
    t = trans
    if film_noise > 0:
        t = t + rng.normal(0.0, film_noise, t.shape)
        specks = rng.random(t.shape) < film_noise / 20.0
        t = np.where(specks, 1.0, t)
    v = optics.gain * (REFERENCE_CLOCK_HZ / clock_hz) * illumination(illum_falloff) * t
    v = v + rng.normal(0.0, optics.sensor_noise, v.shape)
    return np.clip(v, 0.0, 255.0)
