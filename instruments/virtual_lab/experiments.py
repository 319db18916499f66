"""Helpers of the experiments run on the simulated trackers (``instruments.md`` §5).

:func:`bisect_limit`: the smallest target rate at which a tracker loses its target, by bisection,
given the experiment that says whether one rate is lost (each tracker has its own).
:func:`with_faults`: a model with ``SIM:FAULT`` settings, for an experiment under faults.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable
from typing import TypeVar

from mirrorlab.core.devices import LineSimulator

__all__ = ["bisect_limit", "with_faults"]

M = TypeVar("M", bound=LineSimulator)


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


def with_faults(model: M, faults: Iterable[str]) -> M:
    """``model`` after ``SIM:FAULT <fault>`` for each of ``faults`` (argument strings such as ``"BACKLASH H 0"``).

    Raises
    ------
    ValueError
        The model refused one: its error reply is named.

    Examples
    --------
    >>> with_faults(LineSimulator(), ["LEAK 1"])
    Traceback (most recent call last):
    ...
    ValueError: SIM:FAULT LEAK 1: ERR E03 unknown fault LEAK; known: -
    """
    for fault in faults:
        reply = model.execute(f"SIM:FAULT {fault}")
        if reply != ["OK"]:
            raise ValueError(f"SIM:FAULT {fault}: {reply[-1]}")
    return model
