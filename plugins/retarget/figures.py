"""PNG figures of retargeting: input and output chains at a few frames, and f over time (Agg, no pyplot)."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure
from mirrorlab.core import save_figure
from numpy.typing import ArrayLike

__all__ = ["plot_chains"]


def plot_chains(path: os.PathLike[str] | str, input_joints: ArrayLike, output_joints: ArrayLike, time: ArrayLike,
                f: ArrayLike, frames: int = 4, title: str = "") -> Path:
    """Input (grey) and output (colour) chains at ``frames`` evenly spaced frames, in the two planes of
    largest spread, and the evaluation function over time.

    Parameters
    ----------
    path : path-like
        PNG file to write (parent folders are created).
    input_joints : array_like (T, n + 1, 3)
        Input joint positions, mm.
    output_joints : array_like (T, N + 1, 3)
        Output joint positions, mm.
    time : array_like (T,)
        s.
    f : array_like (T,)
        Evaluation function, mm².

    Examples
    --------
    >>> import tempfile
    >>> X = np.zeros((3, 2, 3)); X[:, 1, 0] = 1.0
    >>> p = plot_chains(Path(tempfile.mkdtemp()) / "c.png", X, X, [0, 1, 2], [0.0, 0.0, 0.0])
    >>> p.stat().st_size > 0
    True
    """
    Xi, Xo = np.asarray(input_joints, float), np.asarray(output_joints, float)
    t, fv = np.asarray(time, float), np.asarray(f, float)
    # centre each frame on the input root so chains of a moving body can be compared
    Xi_c, Xo_c = Xi - Xi[:, :1], Xo - Xi[:, :1]
    spread = np.nanstd(Xi_c.reshape(-1, 3), axis=0)
    a, b = np.sort(np.argsort(spread)[-2:])
    names = "xyz"
    fig = Figure(figsize=(11, 4.8))
    ax, axf = fig.add_subplot(1, 2, 1), fig.add_subplot(1, 2, 2)
    picks = np.linspace(0, len(t) - 1, frames).round().astype(int)
    colours = ["tab:blue", "tab:orange", "tab:green", "tab:red", "tab:purple", "tab:brown"]
    for n, k in enumerate(picks):
        ax.plot(Xi_c[k, :, a], Xi_c[k, :, b], "o-", color="0.6", lw=3, alpha=0.7,
                label="input chain" if n == 0 else None)
        ax.plot(Xo_c[k, :, a], Xo_c[k, :, b], "s--", color=colours[n % len(colours)], lw=1.5,
                label=f"output, t = {t[k]:.2f} s")
    ax.set_xlabel(f"{names[a]} relative to the input root (mm)")
    ax.set_ylabel(f"{names[b]} relative to the input root (mm)")
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_title("input and output chains")
    ax.legend(fontsize=8)
    axf.plot(t, fv, lw=1, label="f (evaluation function)")
    axf.set_xlabel("time (s)")
    axf.set_ylabel("f (mm²)")
    axf.set_title("shape difference per frame")
    axf.legend(fontsize=8)
    fig.suptitle(title or "chain shape approximation")
    fig.tight_layout()
    return save_figure(fig, path)
