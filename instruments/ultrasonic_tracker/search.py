"""The gradient search of the ultrasonic tracker (``instruments.md`` §2.5, eqs 4.4-4.8), pure functions.

The beam is deflected by ``delta`` in four directions a, b, c, d; the pressure differences give
the gradient of the echo pressure over the platform angles (theta1 about Y, theta2 about Z), and
the platform steps up it by ``h = min(h0, Kh / S_mean)`` (4.5, step inversely proportional to the
pressure). Angles rad; pressures in ADC counts.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]

#: Deflection directions in the tangent plane ``(dtheta1 cos theta2, dtheta2)``: c = +e1, d = -e1,
#: a = +e2, b = -e2, 60 deg apart as the hexagonal array allows (§2.5).
E1 = np.array([-math.sqrt(3.0) / 2.0, -0.5])
E2 = np.array([-math.sqrt(3.0) / 2.0, 0.5])
DIRECTIONS = {"A": E2, "B": -E2, "C": E1, "D": -E1}
QUANTUM = math.radians(80.0 / 256.0)     # 8-bit DAC over the +-40 deg platform range: 0.3125 deg
RANGE = math.radians(40.0)


def gradient(sa: float, sb: float, sc: float, sd: float, theta2: float) -> FloatArray:
    """(4.7)-(4.8): the ascent direction over ``(theta1, theta2)`` from the four pressures.

    ``dS/dtheta1 ~ -sqrt(3) / (2 cos theta2) (Sa - Sb + Sc - Sd)``, ``dS/dtheta2 ~ (Sa - Sb - Sc + Sd) / 2``.

    Examples
    --------
    >>> np.round(gradient(10, 10, 12, 8, 0.0), 4).tolist()      # stronger toward c = +e1
    [-3.4641, -2.0]
    """
    g1 = -math.sqrt(3.0) / (2.0 * math.cos(theta2)) * (sa - sb + sc - sd)
    g2 = 0.5 * (sa - sb - sc + sd)
    return np.array([g1, g2])


def step_length(mean_pressure: float, h0: float, kh: float) -> float:
    """``h = min(h0, Kh / S_mean)`` (rad): long steps far from the target, short ones near it.

    Examples
    --------
    >>> round(math.degrees(step_length(100.0, math.radians(2.5), math.radians(180.0))), 3)
    1.8
    >>> round(math.degrees(step_length(1.0, math.radians(2.5), math.radians(180.0))), 3)
    2.5
    """
    return h0 if mean_pressure <= 0 else min(h0, kh / mean_pressure)


def search_step(theta: FloatArray, pressures: tuple[float, float, float, float], h0: float,
                kh: float) -> tuple[FloatArray, float]:
    """(4.5): ``theta + h g / |g|``, quantised to 0.3125 deg and clipped to +-40 deg; returns (theta, h).

    Examples
    --------
    >>> th, h = search_step(np.zeros(2), (10, 10, 12, 8), math.radians(2.5), math.radians(180.0))
    >>> np.round(np.degrees(th), 4).tolist(), round(math.degrees(h), 2)
    ([-2.1875, -1.25], 2.5)
    """
    g = gradient(*pressures, float(theta[1]))
    h = step_length(float(np.mean(pressures)), h0, kh)
    norm = float(np.hypot(*g))
    new = theta + (h * g / norm if norm > 0 else 0.0)
    return quantise(new), h


def quantise(theta: FloatArray) -> FloatArray:
    """Platform set-points as the 8-bit DAC holds them: multiples of 0.3125 deg within +-40 deg.

    Examples
    --------
    >>> np.round(np.degrees(quantise(np.radians([1.0, -50.0]))), 4).tolist()
    [0.9375, -40.0]
    """
    return np.clip(np.round(np.asarray(theta, dtype=float) / QUANTUM) * QUANTUM, -RANGE, RANGE)


def platform_frame(theta1: float, theta2: float) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Array axis ``u0`` and unit tangents ``t1`` (d/dtheta1 / cos theta2), ``t2`` in the tracker frame.

    Tracker frame: ``x`` forward (the axis at rest), ``y`` up, ``z = x × y``. ``theta1`` turns about
    ``y``, ``theta2`` about ``z``.

    Examples
    --------
    >>> [(np.round(v, 6) + 0.0).tolist() for v in platform_frame(0.0, 0.0)]
    [[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]]
    """
    c1, s1, c2, s2 = math.cos(theta1), math.sin(theta1), math.cos(theta2), math.sin(theta2)
    u0 = np.array([c1 * c2, s2, -s1 * c2])
    t1 = np.array([-s1, 0.0, -c1])
    t2 = np.array([-c1 * s2, c2, s1 * s2])
    return u0, t1, t2


def direction_in_array(w: FloatArray, theta1: float, theta2: float) -> tuple[float, float]:
    """``(alpha, azimuth)`` of the unit direction ``w`` in the array plane at platform pose, rad.

    The array plane's azimuth is the tangent-plane angle minus 90 deg, so that the c-d steering
    axis of (4.3) (azimuth 120 deg) deflects along ``e1``.

    Examples
    --------
    >>> a, az = direction_in_array(np.array([1.0, 0.0, 0.0]), 0.0, 0.0)
    >>> round(a, 9)
    0.0
    """
    u0, t1, t2 = platform_frame(theta1, theta2)
    alpha = math.acos(float(np.clip(np.dot(w, u0), -1.0, 1.0)))
    tau1, tau2 = float(np.dot(w, t1)), float(np.dot(w, t2))
    return alpha, math.atan2(-tau1, tau2)


def lobe_azimuth(direction: str) -> float:
    """Array-plane azimuth (rad) toward which beam state ``direction`` (A-D) deflects.

    Examples
    --------
    >>> [round(math.degrees(lobe_azimuth(d)) % 360) for d in "ABCD"]
    [60, 240, 120, 300]
    """
    e = DIRECTIONS[direction]
    return math.atan2(e[1], e[0]) - math.pi / 2
