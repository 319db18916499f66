"""Synthetic marker data of the thesis's four-bar experiment (``analysis.md`` §4.3-§4.4).

The thesis four-bar (230/100/220/133 mm, two markers per moving link, three on the frame; the
marker layout of the virtual lab's four-bar scene) sampled at 12° crank steps
(:func:`four_bar_positions`), with the thesis digitiser's errors, markers shuffled in every frame
and optional gaps. Units: mm, rad.
"""

from __future__ import annotations

from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["FOUR_BAR_FIELD_MM", "FOUR_BAR_MARKERS", "TABLE_5_1", "THESIS_FOUR_BAR", "four_bar_markers",
           "four_bar_positions"]

#: Field of the virtual lab's four-bar camera on the mechanism plane, mm: a 24 x 18 mm cine frame
#: through a 50 mm lens from 1200 mm (``make_lab("four_bar")``).
FOUR_BAR_FIELD_MM = (24.0 * 1200.0 / 50.0, 18.0 * 1200.0 / 50.0)
#: The true link lengths of the thesis's four-bar, mm.
THESIS_FOUR_BAR = {"ground": 230.0, "input": 100.0, "coupler": 220.0, "output": 133.0}
#: Table 5.1: the thesis's reconstructed lengths (image units x 2.000, mm) and errors (%).
TABLE_5_1 = {"ground": (217.10, -5.6), "input": (108.40, 8.4), "coupler": (234.06, 6.4), "output": (121.28, -8.8)}
#: Marker offsets (mm) in each link's frame: x along the link from its first joint, y to its left.
#: Markers F1-F3 on the frame, L1a, L1b on the input crank, L3a, L3b on the coupler, L4a, L4b on the output.
FOUR_BAR_MARKERS: dict[str, tuple[tuple[float, float], ...]] = {
    "frame": ((-70.0, -110.0), (110.0, -150.0), (310.0, -140.0)),
    "input": ((35.0, 12.0), (80.0, -10.0)),
    "coupler": ((95.0, 35.0), (165.0, -20.0)),
    "output": ((45.0, 10.0), (100.0, -12.0)),
}


def four_bar_positions(theta: ArrayLike, lengths: dict[str, float] = THESIS_FOUR_BAR) -> NDArray[np.float64]:
    """Marker positions (T, 9, 2) mm of a planar four-bar at input crank angles ``theta`` (T,) rad.

    Ground pivots G1 = (0, 0) and G2 = (ground, 0); the crank G1-J1 at ``theta``; the output link
    G2-J2 at the angle that closes the loop (cosine law in the triangle J1 G2 J2), J2 on the left
    of J1 -> G2. Points are complex numbers here: a marker at ``(x, y)`` in a link's frame sits at
    ``origin + (x + i y) u``, ``u`` the link's unit direction.

    Raises
    ------
    ValueError
        The links cannot close at some ``theta`` (the message names it).

    Examples
    --------
    >>> p = four_bar_positions([0.0, np.pi / 2])
    >>> p.shape, np.linalg.norm(p[:, 4] - p[:, 3], axis=-1).round(6).tolist()   # two markers on the crank
    ((2, 9, 2), [50.089919, 50.089919])
    """
    th = np.atleast_1d(np.asarray(theta, dtype=float))
    L0, L1, L3, L4 = (float(lengths[k]) for k in ("ground", "input", "coupler", "output"))
    G1, G2 = 0j, complex(L0, 0.0)
    J1 = L1 * np.exp(1j * th)
    diagonal = np.abs(J1 - G2)
    cos_beta = (L4**2 + diagonal**2 - L3**2) / (2.0 * L4 * diagonal)     # angle J1 G2 J2
    if np.any(np.abs(cos_beta) > 1.0):
        k = int(np.flatnonzero(np.abs(cos_beta) > 1.0)[0])
        raise ValueError(f"the four-bar cannot close at theta = {th[k]:.4g} rad; check the link lengths")
    J2 = G2 + L4 * np.exp(1j * (np.angle(J1 - G2) - np.arccos(cos_beta)))

    def on_link(origin: ArrayLike, tip: ArrayLike, offsets: tuple[tuple[float, float], ...]) -> NDArray[np.complex128]:
        u = (np.asarray(tip) - origin) / np.abs(np.asarray(tip) - origin)
        return np.asarray(origin)[..., None] + np.array([complex(x, y) for x, y in offsets]) * np.asarray(u)[..., None]

    frame = np.broadcast_to(np.array([complex(x, y) for x, y in FOUR_BAR_MARKERS["frame"]]), (th.size, 3))
    z = np.concatenate([frame, on_link(G1, J1, FOUR_BAR_MARKERS["input"]), on_link(J1, J2, FOUR_BAR_MARKERS["coupler"]),
                        on_link(np.full(th.size, G2), J2, FOUR_BAR_MARKERS["output"])], axis=1)
    return np.stack([z.real, z.imag], axis=-1)


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
    truth : (frames, 9, 2) the same markers unshuffled and noiseless, in the order of :data:`FOUR_BAR_MARKERS`.

    Examples
    --------
    >>> p, truth = four_bar_markers(3, noise="none", shuffle=False)
    >>> bool(np.array_equal(p, truth)), p.shape
    (True, (3, 9, 2))
    """
    truth = four_bar_positions(theta0 + np.arange(frames) * step)
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
