"""PNG figures of the tracker experiments (matplotlib, Agg canvas; no global pyplot state).

:func:`plot_traces` draws curves on one or more panels sharing nothing but the file: every panel
has a title, axis labels with units and a legend (to the right of the panel: tracker traces fill
their panels, so a legend inside would cover data).
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure
from mirrorlab.core import save_figure
from numpy.typing import ArrayLike

__all__ = ["Panel", "Trace", "plot_traces", "traces_figure"]

#: z-order of an ``on_top`` trace: above lines and markers (2), below the legend (5).
ON_TOP = 3.0


@dataclass(frozen=True)
class Trace:
    """One curve: ``x``, ``y`` (already in the panel's units), its legend ``label`` and matplotlib ``style``.

    ``size`` is the marker size (points); ``on_top`` draws the trace above the others of its panel
    (e.g. a single target point that the data would hide).
    """

    x: ArrayLike
    y: ArrayLike
    label: str
    style: str = "-"
    size: float = 3.0
    on_top: bool = False


@dataclass(frozen=True)
class Panel:
    """One set of axes: ``title``, ``xlabel`` and ``ylabel`` (with units), its traces; ``equal``: same scale on x and y."""

    title: str
    xlabel: str
    ylabel: str
    traces: Sequence[Trace] = field(default_factory=tuple)
    equal: bool = False


def plot_traces(path: os.PathLike[str] | str, panels: Sequence[Panel], title: str = "") -> Path:
    """Write :func:`traces_figure` to the PNG file ``path``; return its path.

    Examples
    --------
    >>> import tempfile
    >>> t = np.linspace(0, 1, 20)
    >>> p = plot_traces(os.path.join(tempfile.mkdtemp(), "f.png"),
    ...                 [Panel("a line", "time (s)", "angle (deg)", [Trace(t, 2 * t, "2 t")])], "demo")
    >>> p.stat().st_size > 0
    True
    """
    return save_figure(traces_figure(panels, title), path)


def traces_figure(panels: Sequence[Panel], title: str = "") -> Figure:
    """The ``panels``, one above the other, each with its title, axis labels and legend."""
    fig = Figure(figsize=(8, 3.2 * len(panels) + 0.6), layout="constrained")
    axes = np.atleast_1d(fig.subplots(len(panels), 1))
    for ax, panel in zip(axes, panels):
        for trace in panel.traces:
            ax.plot(np.asarray(trace.x, float), np.asarray(trace.y, float), trace.style, lw=1.0, ms=trace.size,
                    label=trace.label, zorder=ON_TOP if trace.on_top else None)
        ax.set_title(panel.title, fontsize=10)
        ax.set_xlabel(panel.xlabel)
        ax.set_ylabel(panel.ylabel)
        if panel.equal:
            ax.set_aspect("equal", adjustable="datalim")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0)   # beside the data
    if title:
        fig.suptitle(title)
    return fig
