"""PNG figures of the photogrammetry error analysis (matplotlib, Agg backend).

Each function takes arrays computed by :mod:`.parallel` / :mod:`.sensitivity` and writes one PNG;
nothing is computed here beyond reshaping. Lengths in mm, angles in rad (axes labelled).
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from numpy.typing import ArrayLike  # noqa: E402

__all__ = ["plot_min_shooting_distance", "plot_error_map", "plot_mirror_angle_sweep"]


def plot_min_shooting_distance(theta: ArrayLike, dtheta: ArrayLike, L_min: ArrayLike, path: str | Path) -> Path:
    """Fig. 2.4: L_min (rows: theta, columns: dtheta, both rad) against dtheta, one line per theta.

    Examples
    --------
    >>> import tempfile, os
    >>> p = plot_min_shooting_distance([0.0], [0.1, 0.2], [[1.0, 2.0]], os.path.join(tempfile.mkdtemp(), "f.png"))
    >>> p.exists()
    True
    """
    th, dth, L = np.asarray(theta), np.asarray(dtheta), np.asarray(L_min)
    fig, ax = plt.subplots(figsize=(5, 4))
    for t, row in zip(th, L):
        ax.plot(np.degrees(dth), row, marker="o", label=f"θ = {np.degrees(t):.0f}°")
    ax.set_xlabel("Δθ (deg)")
    ax.set_ylabel("L_min (unit of A)")
    ax.legend()
    ax.grid(alpha=0.3)
    return _save(fig, path)


def plot_error_map(points: ArrayLike, errors: ArrayLike, path: str | Path, center: ArrayLike | None = None,
                   title: str = "", scale: float = 5.0) -> Path:
    """Figs 2.11 / 3.22: error vectors (M, 3) drawn ×``scale`` at markers (M, 3), three projections.

    Examples
    --------
    >>> import tempfile, os
    >>> p = plot_error_map(np.eye(3), 0.1 * np.eye(3), os.path.join(tempfile.mkdtemp(), "m.png"))
    >>> p.exists()
    True
    """
    P, E = np.asarray(points, float), np.asarray(errors, float)
    c = P.mean(axis=0) if center is None else np.asarray(center, float)
    fig, axes = plt.subplots(1, 3, figsize=(12, 4))
    for ax, (i, j), lab in zip(axes, [(0, 1), (2, 1), (0, 2)], ["X–Y", "Z–Y", "X–Z"]):
        ax.scatter(P[:, i] - c[i], P[:, j] - c[j], s=4, c="k")
        ax.quiver(P[:, i] - c[i], P[:, j] - c[j], scale * E[:, i], scale * E[:, j], angles="xy",
                  scale_units="xy", scale=1, color="C3", width=0.003)
        ax.set_aspect("equal")
        ax.set_title(f"{lab} (errors ×{scale:g}, mm)")
    fig.suptitle(title)
    return _save(fig, path)


def plot_mirror_angle_sweep(angles: ArrayLike, errors: ArrayLike, path: str | Path, reference: float | None = 0.68
                            ) -> Path:
    """Fig. 3.23: total error (mm) against mirror angle (rad); ``reference`` marks the thesis minimum.

    Examples
    --------
    >>> import tempfile, os
    >>> p = plot_mirror_angle_sweep([0.5, 0.7, 0.9], [2.0, 1.0, 2.0], os.path.join(tempfile.mkdtemp(), "s.png"))
    >>> p.exists()
    True
    """
    a, e = np.asarray(angles, float), np.asarray(errors, float)
    fig, ax = plt.subplots(figsize=(5, 4))
    ax.plot(a, e, "-o", ms=3)
    if reference is not None:
        ax.axvline(reference, color="C3", ls="--", label=f"thesis minimum {reference} rad")
        ax.legend()
    ax.set_xlabel("mirror angle T (rad)")
    ax.set_ylabel("total error (mm)")
    ax.grid(alpha=0.3)
    return _save(fig, path)


def _save(fig, path: str | Path) -> Path:
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    fig.tight_layout()
    fig.savefig(p, dpi=110)
    plt.close(fig)
    return p
