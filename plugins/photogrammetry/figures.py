"""PNG figures of the photogrammetry error analysis (matplotlib, Agg canvas; no global pyplot state).

Each ``*_figure`` function takes arrays computed by :mod:`.parallel` / :mod:`.sensitivity` and
draws one figure; each ``plot_*`` writes it to a PNG and returns the path. Nothing is computed
here beyond reshaping. Lengths in mm, angles in rad (axes labelled).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.figure import Figure
from mirrorlab.core import save_figure
from numpy.typing import ArrayLike

__all__ = ["error_map_figure", "min_shooting_distance_figure", "mirror_angle_sweep_figure", "plot_error_map",
           "plot_min_shooting_distance", "plot_mirror_angle_sweep"]

#: Resolution of the PNG files, dots per inch.
DPI = 110


def min_shooting_distance_figure(theta: ArrayLike, dtheta: ArrayLike, L_min: ArrayLike) -> Figure:
    """Fig. 2.4: L_min (rows: theta, columns: dtheta, both rad) against dtheta, one line per theta."""
    th, dth, L = np.asarray(theta), np.asarray(dtheta), np.asarray(L_min)
    fig = Figure(figsize=(5, 4), layout="constrained")
    ax = fig.subplots()
    for t, row in zip(th, L):
        ax.plot(np.degrees(dth), row, marker="o", label=f"θ = {np.degrees(t):.0f}°")
    ax.set_xlabel("Δθ (deg)")
    ax.set_ylabel("L_min (unit of A)")
    ax.set_title("Minimum shooting distance (Fig. 2.4)")
    ax.legend()
    ax.grid(alpha=0.3)
    return fig


def plot_min_shooting_distance(theta: ArrayLike, dtheta: ArrayLike, L_min: ArrayLike, path: str | Path) -> Path:
    """Write :func:`min_shooting_distance_figure` to the PNG file ``path``.

    Examples
    --------
    >>> import tempfile, os
    >>> p = plot_min_shooting_distance([0.0], [0.1, 0.2], [[1.0, 2.0]], os.path.join(tempfile.mkdtemp(), "f.png"))
    >>> p.exists()
    True
    """
    return save_figure(min_shooting_distance_figure(theta, dtheta, L_min), path, dpi=DPI)


def error_map_figure(points: ArrayLike, errors: ArrayLike, center: ArrayLike | None = None, title: str = "",
                     scale: float = 5.0) -> Figure:
    """Figs 2.11 / 3.22: error vectors (M, 3) drawn ×``scale`` at markers (M, 3), three projections (mm)."""
    P, E = np.asarray(points, float), np.asarray(errors, float)
    c = P.mean(axis=0) if center is None else np.asarray(center, float)
    fig = Figure(figsize=(12, 4.4), layout="constrained")
    axes = fig.subplots(1, 3)
    for ax, (i, j) in zip(axes, [(0, 1), (2, 1), (0, 2)]):
        ax.scatter(P[:, i] - c[i], P[:, j] - c[j], s=4, c="k", label="marker")
        ax.quiver(P[:, i] - c[i], P[:, j] - c[j], scale * E[:, i], scale * E[:, j], angles="xy",
                  scale_units="xy", scale=1, color="C3", width=0.003, label=f"error ×{scale:g}")
        ax.set_aspect("equal")
        ax.set_xlabel(f"{'XYZ'[i]} − centre (mm)")
        ax.set_ylabel(f"{'XYZ'[j]} − centre (mm)")
        ax.set_title(f"{'XYZ'[i]}–{'XYZ'[j]}")
    axes[0].legend(fontsize=8)
    fig.suptitle(title or f"Reconstruction error vectors (drawn ×{scale:g})")
    return fig


def plot_error_map(points: ArrayLike, errors: ArrayLike, path: str | Path, center: ArrayLike | None = None,
                   title: str = "", scale: float = 5.0) -> Path:
    """Write :func:`error_map_figure` to the PNG file ``path``.

    Examples
    --------
    >>> import tempfile, os
    >>> p = plot_error_map(np.eye(3), 0.1 * np.eye(3), os.path.join(tempfile.mkdtemp(), "m.png"))
    >>> p.exists()
    True
    """
    return save_figure(error_map_figure(points, errors, center, title, scale), path, dpi=DPI)


def mirror_angle_sweep_figure(angles: ArrayLike, errors: ArrayLike, reference: float | None = 0.68) -> Figure:
    """Fig. 3.23: total error (mm) against mirror angle (rad); ``reference`` marks the thesis minimum."""
    a, e = np.asarray(angles, float), np.asarray(errors, float)
    fig = Figure(figsize=(5, 4), layout="constrained")
    ax = fig.subplots()
    ax.plot(a, e, "-o", ms=3, label="total error")
    if reference is not None:
        ax.axvline(reference, color="C3", ls="--", label=f"thesis minimum {reference} rad")
    ax.legend()
    ax.set_xlabel("mirror angle T (rad)")
    ax.set_ylabel("total error (mm)")
    ax.set_title("Mirror-method error against mirror angle (Fig. 3.23)")
    ax.grid(alpha=0.3)
    return fig


def plot_mirror_angle_sweep(angles: ArrayLike, errors: ArrayLike, path: str | Path, reference: float | None = 0.68
                            ) -> Path:
    """Write :func:`mirror_angle_sweep_figure` to the PNG file ``path``.

    Examples
    --------
    >>> import tempfile, os
    >>> p = plot_mirror_angle_sweep([0.5, 0.7, 0.9], [2.0, 1.0, 2.0], os.path.join(tempfile.mkdtemp(), "s.png"))
    >>> p.exists()
    True
    """
    return save_figure(mirror_angle_sweep_figure(angles, errors, reference), path, dpi=DPI)
