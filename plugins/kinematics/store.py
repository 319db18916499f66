"""Marker datasets in a session file: import from C3D / TRC / Qualisys TSV, read back, export.

Layout of one imported marker set (created with :meth:`mirrorlab.core.Session.write_group`)::

    /markers/<name>/                 group
        points    (T, M, 3) float64  positions in mm, NaN where the marker is missing
        time      (T,)      float64  s, (first_frame + k) / rate (the source file's clock)
        @labels        JSON list of M marker names, in column order
        @rate          float, frames per second (Hz)
        @units         "mm"
        @time_unit     "s"
        @first_frame   int, index of frame 0 in the source file (0-based)
        @source_file   absolute path of the file read
        @source_sha256 hex SHA-256 of that file
        @source_format "c3d", "trc" or "tsv"
        @kind          "markers"

Anything stored in this layout (also reconstructed markers written by other plugins) can be read
with :func:`read_markers` and exported with :func:`export_markers`.
"""

from __future__ import annotations

import hashlib
import os
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from .errors import KinematicsIOError
from .io import (
    MarkerData,
    distinct_labels,
    read_c3d,
    read_qualisys_tsv,
    read_trc,
    resolve_label,
    write_c3d,
    write_csv,
)

if TYPE_CHECKING:
    from mirrorlab.core import Session

__all__ = ["FORMATS", "MARKERS_ROOT", "read_marker_file", "marker_group_path", "import_markers",
           "read_markers", "export_markers", "sha256_file", "resolve_label", "marker_names"]

#: Top-level group of marker datasets in a session.
MARKERS_ROOT = "markers"
#: File suffix -> reader.
FORMATS = {"c3d": read_c3d, "trc": read_trc, "tsv": read_qualisys_tsv}


def sha256_file(path: os.PathLike[str] | str) -> str:
    """Hex SHA-256 of a file, read in 1 MiB blocks."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def file_format(path: os.PathLike[str] | str, fmt: str = "auto") -> str:
    """``"c3d"``, ``"trc"`` or ``"tsv"``: ``fmt`` itself, or the file's suffix when ``fmt="auto"``.

    Raises
    ------
    KinematicsIOError
        If the suffix is not one of the supported formats.
    """
    if fmt != "auto":
        if fmt not in FORMATS:
            raise KinematicsIOError(f"unknown marker file format {fmt!r}; use one of {sorted(FORMATS)}")
        return fmt
    suffix = Path(path).suffix.lower().lstrip(".")
    if suffix not in FORMATS:
        raise KinematicsIOError(f"{path}: cannot tell the format from the suffix {Path(path).suffix!r}; "
                                f"expected .c3d, .trc or .tsv (or pass the format explicitly)")
    return suffix


def read_marker_file(path: os.PathLike[str] | str, fmt: str = "auto") -> MarkerData:
    """Read a C3D, TRC or Qualisys TSV marker file (format from the suffix unless given).

    Examples
    --------
    >>> import tempfile, os
    >>> p = os.path.join(tempfile.mkdtemp(), "x.c3d")
    >>> write_c3d(p, ["A", "B", "C"], 50.0, np.zeros((3, 3, 3)))
    >>> read_marker_file(p).labels
    ['A', 'B', 'C']
    """
    return FORMATS[file_format(path, fmt)](path)


def marker_group_path(name: str) -> str:
    """``/markers/<name>`` after checking that ``name`` is one plain HDF5 name.

    Raises
    ------
    KinematicsIOError
        If the name is empty or contains ``/`` or ``.`` only.
    """
    if not name or "/" in name or name in (".", ".."):
        raise KinematicsIOError(f"marker dataset name {name!r} must be a non-empty name without '/'")
    return f"/{MARKERS_ROOT}/{name}"


def import_markers(session: Session, path: os.PathLike[str] | str, name: str | None = None,
                   fmt: str = "auto") -> tuple[str, MarkerData]:
    """Read a marker file and store it as ``/markers/<name>`` in an open, writable session.

    Parameters
    ----------
    session : mirrorlab.core.Session
        Writable session (not recording).
    path : path-like
        C3D, TRC or TSV file.
    name : str, optional
        Dataset name; default: the file's stem.
    fmt : {"auto", "c3d", "trc", "tsv"}

    Returns
    -------
    group_path, data : str, MarkerData

    Raises
    ------
    KinematicsIOError
        Unreadable file, or ``/markers/<name>`` already present (choose another name).
    """
    p = Path(path).resolve()
    fmt = file_format(p, fmt)
    name = name or p.stem
    group = marker_group_path(name)
    if session.exists(group):
        raise KinematicsIOError(f"{session.path} already holds {group}; pass another name (--name) "
                                "because marker datasets are never overwritten")
    data = FORMATS[fmt](p)
    session.write_group(group, {"points": data.points, "time": data.time}, {
        "labels": list(data.labels), "rate": float(data.rate), "unit": "mm", "units": "mm", "time_unit": "s",
        "first_frame": int(data.first_frame), "source_file": str(p), "source_sha256": sha256_file(p),
        "source_format": fmt, "kind": "markers",
    })
    return group, data


def _group_of(session: Session, name: str) -> str:
    """The path of the marker group ``name`` (``/markers/<name>``, or any group path holding ``points``)."""
    key = name.strip("/")
    if "/" not in key:
        key = f"{MARKERS_ROOT}/{key}"
    if "points" not in session.members(key):
        have = sorted(session.members(MARKERS_ROOT))
        raise KinematicsIOError(f"{session.path} has no marker dataset {name!r} (a group with 'points'); "
                                f"marker datasets here: {have or 'none'} (`mirrorlab kinematics import` adds one)")
    return f"/{key}"


def marker_names(session: Session) -> list[str]:
    """Names of the marker datasets under ``/markers``."""
    return sorted(k for k in session.members(MARKERS_ROOT) if "points" in session.members(f"{MARKERS_ROOT}/{k}"))


def read_markers(session: Session, name: str) -> MarkerData:
    """Read ``/markers/<name>`` (or any group path holding ``points`` in this layout) of ``session``.

    ``labels`` default to ``M1..Mn`` and ``rate`` is derived from ``time`` when the attributes are
    absent (e.g. markers reconstructed by another plugin).

    Raises
    ------
    KinematicsIOError
        No such group, or ``points`` not (T, M, 3).
    """
    group = _group_of(session, name)
    pts = np.asarray(session.read(f"{group}/points"), dtype=float)
    if pts.ndim != 3 or pts.shape[2] != 3:
        raise KinematicsIOError(f"{group}/points has shape {pts.shape}; expected (frames, markers, 3)")
    labels = session.json_attribute(group, "labels", None) or [f"M{k + 1}" for k in range(pts.shape[1])]
    if len(labels) != pts.shape[1]:
        raise KinematicsIOError(f"{group}: {len(labels)} labels for {pts.shape[1]} markers")
    attrs = session.attributes(group)
    first = int(attrs.get("first_frame", 0))
    if "rate" in attrs:
        rate = float(attrs["rate"])
    elif "time" in session.members(group) and session.node(f"{group}/time").shape[0] > 1:
        rate = float(1.0 / np.median(np.diff(session.read(f"{group}/time"))))
    else:
        raise KinematicsIOError(f"{group} has neither a 'rate' attribute nor a 'time' dataset")
    return MarkerData(list(labels), rate, pts, first)


def marker_time(session: Session, name: str) -> np.ndarray:
    """The ``time`` dataset of a marker group of ``session`` (or ``(first_frame + k) / rate``)."""
    group = _group_of(session, name)
    if "time" in session.members(group):
        return np.asarray(session.read(f"{group}/time"), dtype=float)
    return read_markers(session, name).time


def export_markers(data: MarkerData, out: os.PathLike[str] | str, fmt: str) -> None:
    """Write marker data as ``csv`` (:func:`~.io.write_csv`) or ``c3d`` (:func:`~.io.write_c3d`).

    A C3D file keeps the labels as they are; CSV column names must tell markers apart, so labels
    that several markers share get their number there (``RKNE#4_x_mm``, see :func:`~.io.distinct_labels`).
    """
    if fmt == "csv":
        write_csv(out, distinct_labels(data.labels), data.rate, data.points, first_frame=data.first_frame)
    elif fmt == "c3d":
        write_c3d(out, data.labels, data.rate, data.points)
    else:
        raise KinematicsIOError(f"unknown export format {fmt!r}; use csv or c3d")
