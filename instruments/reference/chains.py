"""The motion a simulated chain source plays: a recording's joints, or a generated arm.

The generated arm's forward kinematics are written out here (a yaw and three pitches), not taken
from the retarget plugin that the chain source feeds; a recording is read by the plugin that
answers the ``mirrorlab_read_motion`` hook (the retarget plugin's readers of BVH and marker files),
so this instrument imports no plugin. Units: mm, s, Hz.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from mirrorlab.core import ConfigurationError, MirrorlabError, get_registry
from numpy.typing import ArrayLike, NDArray

#: The generated arm: upper arm, forearm and hand, mm; its frame rate, Hz, and length, s.
ARM_LENGTHS = (300.0, 250.0, 80.0)
ARM_RATE = 100.0
ARM_SECONDS = 10.0
#: Joint names of the generated arm.
ARM_JOINTS = ("shoulder", "elbow", "wrist", "hand")
#: Its joints' axes in the retarget chain convention (``docs/retarget.md``): shoulder ``zy``, elbow and wrist ``y``.
ARM_AXES = ("zy", "y", "y")


def arm_angles(frames: int = int(ARM_RATE * ARM_SECONDS), rate: float = ARM_RATE) -> NDArray[np.float64]:
    """Joint angles (frames, 4) rad of the generated arm: shoulder yaw and pitch, elbow, wrist, moving
    sinusoidally at incommensurate frequencies (a smooth, non-planar motion)."""
    t = np.arange(frames) / rate
    return np.stack([0.6 * np.sin(2 * np.pi * 0.2 * t), -0.5 + 0.4 * np.sin(2 * np.pi * 0.3 * t),
                     0.9 + 0.5 * np.sin(2 * np.pi * 0.25 * t + 1.0), 0.3 * np.sin(2 * np.pi * 0.4 * t)], axis=1)


def arm_positions(q: ArrayLike) -> NDArray[np.float64]:
    """Joint positions (frames, 4, 3) mm of the arm at joint angles ``q`` (frames, 4) rad.

    Each link lies along its local x axis. The shoulder turns the arm by ``q0`` about z, then
    every joint pitches the links beyond it about their common local y axis, so link ``k`` points
    along ``(cos q0 cos p_k, sin q0 cos p_k, -sin p_k)`` with ``p_k = q1 + ... + q(k+1)``.

    Examples
    --------
    >>> arm_positions([[0.0, np.pi / 2, -np.pi / 2, 0.0]]).round(9).tolist()[0]   # upper arm down, forearm forward
    [[0.0, 0.0, 0.0], [0.0, 0.0, -300.0], [250.0, 0.0, -300.0], [330.0, 0.0, -300.0]]
    """
    q = np.atleast_2d(np.asarray(q, dtype=float))
    yaw, pitch = q[:, :1], np.cumsum(q[:, 1:], axis=1)
    along = np.stack([np.cos(yaw) * np.cos(pitch), np.sin(yaw) * np.cos(pitch), -np.sin(pitch)], axis=-1)
    links = along * np.asarray(ARM_LENGTHS)[:, None]
    return np.concatenate([np.zeros((q.shape[0], 1, 3)), np.cumsum(links, axis=1)], axis=1)


def generated_arm(frames: int = int(ARM_RATE * ARM_SECONDS), rate: float = ARM_RATE) -> NDArray[np.float64]:
    """Joint positions (frames, 4, 3) mm of the 4-DOF arm (shoulder ``zy``, elbow ``y``, wrist ``y``)
    moving as :func:`arm_angles`.

    Examples
    --------
    >>> X = generated_arm(3)
    >>> X.shape, np.linalg.norm(X[:, 1] - X[:, 0], axis=1).round(9).tolist()
    ((3, 4, 3), [300.0, 300.0, 300.0])
    """
    return arm_positions(arm_angles(frames, rate))


def simulated_chain(motion: str, joints: Sequence[str], scale: float = 1.0,
                    skip: int = 0) -> tuple[NDArray[np.float64], list[str], float]:
    """Positions (frames, joints, 3) mm, joint names and frame rate (Hz) for a simulated chain source.

    ``motion`` names a recording (``.bvh``, ``.c3d``, ``.trc``, ``.tsv``) whose ``joints`` are played
    (marker files: ``"A+B"`` is the midpoint), read by the plugin answering ``mirrorlab_read_motion``;
    empty: :func:`generated_arm` with joints :data:`ARM_JOINTS`, every one of them (``joints``
    selects among them on the device).

    Raises
    ------
    ConfigurationError
        The recording cannot be read or lacks a joint (the message names the file and the joint), or
        no installed plugin reads recordings.
    """
    if not motion:
        return generated_arm(), list(ARM_JOINTS), ARM_RATE
    try:
        read = get_registry().first_result("mirrorlab_read_motion", path=motion, joints=list(joints),
                                           scale=scale, skip=skip)
    except MirrorlabError as exc:
        raise ConfigurationError(f"chain source simulator: {exc}") from None
    if read is None:
        raise ConfigurationError(f"chain source simulator: no installed plugin reads the recording {motion}; "
                                 "install mirrorlab's retarget plugin, or leave motion empty for the generated arm")
    positions, names, rate = read
    return np.asarray(positions, dtype=float), list(names), float(rate)
