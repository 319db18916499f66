"""The motion a simulated chain source plays: a recording's joints, or a generated arm.

Units: mm, s, Hz.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
from mirrorlab.core import ConfigurationError
from numpy.typing import NDArray

#: The generated arm: upper arm, forearm and hand, mm; its frame rate, Hz, and length, s.
ARM_LENGTHS = (300.0, 250.0, 80.0)
ARM_RATE = 100.0
ARM_SECONDS = 10.0
#: Joint names of the generated arm.
ARM_JOINTS = ("shoulder", "elbow", "wrist", "hand")


def generated_arm(frames: int = int(ARM_RATE * ARM_SECONDS), rate: float = ARM_RATE) -> NDArray[np.float64]:
    """Joint positions (frames, 4, 3) mm of a 4-DOF arm (shoulder ``zy``, elbow ``y``, wrist ``y``)
    moving its joints sinusoidally at incommensurate frequencies (a smooth, non-planar motion).

    Examples
    --------
    >>> X = generated_arm(3)
    >>> X.shape, np.linalg.norm(X[:, 1] - X[:, 0], axis=1).round(9).tolist()
    ((3, 4, 3), [300.0, 300.0, 300.0])
    """
    from mirrorlab.plugins.retarget import Chain

    t = np.arange(frames) / rate
    q = np.stack([0.6 * np.sin(2 * np.pi * 0.2 * t), -0.5 + 0.4 * np.sin(2 * np.pi * 0.3 * t),
                  0.9 + 0.5 * np.sin(2 * np.pi * 0.25 * t + 1.0), 0.3 * np.sin(2 * np.pi * 0.4 * t)], axis=1)
    return Chain(list(ARM_LENGTHS), ["zy", "y", "y"]).forward(q)


def simulated_chain(motion: str, joints: Sequence[str], scale: float = 1.0,
                    skip: int = 0) -> tuple[NDArray[np.float64], list[str], float]:
    """Positions (frames, joints, 3) mm, joint names and frame rate (Hz) for a simulated chain source.

    ``motion`` names a recording (``.bvh``, ``.c3d``, ``.trc``, ``.tsv``) whose ``joints`` are played
    (marker files: ``"A+B"`` is the midpoint); empty: :func:`generated_arm` with joints
    :data:`ARM_JOINTS`, every one of them (``joints`` selects among them on the device).

    Raises
    ------
    ConfigurationError
        The recording cannot be read or lacks a joint (the message names the file and the joint).
    """
    if not motion:
        return generated_arm(), list(ARM_JOINTS), ARM_RATE
    from mirrorlab.plugins.retarget.algorithms import read_motion
    from mirrorlab.plugins.retarget.errors import SourceError

    try:
        m = read_motion(Path(motion), list(joints), scale, skip)
    except SourceError as exc:
        raise ConfigurationError(f"chain source simulator: {exc}") from None
    names = [n.replace(" ", "_") for n in m.names]
    return m.joints, names, m.rate
