"""The cylindrical-lens line sensor of the optical direction detector (``instruments.md`` §3.2).

Pure functions: pixel geometry, the summing projection of lit spheres onto the sensor axis, the
video signal (exposure set by the clock, blur, noise, saturation), binarisation, runs of 1s and
the mark ``(m, d)`` of a run. Angles in rad, times in s, lengths in mm, signal in 8-bit counts.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.ndimage import gaussian_filter1d

FloatArray = NDArray[np.float64]

PIXELS = 512
PITCH_MM = 0.028                 # photodiode pitch
FOCAL_MM = 44.0                  # cylindrical lens focal length
SENSOR_HALF_MM = 7.2             # half of the 14.4 mm sensor
LENS_HALF_MM = 20.0              # half of the 40 mm lens length (the summing direction)
CENTRE_PX = 255.5                # pixel coordinate of the optical axis
FIELD_ALONG = 2 * math.atan(SENSOR_HALF_MM / FOCAL_MM)    # detection range, rad (18.6 deg)
FIELD_ACROSS = 2 * math.atan(LENS_HALF_MM / FOCAL_MM)     # summing range, rad (49 deg)
MIN_CLOCK_HZ = 1_000
MAX_CLOCK_HZ = 307_692           # 6502 host loop: 26 machine cycles per byte of 8 px at 1 MHz
SATURATION = 255.0


def pixel_angles(pixels: ArrayLike | None = None) -> FloatArray:
    """Viewing angle of pixels along the sensor, ``arctan((i - 255.5) * 0.028 / 44)``, rad.

    Examples
    --------
    >>> a = pixel_angles()
    >>> round(math.degrees(a[511]), 2), round(math.degrees(a[256] - a[255]), 4)   # 0.0365 deg/px
    (9.23, 0.0365)
    >>> round(math.degrees(FIELD_ALONG), 1), round(math.degrees(FIELD_ACROSS), 1)  # 14.4 mm, 40 mm at f = 44
    (18.6, 48.9)
    """
    i = np.arange(PIXELS, dtype=float) if pixels is None else np.asarray(pixels, dtype=float)
    return np.arctan((i - CENTRE_PX) * PITCH_MM / FOCAL_MM)


def angle_to_pixel(angle: ArrayLike) -> FloatArray:
    """Pixel coordinate (continuous, 255.5 on the axis) at which a direction ``angle`` (rad) images.

    Examples
    --------
    >>> round(float(angle_to_pixel(math.atan(0.16))), 1)       # 160 mm off axis at 1 m
    506.9
    """
    return CENTRE_PX + np.tan(np.asarray(angle, dtype=float)) * FOCAL_MM / PITCH_MM


def sphere_projection(angles: ArrayLike, centre: ArrayLike, half_angle: ArrayLike,
                      radiance: ArrayLike, gradient: float = 0.0) -> FloatArray:
    """Summing projection of lit discs: radiance integrated across the sensor axis, rad.

    A sphere seen at ``centre`` (rad along the sensor) with angular radius ``half_angle`` is a disc
    whose projection is its chord length ``2 sqrt(a^2 - (phi - c)^2)`` (rad) times its radiance.

    Parameters
    ----------
    angles
        Viewing angles of the pixels, rad, shape ``(P,)``.
    centre, half_angle, radiance
        Per disc, shape ``(S,)``: centre angle (rad), angular radius (rad), radiance (arbitrary).
    gradient
        Lighting gradient across each disc (``SIDELIGHT``): radiance times ``1 + gradient * u``,
        ``u`` from -1 to 1 across the disc.

    Examples
    --------
    >>> p = sphere_projection([0.0, 0.05, 0.2], [0.0], [0.1], [1.0])
    >>> np.round(p, 4).tolist()
    [0.2, 0.1732, 0.0]
    """
    phi = np.asarray(angles, dtype=float)[:, None]
    c, a = np.asarray(centre, dtype=float)[None], np.asarray(half_angle, dtype=float)[None]
    u = (phi - c) / a
    chord = 2.0 * a * np.sqrt(np.clip(1.0 - u**2, 0.0, None))
    light = np.clip(1.0 + gradient * np.clip(u, -1.0, 1.0), 0.0, None)
    return (chord * light * np.asarray(radiance, dtype=float)[None]).sum(axis=1)


def video_signal(projection: ArrayLike, clock_hz: float, gain: float, blur_px: float, noise: float,
                 rng: np.random.Generator) -> FloatArray:
    """Comparator counts of the 512 pixels: exposure ``512 / clock_hz`` s, blur, noise, saturation.

    Parameters
    ----------
    projection
        Summed scene radiance per pixel (:func:`sphere_projection` plus background), rad.
    clock_hz
        Sensor clock; the integration time is one scan, ``512 / clock_hz`` s.
    gain
        Counts per unit projection and second of exposure.
    blur_px
        Gaussian defocus sigma, px (0 = sharp).
    noise
        Read noise, counts (1 sigma).
    rng
        Random generator of the simulator.
    """
    v = np.asarray(projection, dtype=float) * gain * PIXELS / clock_hz
    if blur_px > 0:
        v = gaussian_filter1d(v, blur_px, mode="nearest")
    if noise > 0:
        v = v + rng.normal(0.0, noise, v.shape)
    return np.clip(v, 0.0, SATURATION)


def find_runs(bits: ArrayLike) -> NDArray[np.int64]:
    """Runs of 1s as ``(n, 2)`` inclusive pixel edges ``[e1, e2]``.

    Examples
    --------
    >>> find_runs([0, 1, 1, 0, 0, 1, 1, 1]).tolist()
    [[1, 2], [5, 7]]
    """
    b = np.concatenate([[0], np.asarray(bits, dtype=np.int8), [0]])
    edges = np.flatnonzero(np.diff(b))
    return edges.reshape(-1, 2) - np.array([0, 1])


def mark_of_run(run: ArrayLike) -> tuple[float, int]:
    """Position ``m = (e1 + e2) / 2`` (half-pixel steps) and size ``d = e2 - e1 + 1`` of a run.

    Examples
    --------
    >>> mark_of_run([250, 261])
    (255.5, 12)
    """
    e1, e2 = (int(e) for e in run)
    return (e1 + e2) / 2.0, e2 - e1 + 1


def select_run(runs: NDArray[np.int64], rule: str, previous_m: float | None = None) -> int | None:
    """Index of the run chosen by ``rule`` (``WIDEST``, ``NEAREST`` to ``previous_m``, ``FIRST``).

    ``None`` when there is no run, or for ``WIDEST`` when two or more runs tie for the widest
    (the ``E31 multiple`` case).

    Examples
    --------
    >>> runs = np.array([[10, 20], [100, 130], [300, 330]])
    >>> select_run(runs, "WIDEST") is None, select_run(runs, "NEAREST", 290.0), select_run(runs, "FIRST")
    (True, 2, 0)
    """
    if len(runs) == 0:
        return None
    widths = runs[:, 1] - runs[:, 0]
    if rule == "FIRST":
        return 0
    if rule == "NEAREST" and previous_m is not None:
        return int(np.argmin(np.abs(runs.mean(axis=1) - previous_m)))
    best = np.flatnonzero(widths == widths.max())
    return int(best[0]) if len(best) == 1 else None


def adapt_threshold(threshold: int, d: int, d_ref: int, step: int) -> int:
    """One step of the adaptive threshold (§3.3 Step 4): ``T + dT sgn(d - d_ref)``, clamped to 0..255.

    Examples
    --------
    >>> adapt_threshold(120, 30, 25, 4), adapt_threshold(2, 10, 25, 4), adapt_threshold(9, 25, 25, 4)
    (124, 0, 9)
    """
    return int(np.clip(threshold + step * np.sign(d - d_ref), 0, 255))
