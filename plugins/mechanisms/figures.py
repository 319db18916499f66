"""PNG figures of mechanism results (matplotlib Agg canvas, no pyplot state).

Each function draws one figure, writes it to ``path`` (parent folders created) and returns the
path. Every figure has a title, axis labels with units and a legend.
"""

from __future__ import annotations

import os
from collections.abc import Collection, Mapping
from pathlib import Path

import numpy as np
import shapely
from matplotlib.axes import Axes
from matplotlib.figure import Figure
from mirrorlab.core import save_figure
from numpy.typing import ArrayLike

__all__ = ["four_bar_figure", "plot_centrodes", "plot_four_bar", "plot_swept", "plot_walls", "walls_figure"]

LINK_COLOURS = {0: ("ground", "0.4"), 1: ("input", "tab:blue"), 2: ("coupler", "tab:orange"), 3: ("output", "tab:green"),
                -1: ("unassigned", "tab:red")}


def plot_four_bar(path: os.PathLike[str] | str, tracks: ArrayLike, link: ArrayLike, joints: ArrayLike,
                  title: str = "reconstructed four-bar", every: int = 5, unit: str = "mm") -> Path:
    """Write :func:`four_bar_figure` to the PNG file ``path``.

    Examples
    --------
    >>> import tempfile
    >>> j = np.zeros((3, 4, 2)); j[:, 1] = [1, 1]; j[:, 2] = [3, 2]; j[:, 3] = [4, 0]
    >>> plot_four_bar(os.path.join(tempfile.mkdtemp(), "f.png"), j, [0, 1, 2, 3], j).stat().st_size > 0
    True
    """
    return save_figure(four_bar_figure(tracks, link, joints, title, every, unit), path)


def four_bar_figure(tracks: ArrayLike, link: ArrayLike, joints: ArrayLike, title: str = "reconstructed four-bar",
                    every: int = 5, unit: str = "mm") -> Figure:
    """The tracked markers coloured by link, with the reconstructed linkage drawn every ``every`` frames.

    The markers fill the plane of the mechanism, so the legend stands to the right of the axes.

    Parameters
    ----------
    tracks : (T, M, 2) marker tracks; link : (M,) link index (0 ground, 1 input, 2 coupler,
        3 output, -1 none); joints : (T, 4, 2) G1, J1, J2, G2.
    """
    tr, lk, J = np.asarray(tracks, float), np.asarray(link), np.asarray(joints, float)
    fig = Figure(figsize=(9, 5.5), layout="constrained")
    ax = fig.add_subplot()
    for k, (name, colour) in LINK_COLOURS.items():
        cols = np.flatnonzero(lk == k)
        if cols.size:
            ax.plot(tr[:, cols, 0].ravel(), tr[:, cols, 1].ravel(), ".", ms=4, color=colour,
                    label=f"{name} markers")
    for n, k in enumerate(range(0, len(J), max(1, every))):
        ax.plot(J[k, :, 0], J[k, :, 1], "-o", color="k", lw=1.2, ms=3, alpha=0.6,
                label="reconstructed linkage G1-J1-J2-G2" if n == 0 else None)
    ax.plot(J[0, [0, 3], 0], J[0, [0, 3], 1], "^", color="k", ms=9, label="ground pivots")
    ax.set_aspect("equal")
    ax.set_xlabel(f"x ({unit})")
    ax.set_ylabel(f"y ({unit})")
    ax.set_title(title)
    fig.legend(fontsize=8, loc="outside right upper")
    return fig


def _rods(ax: Axes, A: np.ndarray, B: np.ndarray, every: int, colour: str, path_of_a: str) -> None:
    """The rod A-B every ``every`` samples in ``colour`` (one legend entry), then A's path labelled ``path_of_a``."""
    for n, k in enumerate(range(0, len(A), max(1, every))):
        ax.plot([A[k, 0], B[k, 0]], [A[k, 1], B[k, 1]], "-", color=colour, lw=0.8,
                label="rod positions" if n == 0 else None)
    ax.plot(A[:, 0], A[:, 1], "-", color="k", lw=1.5, label=path_of_a)


def plot_swept(path: os.PathLike[str] | str, a: ArrayLike, b: ArrayLike, region: shapely.Geometry | None = None,
               title: str = "swept region", every: int = 20, unit: str = "mm") -> Path:
    """Rod positions every ``every`` samples and the swept region (a shapely geometry) filled."""
    A, B = np.asarray(a, float), np.asarray(b, float)
    fig = Figure(figsize=(6.5, 5.5))
    ax = fig.add_subplot()
    if region is not None:
        polys = getattr(region, "geoms", [region])
        for n, poly in enumerate(polys):
            if poly.geom_type == "Polygon":
                x, y = poly.exterior.xy
                ax.fill(x, y, color="tab:orange", alpha=0.35, lw=0,
                        label=f"swept region, area {region.area:.5g} {unit}²" if n == 0 else None)
    _rods(ax, A, B, every, "tab:blue", "path of A")
    ax.plot(B[:, 0], B[:, 1], "--", color="k", lw=1.0, label="path of B")
    ax.set_aspect("equal")
    ax.set_xlabel(f"x ({unit})")
    ax.set_ylabel(f"y ({unit})")
    ax.set_title(title)
    ax.legend(fontsize=8, loc="best")
    return save_figure(fig, path)


def plot_centrodes(path: os.PathLike[str] | str, a: ArrayLike, b: ArrayLike, fixed: ArrayLike, moving: ArrayLike,
                   title: str = "centrodes", every: int = 40, unit: str = "mm") -> Path:
    """Fixed centrode with rod positions (left) and the moving centrode in the rod frame (right)."""
    A, B, F, Mv = (np.asarray(v, float) for v in (a, b, fixed, moving))
    fig = Figure(figsize=(11, 4.8))
    ax, bx = fig.subplots(1, 2)
    _rods(ax, A, B, every, "0.6", "wall (path of A)")
    ax.plot(F[:, 0], F[:, 1], "-", color="tab:red", lw=1.5, label="fixed centrode")
    ax.set_title("fixed centrode (world)")
    bx.plot(Mv[:, 0], Mv[:, 1], "-", color="tab:purple", lw=1.5, label="moving centrode")
    L = float(np.nanmedian(np.linalg.norm(A - B, axis=1)))
    bx.plot([0, L], [0, 0], "-o", color="k", lw=2, label="rod B-A")
    bx.set_title("moving centrode (rod frame: origin B, x along BA)")
    for axis in (ax, bx):
        axis.set_aspect("equal")
        axis.set_xlabel(f"x ({unit})")
        axis.set_ylabel(f"y ({unit})")
        axis.legend(fontsize=8, loc="best")
    fig.suptitle(title)
    return save_figure(fig, path)


def plot_walls(path: os.PathLike[str] | str, walls: Mapping[str, tuple[ArrayLike, ArrayLike]],
               title: str = "guiding walls", unit: str = "l units", polylines: Collection[str] = ()) -> Path:
    """Write :func:`walls_figure` to the PNG file ``path``."""
    return save_figure(walls_figure(walls, title, unit, polylines), path)


def walls_figure(walls: Mapping[str, tuple[ArrayLike, ArrayLike]], title: str = "guiding walls",
                 unit: str = "l units", polylines: Collection[str] = ()) -> Figure:
    """Walls ``x = w(y)`` drawn as curves, labelled by name (e.g. with their areas).

    The walls named in ``polylines`` are the optimal wall's polyline (values at its nodes): their
    nodes are marked, and the first node below the top is pointed out: it lies right of the next
    one because a straight first segment is the polyline's stand-in for a wall that leaves the top
    horizontally (as eq. 6.3's does); lowering it to the next node's abscissa sweeps more.
    """
    fig = Figure(figsize=(6.5, 6))
    ax = fig.add_subplot()
    for name, (x, y) in walls.items():
        xs, ys = np.asarray(x, float), np.asarray(y, float)
        if name in polylines:
            line, = ax.plot(xs, ys, "-o", lw=1.5, ms=2.5, label=f"{name} (polyline, nodes marked)")
            top = int(np.argmax(ys))
            first = top - 1 if top > 0 and ys[top - 1] < ys[top] else top + 1     # the node next to the top
            ax.annotate("first node: the straight first segment\nstands in for a horizontal start",
                        (xs[first], ys[first]), xytext=(-12, -48), textcoords="offset points", ha="right",
                        fontsize=7, color=line.get_color(), arrowprops={"arrowstyle": "->", "color": line.get_color()})
        else:
            ax.plot(xs, ys, "-", lw=1.5, label=name)
    ax.axvline(0.0, color="0.7", lw=0.8)             # x stretched: the walls bulge by about l / 8
    ax.set_xlabel(f"x ({unit})")
    ax.set_ylabel(f"y ({unit})")
    ax.set_title(title)
    ax.legend(fontsize=8, loc="best")
    return fig
