"""PNG figures of kinematics results (matplotlib, Agg canvas; no global pyplot state).

Each ``*_figure`` function draws one figure; each ``plot_*`` writes it to ``path`` (parent folders
are created) and returns the path. Angles are drawn in degrees, positions in mm, time in s.
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure
from mirrorlab.core import save_figure
from numpy.typing import ArrayLike

__all__ = ["angles_figure", "derivatives_figure", "plot_angles", "plot_derivatives", "plot_rigid", "rigid_figure"]

#: At most this many markers are drawn individually; the rest are summarised by the legend text.
MAX_TRACES = 8


def _norm(x: np.ndarray) -> np.ndarray:
    return np.linalg.norm(x, axis=-1)


def plot_derivatives(path: os.PathLike[str] | str, t: ArrayLike, labels: Sequence[str], smoothed: ArrayLike,
                     velocity: ArrayLike, acceleration: ArrayLike, title: str = "") -> Path:
    """Write :func:`derivatives_figure` to the PNG file ``path``.

    Examples
    --------
    >>> import tempfile, os
    >>> t = np.linspace(0, 1, 20); x = np.zeros((20, 1, 3)); x[:, 0, 0] = t
    >>> p = plot_derivatives(os.path.join(tempfile.mkdtemp(), "d.png"), t, ["A"], x, x, x)
    >>> p.stat().st_size > 0
    True
    """
    return save_figure(derivatives_figure(t, labels, smoothed, velocity, acceleration, title), path)


def derivatives_figure(t: ArrayLike, labels: Sequence[str], smoothed: ArrayLike, velocity: ArrayLike,
                       acceleration: ArrayLike, title: str = "") -> Figure:
    """Positions (x, y, z) in mm, speed |v| in mm/s and |a| in mm/s² of markers over time.

    Parameters
    ----------
    t : array_like, shape (T,)
        Times in s.
    labels : sequence of str
        Marker names (M).
    smoothed, velocity, acceleration : array_like, shape (T, M, 3)
        mm, mm/s, mm/s².
    """
    tt = np.asarray(t, float)
    xs, v, a = (np.asarray(q, float) for q in (smoothed, velocity, acceleration))
    fig = Figure(figsize=(9, 9), layout="constrained")
    ax = fig.subplots(3, 1, sharex=True)
    shown = list(range(min(len(labels), MAX_TRACES)))
    for m in shown:
        for c, ls in enumerate(("-", "--", ":")):
            ax[0].plot(tt, xs[:, m, c], ls, lw=0.8, color=f"C{m % 10}", label=labels[m] if c == 0 else None)
        ax[1].plot(tt, _norm(v[:, m]), lw=0.8, color=f"C{m % 10}", label=labels[m])
        ax[2].plot(tt, _norm(a[:, m]), lw=0.8, color=f"C{m % 10}", label=labels[m])
    ax[0].set_ylabel("position (mm)\nx solid, y dashed, z dotted")
    ax[1].set_ylabel("speed |v| (mm/s)")
    ax[2].set_ylabel("|a| (mm/s²)")
    ax[2].set_xlabel("time (s)")
    more = len(labels) - len(shown)
    ax[1].legend(fontsize=7, ncol=2, title=f"+{more} more not drawn" if more > 0 else None)
    for axis in ax:
        axis.grid(alpha=0.3)
    fig.suptitle(title or "marker kinematics")
    return fig


def plot_angles(path: os.PathLike[str] | str, t: ArrayLike, angles: Mapping[str, ArrayLike],
                title: str = "", reference: Mapping[str, tuple[ArrayLike, ArrayLike]] | None = None) -> Path:
    """Write :func:`angles_figure` to the PNG file ``path``.

    Examples
    --------
    >>> import tempfile, os
    >>> t = np.linspace(0, 1, 10)
    >>> plot_angles(os.path.join(tempfile.mkdtemp(), "a.png"), t, {"theta3": t}).stat().st_size > 0
    True
    """
    return save_figure(angles_figure(t, angles, title, reference), path)


def angles_figure(t: ArrayLike, angles: Mapping[str, ArrayLike], title: str = "",
                  reference: Mapping[str, tuple[ArrayLike, ArrayLike]] | None = None) -> Figure:
    """Joint angles (rad in, degrees drawn) over time, one panel per angle.

    ``reference`` maps an angle name to ``(t_ref, degrees)`` drawn on the same panel (e.g. OpenSim).
    """
    tt = np.asarray(t, float)
    names = list(angles)
    cols = 2 if len(names) > 4 else 1
    rows = int(np.ceil(len(names) / cols)) or 1
    fig = Figure(figsize=(5.0 * cols + 2, 1.9 * rows + 1), layout="constrained")
    axes = np.atleast_1d(fig.subplots(rows, cols, sharex=True, squeeze=False)).ravel()
    for axis, name in zip(axes[:len(names)], names, strict=True):
        y = np.degrees(np.asarray(angles[name], float))
        if y.ndim == 1:
            axis.plot(tt, y, lw=0.9, label=name)
        else:
            for c in range(y.shape[1]):
                axis.plot(tt, y[:, c], lw=0.9, label=f"{name}[{c}]")
        if reference and name in reference:
            tr, yr = reference[name]
            axis.plot(np.asarray(tr, float), np.asarray(yr, float), "k--", lw=0.8, label="reference")
        axis.set_ylabel(f"{name} (deg)", fontsize=8)
        axis.grid(alpha=0.3)
        axis.legend(fontsize=7)
    for axis in axes[len(names):]:
        axis.set_visible(False)
    for axis in axes[max(0, len(names) - cols):len(names)]:
        axis.set_xlabel("time (s)")
        axis.tick_params(labelbottom=True)
    fig.suptitle(title or "joint angles")
    return fig


def plot_rigid(path: os.PathLike[str] | str, t: ArrayLike, omega: ArrayLike, rms: ArrayLike | None = None,
               H: ArrayLike | None = None, title: str = "") -> Path:
    """Write :func:`rigid_figure` to the PNG file ``path``.

    Examples
    --------
    >>> import tempfile, os
    >>> t = np.linspace(0, 1, 10); w = np.ones((10, 3))
    >>> plot_rigid(os.path.join(tempfile.mkdtemp(), "r.png"), t, w, H=w).stat().st_size > 0
    True
    """
    return save_figure(rigid_figure(t, omega, rms, H, title), path)


def rigid_figure(t: ArrayLike, omega: ArrayLike, rms: ArrayLike | None = None, H: ArrayLike | None = None,
                 title: str = "") -> Figure:
    """Angular velocity components (rad/s), fit residual (mm) and, if given, H_G and |H_G| over time (s)."""
    tt = np.asarray(t, float)
    w = np.asarray(omega, float)
    panels = 1 + (rms is not None) + (H is not None)
    fig = Figure(figsize=(9, 2.8 * panels + 0.6), layout="constrained")
    ax = np.atleast_1d(fig.subplots(panels, 1, sharex=True))
    for c in range(3):
        ax[0].plot(tt, w[:, c], lw=0.9, label=f"ω{'xyz'[c]}")
    ax[0].plot(tt, _norm(w), "k", lw=1.1, label="|ω|")
    ax[0].set_ylabel("angular velocity (rad/s)")
    ax[0].legend(fontsize=7, ncol=4)
    k = 1
    if rms is not None:
        ax[k].plot(tt, np.asarray(rms, float), lw=0.9, label="rigid-fit rms")
        ax[k].set_ylabel("rigid-fit rms (mm)")
        ax[k].legend(fontsize=7)
        k += 1
    if H is not None:
        h = np.asarray(H, float)
        for c in range(3):
            ax[k].plot(tt, h[:, c], lw=0.9, label=f"H{'XYZ'[c]}")
        ax[k].plot(tt, _norm(h), "k", lw=1.2, label="|H_G|")
        ax[k].set_ylabel("H_G (kg·m²/s)")
        ax[k].legend(fontsize=7, ncol=4)
    for axis in ax:
        axis.grid(alpha=0.3)
    ax[-1].set_xlabel("time (s)")
    fig.suptitle(title or "rigid-body motion")
    return fig
