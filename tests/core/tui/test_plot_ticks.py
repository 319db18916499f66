"""The console's plots draw the same ticks whatever the data's last bit (a snapshot failed on ``-0.0``
against ``0.0``: plotext labels the data's minimum, -1e-17 on one CPU and 0 on another)."""

from __future__ import annotations

import numpy as np
import pytest
from mirrorlab.core.tui.plots import Series, draw
from rich.text import Text
from textual_plotext.plot import Plot


def render(x: np.ndarray, y: np.ndarray) -> str:
    """The plots screen's drawing of one marker's path, as plain text (78 x 18 characters)."""
    plt = Plot()
    plt.plotsize(78, 18)
    draw(plt, Series("trajectories", "/results/run/points", "x (mm)", "y (mm)", [(x, y, "marker 0")]))
    return Text.from_ansi(plt.build()).plain


@pytest.mark.parametrize("tiny", [-1e-17, 1e-17, -1e-300])
def test_ticks_do_not_depend_on_rounding_and_never_read_negative_zero(tiny: float) -> None:
    x = np.linspace(0.0, 98.0, 60)
    y = 48.0 * (x / 98.0) ** 2
    exact = render(x, y)
    x[0] = y[0] = tiny                          # the minimum, off zero by a rounding
    assert render(x, y) == exact
    rows = exact.splitlines()
    axis = next(i for i, row in enumerate(rows) if "└" in row)
    y_labels = [row.split("┤")[0].strip() for row in rows if "┤" in row]
    x_labels = rows[axis + 1].split()
    assert float(y_labels[-1]) == float(x_labels[0]) == 0.0    # the lowest ticks, at the data's minimum
    assert not any(label.startswith("-") for label in y_labels + x_labels)
