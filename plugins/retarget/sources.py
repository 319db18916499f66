"""Input chains from recordings: BVH files (pybvh), marker files (C3D/TRC/TSV) and session marker sets.

Each reader returns a :class:`Motion`: the positions of the chosen joints (T, n + 1, 3) in mm,
frame times in s and the frame rate. A marker joint may be the midpoint of several markers
(``"EPICl+EPICm"``); NaN marks a missing marker.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from .errors import SourceError

__all__ = ["Motion", "read_bvh_chain", "marker_chain", "read_marker_chain", "session_marker_chain"]

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class Motion:
    """Joint positions (T, n + 1, 3) mm of a chain, times (T,) s, rate Hz, joint names and the source."""

    joints: FloatArray
    time: FloatArray
    rate: float
    names: list[str]
    source: str


def read_bvh_chain(path: os.PathLike[str] | str, joints: Sequence[str], scale: float = 1.0,
                   skip: int = 0) -> Motion:
    """World positions of named BVH joints in every frame (forward kinematics by pybvh).

    Parameters
    ----------
    path : path-like
        BVH file.
    joints : sequence of str
        Joint names from root side to tip, e.g. ``["RightArm", "RightForeArm", "RightHand",
        "RightFingerBase"]``.
    scale : float
        mm per BVH length unit (CMU's ASF units: 1/0.45 · 25.4 = 56.444 mm).
    skip : int
        Leading frames to drop (the CMU conversions' frame 1 is a synthetic T-pose).

    Raises
    ------
    SourceError
        Unreadable file, unknown joint (the message lists the file's joints) or nothing left after ``skip``.
    """
    import pybvh

    p = Path(path)
    if not p.is_file():
        raise SourceError(f"{p}: no such BVH file")
    try:
        bvh = pybvh.read_bvh_file(p)
    except Exception as exc:  # pybvh raises ValueError/IndexError on malformed files
        raise SourceError(f"{p}: not a readable BVH file ({type(exc).__name__}: {exc})") from exc
    missing = [j for j in joints if j not in bvh.joint_names]
    if missing:
        raise SourceError(f"{p}: no joint {missing[0]!r}; the file's joints are {', '.join(bvh.joint_names)}")
    if len(joints) < 2:
        raise SourceError("name at least two joints (one arm) for the input chain")
    if not 0 <= skip < bvh.frame_count:
        raise SourceError(f"{p}: cannot skip {skip} of {bvh.frame_count} frames")
    idx = [bvh.joint_names.index(j) for j in joints]
    pos = bvh.joint_positions()[skip:, idx] * float(scale)
    rate = float(bvh.fps)
    return Motion(np.ascontiguousarray(pos, float), (skip + np.arange(pos.shape[0])) / rate, rate, list(joints), str(p))


def marker_chain(data: object, joints: Sequence[str], source: str = "") -> Motion:
    """Chain joints from a :class:`~mirrorlab.plugins.kinematics.io.MarkerData` (``"A"`` or ``"A+B"`` midpoints).

    Raises
    ------
    SourceError
        If a marker label is unknown (the message lists close matches).
    """
    from mirrorlab.plugins.kinematics.errors import KinematicsIOError
    from mirrorlab.plugins.kinematics.store import resolve_label

    cols = []
    for spec in joints:
        try:
            cols.append([resolve_label(data.labels, part.strip()) for part in spec.split("+") if part.strip()])
        except KinematicsIOError as exc:
            raise SourceError(f"{source or 'markers'}: joint {spec!r}: {exc}") from None
        if not cols[-1]:
            raise SourceError(f"{source or 'markers'}: empty joint name in {list(joints)}")
    pos = np.stack([data.points[:, c].mean(axis=1) for c in cols], axis=1)
    return Motion(pos, data.time, float(data.rate), list(joints), source)


def read_marker_chain(path: os.PathLike[str] | str, joints: Sequence[str], fmt: str = "auto") -> Motion:
    """Chain joints from a C3D, TRC or Qualisys TSV marker file (mm)."""
    from mirrorlab.plugins.kinematics.errors import KinematicsIOError
    from mirrorlab.plugins.kinematics.store import read_marker_file

    try:
        data = read_marker_file(path, fmt)
    except KinematicsIOError as exc:
        raise SourceError(str(exc)) from None
    return marker_chain(data, joints, str(path))


def session_marker_chain(path: os.PathLike[str] | str, dataset: str, joints: Sequence[str]) -> Motion:
    """Chain joints from a session's marker set ``/markers/<dataset>`` (mm)."""
    from mirrorlab.core import Session
    from mirrorlab.plugins.kinematics.errors import KinematicsIOError
    from mirrorlab.plugins.kinematics.store import marker_time, read_markers

    with Session.open(path) as s:
        try:
            data = read_markers(s, dataset)
            t = marker_time(s, dataset)
        except KinematicsIOError as exc:
            raise SourceError(f"{path}: {exc}") from None
    m = marker_chain(data, joints, f"{path}:/markers/{dataset}")
    return Motion(m.joints, t, m.rate, m.names, m.source)
