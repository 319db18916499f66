"""Synthetic marker data of the thesis's four-bar experiment (``analysis.md`` §4.3-§4.4).

The virtual lab's :class:`~mirrorlab.instruments.virtual_lab.scenes.FourBarScene` (230/100/220/133
mm, two markers per moving link, three on the frame) sampled at 12° crank steps, with the thesis
digitiser's errors, markers shuffled in every frame and optional gaps. Units: mm.
"""

from __future__ import annotations

from typing import Literal

import numpy as np
from mirrorlab.instruments.virtual_lab.scenes import FourBarScene
from numpy.typing import NDArray

__all__ = ["FOUR_BAR_FIELD_MM", "TABLE_5_1", "THESIS_FOUR_BAR", "four_bar_markers"]

#: Field of the virtual lab's four-bar camera on the mechanism plane, mm: a 24 x 18 mm cine frame
#: through a 50 mm lens from 1200 mm (``make_lab("four_bar")``).
FOUR_BAR_FIELD_MM = (24.0 * 1200.0 / 50.0, 18.0 * 1200.0 / 50.0)
#: The true link lengths of the thesis's four-bar, mm.
THESIS_FOUR_BAR = {"ground": 230.0, "input": 100.0, "coupler": 220.0, "output": 133.0}
#: Table 5.1: the thesis's reconstructed lengths (image units x 2.000, mm) and errors (%).
TABLE_5_1 = {"ground": (217.10, -5.6), "input": (108.40, 8.4), "coupler": (234.06, 6.4), "output": (121.28, -8.8)}


def four_bar_markers(frames: int = 30, step: float = np.deg2rad(12.0), *, noise: Literal["none", "uniform", "gaussian"]
                     = "uniform", field: tuple[float, float] = FOUR_BAR_FIELD_MM, shuffle: bool = True,
                     missing: float = 0.0, theta0: float = 0.0,
                     seed: int | None = 0) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Planar marker positions of the thesis four-bar, as the thesis's digitiser would give them.

    Parameters
    ----------
    frames : number of frames (the thesis filmed 30).
    step : crank rotation between frames, rad (12° in §4.4).
    noise : the digitiser's repeatability, 1/512 of the field across and 2/344 along the feed
        (§1.2, §5.4): ``"uniform"`` reads it as the peak-to-peak range (errors uniform within
        +-0.5 and +-1 digitiser units, i.e. rounding to the 512 x 344 grid plus feed jitter),
        ``"gaussian"`` as a standard deviation of one and two units (a harsher reading).
    field : width and height of the digitised field on the mechanism plane, mm.
    shuffle : permute the markers independently in every frame (unlabeled data).
    missing : fraction of marker samples replaced by NaN (gaps), after frame 0.
    theta0 : crank angle of frame 0, rad.
    seed : random seed.

    Returns
    -------
    points : (frames, 9, 2) marker positions, mm (rows in random order when shuffled).
    truth : (frames, 9, 2) the same markers unshuffled and noiseless, in the scene's label order.

    Examples
    --------
    >>> p, truth = four_bar_markers(3, noise="none", shuffle=False)
    >>> bool(np.array_equal(p, truth)), p.shape
    (True, (3, 9, 2))
    """
    scene = FourBarScene(theta0=theta0)
    truth = scene.positions(np.arange(frames) * step / scene.omega)[..., :2]
    rng = np.random.default_rng(seed)
    unit = np.array([field[0] / 512.0, field[1] / 344.0])
    if noise == "uniform":
        err = rng.uniform(-1.0, 1.0, truth.shape) * unit * np.array([0.5, 1.0])
    elif noise == "gaussian":
        err = rng.normal(size=truth.shape) * unit * np.array([1.0, 2.0])
    elif noise == "none":
        err = np.zeros_like(truth)
    else:
        raise ValueError(f"unknown noise model {noise!r}; use 'none', 'uniform' or 'gaussian'")
    points = truth + err
    if missing:
        drop = rng.random(points.shape[:2]) < missing
        drop[0] = False
        points[drop] = np.nan
    if shuffle:
        points = np.stack([f[rng.permutation(len(f))] for f in points])
    return points, truth
