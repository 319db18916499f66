"""The turntable experiment of §3.4 (Fig. 4.35) on a recorded trace: a sinusoid of known period.

Pure functions on recorded arrays (times s, mark position px, mark size px).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from mirrorlab.instruments.virtual_lab.line_sensor.sensor import PIXELS
from numpy.typing import ArrayLike


@dataclass(frozen=True)
class SinusoidFit:
    """Least-squares sinusoid of a known period through a trace.

    Attributes
    ----------
    amplitude : px. centre : px. phase : rad (of ``sin``). rms : residual, px.
    sample_period : mean time between samples, s. samples_per_cycle : period / sample period.
    used : samples fitted (marks not cut by the sensor's ends).
    """

    amplitude: float
    centre: float
    phase: float
    rms: float
    sample_period: float
    samples_per_cycle: float
    used: int


def uncut(m: ArrayLike, d: ArrayLike) -> np.ndarray:
    """Which marks ``m`` (px) of size ``d`` (px) are whole: a run, not touching the sensor's ends.

    Examples
    --------
    >>> uncut([255.5, 20.0, np.nan], [40.0, 60.0, np.nan]).tolist()
    [True, False, False]
    """
    mm, dd = np.asarray(m, dtype=float), np.asarray(d, dtype=float)
    with np.errstate(invalid="ignore"):
        return ~np.isnan(mm) & (mm - dd / 2 > 0.5) & (mm + dd / 2 < PIXELS - 1.5)


def fit_sinusoid(t: ArrayLike, m: ArrayLike, d: ArrayLike, period: float) -> SinusoidFit:
    """Fit ``centre + amplitude sin(2 pi t / period + phase)`` to marks ``m`` (px) at times ``t`` (s).

    Marks without a run (NaN) or whose run ``[m - d/2, m + d/2]`` touches the sensor's ends (the
    centre of a cut run is biased) are left out.

    Examples
    --------
    >>> t = np.arange(0, 5.52, 0.0788)
    >>> fit = fit_sinusoid(t, 255.5 + 251.4 * np.sin(2 * np.pi * t / 1.84 + 0.3), np.full(t.size, 40.0), 1.84)
    >>> round(fit.amplitude, 6), round(fit.centre, 6), round(fit.phase, 6), round(fit.samples_per_cycle, 1)
    (251.4, 255.5, 0.3, 23.4)
    """
    tt, mm, dd = (np.asarray(x, dtype=float) for x in (t, m, d))
    inside = uncut(mm, dd)
    w = 2.0 * math.pi / period
    basis = np.stack([np.sin(w * tt), np.cos(w * tt), np.ones_like(tt)], axis=1)[inside]
    (a, b, c), *_ = np.linalg.lstsq(basis, mm[inside], rcond=None)
    residual = mm[inside] - basis @ np.array([a, b, c])
    step = float(np.diff(tt).mean())
    return SinusoidFit(float(math.hypot(a, b)), float(c), float(math.atan2(b, a)),
                       float(np.sqrt(np.mean(residual**2))), step, period / step, int(inside.sum()))
