"""Axis ticks of the console's plots, labelled here instead of by plotext.

plotext puts its ticks at the data's minimum, maximum and evenly between, and labels them from
their values: a minimum of -1e-17 on one CPU and 0.0 on another reads ``-0.0`` against ``0.0`` (a
snapshot test failed on exactly that), and ticks that happen to be whole numbers switch format
(``48`` against ``48.0``) when a limit is off by one rounding. The ticks stay where plotext puts
them; their labels get the decimals that the tick *spacing* needs (not the values' digits), and a
label that rounds to zero is ``0``, never ``-0``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike

if TYPE_CHECKING:
    from textual_plotext.plot import Plot

__all__ = ["X_TICKS", "Y_TICKS", "data_range", "even_ticks", "label", "set_ticks"]

#: Ticks on the x and the y axis (plotext's defaults).
X_TICKS, Y_TICKS = 5, 7
#: Relative slack of the choice of decimals: far above rounding (1e-16), so that a spacing of
#: exactly 0.05 and one a rounding below it get the same decimals.
SLACK = 1e-9


def data_range(values: Sequence[ArrayLike]) -> tuple[float, float]:
    """Smallest and largest finite value of all ``values``; a single value ``v`` gives ``v ± |v|/2``
    (``-1, 1`` for zero or no value), so that an axis always has a width."""
    flat = np.concatenate([np.ravel(np.asarray(v, dtype=float)) for v in values]) if len(values) else np.empty(0)
    finite = flat[np.isfinite(flat)]
    if finite.size == 0:
        return -1.0, 1.0
    lo, hi = float(finite.min()), float(finite.max())
    if lo == hi:
        half = abs(lo) / 2 or 1.0
        return lo - half, hi + half
    return lo, hi


def label(value: float, decimals: int) -> str:
    """``value`` with ``decimals`` decimals; a value that rounds to zero is ``0``, never ``-0``.

    Examples
    --------
    >>> label(-1e-17, 1), label(-0.04, 1), label(-0.06, 1), label(48.0, 0)
    ('0.0', '0.0', '-0.1', '48')
    """
    text = f"{value:.{decimals}f}"
    return text.lstrip("-") if float(text) == 0.0 else text


def even_ticks(lo: float, hi: float, count: int) -> tuple[list[float], list[str]]:
    """``count`` ticks from ``lo`` to ``hi`` evenly spaced (plotext's), and their labels.

    The labels have the decimals that tell ticks one spacing apart (as plotext: the first decimal
    of the spacing, and one more), whatever the values.

    Examples
    --------
    >>> even_ticks(-1e-17, 98.0, 5)[1]
    ['0.0', '24.5', '49.0', '73.5', '98.0']
    >>> even_ticks(0.0, 48.0, 7)[1] == even_ticks(-1e-17, 48.0 + 1e-14, 7)[1]
    True
    >>> even_ticks(-0.013, 0.031, 5)[1]
    ['-0.013', '-0.002', '0.009', '0.020', '0.031']
    """
    step = (hi - lo) / (count - 1)
    decimals = max(0, math.ceil(-math.log10(2 * step) - SLACK)) + 1
    values = [lo + k * step for k in range(count - 1)] + [hi]
    return values, [label(v, decimals) for v in values]


def set_ticks(plt: Plot, x: Sequence[ArrayLike], y: Sequence[ArrayLike]) -> None:
    """Set the axes of the plotext figure ``plt`` to the range of the data ``x`` and ``y`` (one
    array per line) and their ticks to :func:`even_ticks`."""
    for values, limits, ticks, count in ((x, plt.xlim, plt.xticks, X_TICKS), (y, plt.ylim, plt.yticks, Y_TICKS)):
        lo, hi = data_range(values)
        limits(lo, hi)
        ticks(*even_ticks(lo, hi, count))
