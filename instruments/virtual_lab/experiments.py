"""Helpers of the experiments run on the simulated trackers (``instruments.md`` §5).

:func:`bisect_limit`: the smallest target rate at which a tracker loses its target, by bisection,
given the experiment that says whether one rate is lost (each tracker has its own).
"""

from __future__ import annotations

import math
from collections.abc import Callable

__all__ = ["bisect_limit"]


def bisect_limit(loses: Callable[[float], bool], lo: float, hi: float, tol: float) -> float:
    """Smallest rate (rad/s) at which ``loses(rate)`` is true, to within ``tol`` (bisection).

    Assumes tracking holds at ``lo`` and fails at ``hi``; raises ``ValueError`` otherwise.

    Examples
    --------
    >>> round(math.degrees(bisect_limit(lambda rate: rate > math.radians(15.0), math.radians(2.0),
    ...                                 math.radians(60.0), math.radians(0.25))), 1)
    15.0
    """
    if loses(lo) or not loses(hi):
        raise ValueError(f"tracking limit not within {math.degrees(lo):g}..{math.degrees(hi):g} deg/s")
    while hi - lo > tol:
        mid = (lo + hi) / 2
        if loses(mid):
            hi = mid
        else:
            lo = mid
    return (lo + hi) / 2
