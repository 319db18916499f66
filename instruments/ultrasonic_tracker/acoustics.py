"""Acoustics of the 12-element 40 kHz array (``instruments.md`` §2.2-§2.4), as pure functions.

Single-element directivity (4.1), the array layout of §2.2 (inner ring of 6 at ``d``, outer ring
of 6 at ``sqrt(3) d``), the corrected electronic steering (4.3) and echo timing at the speed of
sound of the air temperature (1.8). Lengths mm, angles rad, times s, frequency Hz.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import brentq
from scipy.special import j1

FloatArray = NDArray[np.float64]

FREQUENCY = 40_000.0             # Hz
PITCH = 9.5                      # d: touching 9.5 mm plates, mm
EFFECTIVE_RADIUS = 5.0           # a_eff: reproduces the single element's 37 deg (spec §6.3), mm
STEER_AZIMUTH = math.radians(120.0)   # the c-d axis of (4.3)
AIR_ABSORPTION_NP = 1.3 / 8.686  # 1.3 dB/m at 40 kHz in Np/m (pressure), per m (spec §6.16)


def speed_of_sound(celsius: float) -> float:
    """``c = 331.5 + 0.607 t`` (1.8), mm/s.

    Examples
    --------
    >>> round(speed_of_sound(20.6) / 1000.0, 1)
    344.0
    """
    return (331.5 + 0.607 * celsius) * 1000.0


def round_trip(range_mm: ArrayLike, celsius: float = 20.6) -> FloatArray:
    """Echo arrival time ``2 r / c`` of a reflector at ``range_mm``, s.

    Examples
    --------
    >>> round(float(round_trip(1300.0)) * 1000.0, 2)        # 7.6 ms at 1.3 m (§2.4)
    7.56
    """
    return 2.0 * np.asarray(range_mm, dtype=float) / speed_of_sound(celsius)


def wavenumber(celsius: float = 20.6, frequency: float = FREQUENCY) -> float:
    """``k = 2 pi f / c``, rad/mm (lambda = 8.60 mm at 344 m/s)."""
    return 2.0 * math.pi * frequency / speed_of_sound(celsius)


def element_directivity(alpha: ArrayLike, k: float, radius: float = EFFECTIVE_RADIUS) -> FloatArray:
    """Circular piston (4.1): ``|2 J1(k a sin alpha) / (k a sin alpha)|`` at ``alpha`` (rad) off axis.

    Examples
    --------
    >>> k = wavenumber()
    >>> round(float(element_directivity(math.radians(37.3), k)), 2)
    0.5
    """
    x = k * radius * np.sin(np.asarray(alpha, dtype=float))
    safe = np.where(np.abs(x) < 1e-12, 1.0, x)
    return np.where(np.abs(x) < 1e-12, 1.0, np.abs(2.0 * j1(safe) / safe))


@functools.cache   # the layout is asked for at every emission; read-only, so sharing it is safe
def element_positions(pitch: float = PITCH) -> FloatArray:
    """The 12 elements in the array plane, ``(12, 2)`` mm: 6 at ``d`` (30, 90, ... deg), 6 at ``sqrt(3) d`` (0, 60, ...).

    Examples
    --------
    >>> p = element_positions()
    >>> np.round(np.hypot(*p.T), 3).tolist()[:7]
    [9.5, 9.5, 9.5, 9.5, 9.5, 9.5, 16.454]
    """
    inner = np.radians(30.0 + 60.0 * np.arange(6))
    outer = np.radians(60.0 * np.arange(6))
    rings = [(pitch, inner), (math.sqrt(3.0) * pitch, outer)]
    positions = np.concatenate([r * np.stack([np.cos(a), np.sin(a)], axis=1) for r, a in rings])
    positions.flags.writeable = False
    return positions


@functools.cache
def steering_groups(azimuth: float = STEER_AZIMUTH, pitch: float = PITCH) -> NDArray[np.int64]:
    """Group index ``n_i = round(r_i . e / (sqrt(3)/2 d))`` in -2..2 of each element for steering axis ``e``.

    Examples
    --------
    >>> np.bincount(steering_groups() + 2).tolist()      # groups L1..L5 of 1, 4, 2, 4, 1 elements
    [1, 4, 2, 4, 1]
    """
    e = np.array([math.cos(azimuth), math.sin(azimuth)])
    groups = np.rint(element_positions(pitch) @ e / (math.sqrt(3.0) / 2.0 * pitch)).astype(np.int64)
    groups.flags.writeable = False
    return groups


def array_directivity(alpha: ArrayLike, azimuth: ArrayLike, k: float, psi: float = 0.0,
                      steer_azimuth: float = STEER_AZIMUTH, radius: float = EFFECTIVE_RADIUS,
                      pitch: float = PITCH) -> FloatArray:
    """Pressure directivity of the steered array, (4.2)/(4.3) corrected: ``D1(alpha) |sum_i exp(j(k r_i.u - phi_i))| / 12``.

    Parameters
    ----------
    alpha, azimuth
        Direction: angle off the array axis and its azimuth in the array plane, rad (broadcast).
    k
        Wavenumber, rad/mm.
    psi
        Steering phase step, rad; element phase ``phi_i = -n_i psi``. The main lobe moves toward
        ``-e`` (the side of the group with phase ``+2 psi``) by ``arcsin(2 psi / (sqrt(3) k d))``.
    steer_azimuth
        Azimuth of the steering axis ``e``, rad (the other axes: +-60 deg).

    Examples
    --------
    >>> k = wavenumber()
    >>> round(float(array_directivity(0.0, 0.0, k)), 6)
    1.0
    """
    a, az = np.broadcast_arrays(np.asarray(alpha, dtype=float), np.asarray(azimuth, dtype=float))
    u = np.stack([np.sin(a) * np.cos(az), np.sin(a) * np.sin(az)], axis=-1)
    phase = k * u @ element_positions(pitch).T + steering_groups(steer_azimuth, pitch) * psi
    factor = np.abs(np.exp(1j * phase).mean(axis=-1))
    return element_directivity(a, k, radius) * factor


def half_angle(directivity: Callable[[FloatArray], FloatArray], level: float = 0.5,
               hi: float = math.radians(30.0)) -> float:
    """First angle (rad) where a vectorised directivity ``directivity(alpha)`` falls to ``level`` (-6 dB = 0.5).

    Examples
    --------
    >>> k = wavenumber()
    >>> round(math.degrees(half_angle(lambda a: array_directivity(a, 0.0, k))), 1)   # §2.2: 8.9 deg
    8.9
    """
    grid = np.linspace(0.0, hi, 3001)
    values = np.asarray(directivity(grid), dtype=float)
    below = int(np.argmax(values < level))
    return float(brentq(lambda x: float(directivity(x)) - level, grid[below - 1], grid[below]))
