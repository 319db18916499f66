"""Echoes of the ultrasonic tracker (``instruments.md`` §2.4, §2.7), as pure functions.

Pressure of one scatterer for a beam state: ``A D_psi(u) D_rx(u) exp(-2 alpha r) / r^2`` (``r`` in m,
``alpha`` in Np/m), arriving at ``2 r / c``; identification of the target echo from two emissions
(arrivals common to both); the peak-hold pressure gated at the identified time. Lengths mm,
times s, angles rad, pressures relative (1 = the 130 mm sphere on axis at 1 m, no absorption).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .acoustics import AIR_ABSORPTION_NP, array_directivity, element_directivity, speed_of_sound, wavenumber
from .search import direction_in_array, lobe_azimuth

FloatArray = NDArray[np.float64]
RX_RADIUS = 2.0                  # receivers: small, broad combined directivity (§2.4), mm


def beam_pattern(alpha: float, azimuth: float, k: float, beam: str, psi: float) -> float:
    """Transmit directivity for beam state ``beam`` (``"0"`` undeflected, ``"A"``-``"D"``) at ``psi`` rad.

    A deflection toward array azimuth ``beta`` uses the steering axis ``beta + 180 deg`` with
    ``+psi`` (the lobe goes to the side of the ``+2 psi`` group, §2.3).

    Examples
    --------
    >>> k = wavenumber()
    >>> round(beam_pattern(0.0, 0.0, k, "0", 0.0), 6)
    1.0
    >>> beam_pattern(0.0, 0.0, k, "C", math.radians(45.0)) < 1.0
    True
    """
    if beam == "0" or psi == 0.0:
        return float(array_directivity(alpha, azimuth, k))
    steer = lobe_azimuth(beam) + math.pi
    return float(array_directivity(alpha, azimuth, k, psi, steer))


def echo_arrivals(directions: ArrayLike, ranges: ArrayLike, amplitudes: ArrayLike, theta: ArrayLike,
                  beam: str, psi: float, celsius: float) -> tuple[FloatArray, FloatArray]:
    """Arrival times (s) and pressures of scatterers for the platform at ``theta`` (rad).

    Parameters
    ----------
    directions
        Unit directions of the scatterers in the tracker frame, ``(S, 3)``.
    ranges
        Their ranges, mm ``(S,)``.
    amplitudes
        Their echo strengths ``A`` (1 = the 130 mm sphere; ~ sphere radius), ``(S,)``.
    theta
        Platform angles ``(theta1, theta2)``, rad.
    beam, psi
        Beam state and steering phase step (rad).
    celsius
        Air temperature: speed of sound and wavenumber.

    Examples
    --------
    >>> t, p = echo_arrivals([[1.0, 0.0, 0.0]], [1300.0], [1.0], [0.0, 0.0], "0", 0.0, 20.6)
    >>> round(float(t[0]) * 1000, 2), round(float(p[0]), 4)     # 7.56 ms; 1/1.3^2 times exp(-2 x 0.150 x 1.3)
    (7.56, 0.401)
    """
    k = wavenumber(celsius)
    w = np.atleast_2d(np.asarray(directions, dtype=float))
    r = np.asarray(ranges, dtype=float)
    out = np.zeros(len(r))
    for i, wi in enumerate(w):
        alpha, az = direction_in_array(wi / np.linalg.norm(wi), float(theta[0]), float(theta[1]))
        if alpha >= math.pi / 2:
            continue                                   # behind the array
        out[i] = beam_pattern(alpha, az, k, beam, psi) * float(element_directivity(alpha, k, RX_RADIUS))
    metres = r / 1000.0
    pressure = np.asarray(amplitudes, dtype=float) * out * np.exp(-2.0 * AIR_ABSORPTION_NP * metres) / metres**2
    return 2.0 * r / speed_of_sound(celsius), pressure


def common_arrivals(first: ArrayLike, second: ArrayLike, tolerance: float) -> FloatArray:
    """Arrival times of ``first`` that ``second`` also holds within ``tolerance`` (s), sorted.

    Examples
    --------
    >>> common_arrivals([0.004, 0.0076, 0.011], [0.0061, 0.00765, 0.012], 1e-4).tolist()
    [0.0076]
    """
    a, b = np.sort(np.asarray(first, dtype=float)), np.asarray(second, dtype=float)
    if a.size == 0 or b.size == 0:
        return np.zeros(0)
    return a[np.abs(a[:, None] - b[None, :]).min(axis=1) <= tolerance]


def gated_pressure(times: ArrayLike, pressures: ArrayLike, gate: float, width: float) -> float:
    """Peak-hold reading gated at ``gate`` (s): the pressures arriving within ``+-width`` add.

    Examples
    --------
    >>> gated_pressure([0.0076, 0.0078, 0.012], [300.0, 50.0, 80.0], 0.0076, 0.0005)
    350.0
    """
    t, p = np.asarray(times, dtype=float), np.asarray(pressures, dtype=float)
    return float(p[np.abs(t - gate) <= width].sum())
