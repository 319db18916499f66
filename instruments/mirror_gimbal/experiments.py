"""Experiments on the simulated gimbal (``instruments.md`` §4.3, §5): the tracking-rate limit.

A target circles the mirror at constant range, starting from rest on the detector's axis; the
``H`` axis tracks it (``TRACK``). The target is *lost* when the gimbal reports ``E40``. The limit
is the smallest circling rate that is lost, found by bisection. :func:`fixed_mirror_width`: the
fixed mirror a walk would need (Fig. 4.40).
"""

from __future__ import annotations

import math

import numpy as np
from mirrorlab.instruments.virtual_lab.experiments import bisect_limit, with_faults
from numpy.typing import ArrayLike

from .dynamics import AxisParams
from .model import MirrorGimbalModel


def loses_target(rate: float, params: AxisParams | None = None, seed: int = 0, range_mm: float = 3000.0,
                 sweep: float = math.radians(60.0), faults: tuple[str, ...] = ()) -> bool:
    """Whether tracking a target circling at ``rate`` (rad/s of detector angle) fails (``E40``).

    The target starts at ``-sweep/2`` from the camera direction, still for 1 s (the loop settles),
    then circles through ``sweep`` (rad) at ``range_mm``. ``faults`` are ``SIM:FAULT`` argument
    strings (``"BACKLASH H 0"``).

    Examples
    --------
    >>> loses_target(math.radians(5.0)), loses_target(math.radians(40.0))
    (False, True)
    """
    model = with_faults(MirrorGimbalModel(seed=seed, params=params), faults)
    model.execute(f"SIM:LOAD CIRCLE {-math.degrees(sweep) / 2:.6f} {math.degrees(rate):.6f} {range_mm:.3f} 1.0")
    model.execute("MODE H TRACK")
    end = 1.0 + sweep / rate
    while model.clock_ms / 1000.0 < end:
        model.advance(0.25)
        if "LOST_H" in model.flags:
            return True
    return False


def tracking_limit(params: AxisParams | None = None, seed: int = 0, lo: float = math.radians(2.0),
                   hi: float = math.radians(60.0), tol: float = math.radians(0.25),
                   faults: tuple[str, ...] = ()) -> float:
    """Smallest circling rate (rad/s) at which the target is lost, to within ``tol`` (bisection).

    Assumes tracking holds at ``lo`` and fails at ``hi``; raises ``ValueError`` otherwise.
    """
    return bisect_limit(lambda rate: loses_target(rate, params, seed, faults=faults), lo, hi, tol)


def fixed_mirror_width(camera: ArrayLike, centre: ArrayLike, points: ArrayLike, radius: float = 0.0) -> float:
    """Side (mm) of a fixed square mirror at ``centre`` facing ``camera`` that shows every one of ``points``.

    Each point's image is where the ray camera -> reflected point meets the mirror plane
    (:func:`~mirrorlab.instruments.virtual_lab.world.image_in_mirror`'s construction), widened by
    the footprint of a disc of ``radius`` mm; the side is the larger extent of those images along
    the mirror's horizontal and vertical axes, mm (Fig. 4.40's A-B).

    Examples
    --------
    >>> round(fixed_mirror_width([0, 0, 6000], [0, 0, 0], [[-1500, 0, 3000], [1500, 0, 3000]]), 3)
    2000.0
    """
    c, o = np.asarray(camera, dtype=float), np.asarray(centre, dtype=float)
    p = np.atleast_2d(np.asarray(points, dtype=float))
    n = (c - o) / np.linalg.norm(c - o)
    reflected = p - 2.0 * ((p - o) @ n)[:, None] * n
    ray = reflected - c
    s = ((o - c) @ n) / (ray @ n)
    x = c + s[:, None] * ray - o
    e1 = np.cross([0.0, 1.0, 0.0], n)
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(n, e1)
    foot = radius * s
    extents = [np.ptp(np.concatenate([x @ e - foot, x @ e + foot])) for e in (e1, e2)]
    return float(max(extents))
