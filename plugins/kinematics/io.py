"""Marker-trajectory file I/O: C3D (ezc3d), TRC, Qualisys TSV readers; C3D and CSV writers.

All readers return :class:`MarkerData` with positions in **mm** (converted from the file's unit)
and NaN for missing samples (C3D residual < 0, empty TRC cells, Qualisys all-zero triples).
"""

from __future__ import annotations

import csv
import os
import struct
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from mirrorlab.core import MirrorlabWarning
from numpy.typing import ArrayLike, NDArray

from .c3d_reader import read_c3d_arrays
from .errors import KinematicsIOError, TruncatedMarkerFile

__all__ = ["MarkerData", "read_c3d", "read_trc", "read_qualisys_tsv", "write_c3d", "write_csv"]

FloatArray = NDArray[np.float64]

_UNIT_TO_MM = {"mm": 1.0, "millimeters": 1.0, "cm": 10.0, "m": 1000.0, "meters": 1000.0, "dm": 100.0}


def _scale(unit: str, path: os.PathLike[str] | str) -> float:
    u = unit.strip().lower()
    if u not in _UNIT_TO_MM:
        raise KinematicsIOError(f"{path}: unknown length unit {unit!r}; expected one of {sorted(_UNIT_TO_MM)}")
    return _UNIT_TO_MM[u]


@dataclass(frozen=True)
class MarkerData:
    """Marker trajectories.

    Attributes
    ----------
    labels : list of str
        Marker names, one per column of ``points``.
    rate : float
        Frame rate (Hz).
    points : ndarray, shape (T, M, 3)
        Positions in mm, NaN where missing.
    first_frame : int
        Index of the first frame in the source (0-based; C3D frame number minus 1).
    """

    labels: list[str]
    rate: float
    points: FloatArray
    first_frame: int = 0

    @property
    def time(self) -> FloatArray:
        """Frame times in s, ``(first_frame + k) / rate``."""
        return (self.first_frame + np.arange(self.points.shape[0])) / self.rate

    def marker(self, label: str) -> FloatArray:
        """Trajectory (T, 3) of one marker by label.

        Raises
        ------
        KinematicsIOError
            If the label is unknown (the message lists close matches).
        """
        if label not in self.labels:
            near = [x for x in self.labels if label.lower() in x.lower()]
            raise KinematicsIOError(f"no marker {label!r}; similar labels: {near or self.labels[:10]}")
        return self.points[:, self.labels.index(label)]


def _c3d_layout(p: Path) -> tuple[int, int, int, int] | None:
    """Frame range and data layout from a C3D header: (first, last, data offset in bytes, bytes per frame).

    ``None`` when the header is not one this can read (ezc3d then judges the file). Header words
    (16 bit, 1-based): 1 parameter block | 2 points | 3 analog values per frame | 4 first frame |
    5 last frame | 7-8 scale factor (float; negative = float data) | 9 first data block. Byte 4 of
    the parameter block names the processor: 84 Intel, 85 DEC (both little-endian), 86 MIPS (big).
    """
    with p.open("rb") as fh:
        header = fh.read(512)
        if len(header) < 512 or header[0] < 1:
            return None
        fh.seek((header[0] - 1) * 512)
        param = fh.read(4)
    if len(param) < 4 or param[3] not in (84, 85, 86):
        return None
    order = ">" if param[3] == 86 else "<"
    points, analogs, first, last = struct.unpack_from(order + "4H", header, 2)
    (start,) = struct.unpack_from(order + "H", header, 16)
    scale_sign = header[{84: 15, 85: 13, 86: 12}[param[3]]] & 0x80
    return first, last, (start - 1) * 512, (4 * points + analogs) * (4 if scale_sign else 2)


def _check_c3d_length(p: Path) -> None:
    """Raise :class:`TruncatedMarkerFile` if the file is shorter than the frames its header declares.

    ezc3d reads whatever frames a cut file holds and adjusts its own header copy to match, so the
    declared frame range is read from the file's header here.
    """
    layout = _c3d_layout(p)
    if layout is None:
        return
    first, last, offset, per_frame = layout
    declared = last - first + 1
    if declared <= 0 or per_frame <= 0 or offset < 0:
        return
    found = max(0, (p.stat().st_size - offset) // per_frame)
    if found < declared:
        raise TruncatedMarkerFile(p, declared, found, f"the header declares {declared} frames ({first}..{last}) "
                                                      f"but the file holds {found}")


def read_c3d(path: os.PathLike[str] | str) -> MarkerData:
    """Read the 3-D points of a C3D file with ezc3d.

    Parameters
    ----------
    path : path-like
        C3D file.

    Returns
    -------
    MarkerData
        Points in mm (``POINT:UNITS`` honoured), NaN where the residual is negative or the point
        is NaN.

    Raises
    ------
    TruncatedMarkerFile
        If the file holds fewer frames than its header declares (it was cut short).
    KinematicsIOError
        If the file cannot be read or has no point data (ezc3d runs in a child process, so a
        damaged file that crashes it is reported here too).

    Examples
    --------
    >>> import tempfile, os
    >>> p = os.path.join(tempfile.mkdtemp(), "x.c3d")
    >>> write_c3d(p, ["A", "B", "C"], 100.0, np.zeros((4, 3, 3)))
    >>> d = read_c3d(p); d.labels, d.rate, d.points.shape
    (['A', 'B', 'C'], 100.0, (4, 3, 3))
    """
    p = Path(path)
    if not p.is_file():
        raise KinematicsIOError(f"{p}: no such C3D file")
    _check_c3d_length(p)
    c = read_c3d_arrays(p)
    data = c.points  # (4, M, T)
    if data.ndim != 3 or data.shape[0] < 3 or data.shape[1] == 0 or data.shape[2] == 0:
        raise KinematicsIOError(f"{p}: the C3D file holds no 3-D points")
    if not (np.isfinite(c.rate) and c.rate > 0):
        raise KinematicsIOError(f"{p}: POINT:RATE is {c.rate}, not a frame rate; the file is damaged")
    unit = c.units[0] if c.units else "mm"
    pts = np.transpose(data[:3], (2, 1, 0)) * _scale(unit, p)
    if c.residuals.shape == (1, *data.shape[1:]):
        pts[c.residuals[0].T < 0] = np.nan
    n = pts.shape[1]  # a file may name fewer points than it holds: number the rest
    labels = c.labels[:n] + [f"point_{k + 1}" for k in range(len(c.labels), n)]
    return MarkerData(labels, c.rate, pts, c.first_frame)


def _split(line: str, sep: str) -> list[str]:
    return line.rstrip("\r\n").split(sep)


def _declared(value: object) -> int | None:
    try:
        return int(str(value).strip())
    except ValueError:
        return None


def _check_rows(p: Path, text: str, declared: int | None, rows: int, last: tuple[int, int, int] | None) -> None:
    """A text marker file against its header's frame count.

    ``last`` is (line number, fields, fields expected) of the last data row. A last row with too
    few fields and no line end is a file cut inside a row: :class:`TruncatedMarkerFile`. Fewer
    complete rows than declared is a warning (:class:`~mirrorlab.core.errors.MirrorlabWarning`):
    an excerpt, or a file cut at a line end, which cannot be told apart.
    """
    if last is not None and not text.endswith(("\n", "\r")) and last[1] < last[2]:
        raise TruncatedMarkerFile(p, declared or 0, rows - 1,
                                  f"line {last[0]} ends after {last[1]} of {last[2]} fields"
                                  + (f" (the header declares {declared} frames)" if declared else ""))
    if declared is not None and rows < declared:
        warnings.warn(MirrorlabWarning(f"{p}: the header declares {declared} frames but the file holds {rows}; "
                                       f"using those {rows} (an excerpt, or a copy cut short)"), stacklevel=3)


def read_trc(path: os.PathLike[str] | str) -> MarkerData:
    """Read a TRC file (tab- or comma-separated, PathFileType 4).

    All complete data rows are read; fewer rows than the header's ``NumFrames`` give a
    :class:`~mirrorlab.core.errors.MirrorlabWarning`. Empty cells are NaN.

    Returns
    -------
    MarkerData
        Points converted to mm from the header ``Units``; ``first_frame`` from the first row's
        ``Frame#`` (1-based in the file).

    Raises
    ------
    TruncatedMarkerFile
        If the file ends inside a data row (it was cut short).
    KinematicsIOError
        On a malformed header or data row.
    """
    p = Path(path)
    if not p.is_file():
        raise KinematicsIOError(f"{p}: no such TRC file")
    text = p.read_text(errors="replace")
    lines = text.splitlines()
    if len(lines) < 5 or not lines[0].startswith("PathFileType"):
        raise KinematicsIOError(f"{p}: not a TRC file (first line must start with 'PathFileType')")
    sep = "\t" if "\t" in lines[1] else ","
    keys = [k.strip() for k in _split(lines[1], sep)]
    vals = [v.strip() for v in _split(lines[2], sep)]
    hdr = dict(zip(keys, vals))
    try:
        rate = float(hdr.get("DataRate") or hdr["CameraRate"])
        n_markers = int(hdr["NumMarkers"])
    except (KeyError, ValueError) as exc:
        raise KinematicsIOError(f"{p}: TRC header lacks DataRate/NumMarkers ({exc})") from exc
    if not (np.isfinite(rate) and rate > 0) or not 0 < n_markers <= 100_000:
        raise KinematicsIOError(f"{p}: TRC header gives DataRate {rate} and NumMarkers {n_markers}; "
                                "expected a positive rate and marker count")
    scale = _scale(hdr.get("Units", "mm"), p)
    names = [x.strip() for x in _split(lines[3], sep)[2:]]
    labels = [x for x in names if x][:n_markers]
    labels += [f"M{k + 1}" for k in range(len(labels), n_markers)]
    rows = []
    frames = []
    last = None
    for lineno, ln in enumerate(lines[5:], start=6):
        cells = _split(ln, sep)
        if not cells or not cells[0].strip():
            continue
        try:
            frames.append(int(float(cells[0])))
            vals3 = cells[2 : 2 + 3 * n_markers]
            vals3 += [""] * (3 * n_markers - len(vals3))
            rows.append([float(v) if v.strip() else np.nan for v in vals3])
        except (ValueError, OverflowError):
            raise KinematicsIOError(f"{p}: line {lineno} is not a data row of numbers: {ln[:60]!r}") from None
        last = (lineno, len(cells), 2 + 3 * n_markers)
    if not rows:
        raise KinematicsIOError(f"{p}: TRC file has no data rows")
    _check_rows(p, text, _declared(hdr.get("NumFrames", "")), len(rows), last)
    pts = np.asarray(rows, dtype=float).reshape(len(rows), n_markers, 3) * scale
    return MarkerData(labels, rate, pts, frames[0] - 1)


def read_qualisys_tsv(path: os.PathLike[str] | str) -> MarkerData:
    """Read a Qualisys 3-D TSV export; unnamed trajectories are labelled ``unlabeled_<k>``.

    A marker whose X, Y and Z are all exactly 0.000 is treated as not visible (NaN). Fewer rows
    than the header's ``NO_OF_FRAMES`` give a :class:`~mirrorlab.core.errors.MirrorlabWarning`.

    Returns
    -------
    MarkerData
        Points in mm.

    Raises
    ------
    TruncatedMarkerFile
        If the file ends inside a data row (it was cut short).
    KinematicsIOError
        On a malformed header or data row.
    """
    p = Path(path)
    if not p.is_file():
        raise KinematicsIOError(f"{p}: no such TSV file")
    text = p.read_text(errors="replace")
    lines = text.splitlines()
    hdr: dict[str, list[str]] = {}
    for n_hdr, ln in enumerate(lines):  # noqa: B007 - n_hdr is used after the loop
        cells = ln.split("\t")
        if cells[0] == "Frame":
            break
        hdr[cells[0]] = cells[1:]
    else:
        raise KinematicsIOError(f"{p}: no 'Frame' column-header line; not a Qualisys 3-D TSV")
    try:
        rate = float(hdr["FREQUENCY"][0])
        n_markers = int(hdr["NO_OF_MARKERS"][0])
    except (KeyError, ValueError, IndexError) as exc:
        raise KinematicsIOError(f"{p}: header lacks FREQUENCY / NO_OF_MARKERS") from exc
    if not (np.isfinite(rate) and rate > 0) or not 0 < n_markers <= 100_000:
        raise KinematicsIOError(f"{p}: header gives FREQUENCY {rate} and NO_OF_MARKERS {n_markers}; "
                                "expected a positive rate and marker count")
    width = 2 + 3 * n_markers
    rows = []
    last = None
    for lineno, ln in enumerate(lines[n_hdr + 1:], start=n_hdr + 2):
        if not ln.strip():
            continue
        cells = ln.split("\t")
        last = (lineno, len(cells), width)
        if len(cells) < width:
            if lineno == len(lines):
                break  # the last line: _check_rows says whether the file was cut inside it
            raise KinematicsIOError(f"{p}: line {lineno} has {len(cells)} fields; the header needs {width}")
        try:
            rows.append([float(cells[0]), *map(float, cells[2:width])])
        except ValueError:
            raise KinematicsIOError(f"{p}: line {lineno} is not a data row of numbers: {ln[:60]!r}") from None
    if not rows:
        raise KinematicsIOError(f"{p}: the TSV file has no data rows")
    _check_rows(p, text, _declared((hdr.get("NO_OF_FRAMES") or [""])[0]), len(rows), last)
    table = np.asarray(rows, dtype=float)
    frames = table[:, 0]
    pts = table[:, 1:].reshape(table.shape[0], n_markers, 3)
    pts[np.all(pts == 0.0, axis=-1)] = np.nan
    names = [x.strip() for x in hdr.get("MARKER_NAMES", [])]
    labels = [names[i] if i < len(names) and names[i] else f"unlabeled_{i - len([n for n in names if n]) + 1}"
              for i in range(n_markers)]
    return MarkerData(labels, rate, pts, int(frames[0]) - 1)


def _check_points(labels: list[str], points: ArrayLike) -> FloatArray:
    pts = np.asarray(points, dtype=float)
    if pts.ndim != 3 or pts.shape[2] != 3 or pts.shape[1] != len(labels):
        raise KinematicsIOError(
            f"points must have shape (T, {len(labels)}, 3) to match the labels, got {pts.shape}"
        )
    return pts


def write_c3d(path: os.PathLike[str] | str, labels: list[str], rate: float, points: ArrayLike) -> None:
    """Write marker trajectories (mm, NaN = missing) to a float C3D file via ezc3d.

    Missing samples get residual -1 so that :func:`read_c3d` (and other readers) restore NaN.

    Parameters
    ----------
    path : path-like
    labels : list of str
    rate : float
        Frame rate (Hz).
    points : array_like, shape (T, M, 3)
        Positions (mm).
    """
    import ezc3d

    pts = _check_points(list(labels), points)
    T, M, _ = pts.shape
    c = ezc3d.c3d()
    c["parameters"]["POINT"]["RATE"]["value"] = [float(rate)]
    c["parameters"]["POINT"]["LABELS"]["value"] = tuple(str(x) for x in labels)
    c["parameters"]["POINT"]["UNITS"]["value"] = ["mm"]
    data = np.ones((4, M, T))
    data[:3] = np.transpose(pts, (2, 1, 0))
    c["data"]["points"] = data
    resid = np.zeros((1, M, T))
    resid[0][np.any(~np.isfinite(pts), axis=-1).T] = -1.0
    c["data"]["meta_points"] = {"residuals": resid, "camera_masks": np.zeros((7, M, T), dtype=bool)}
    c.write(str(path))


def write_csv(
    path: os.PathLike[str] | str,
    labels: list[str],
    rate: float,
    points: ArrayLike,
    first_frame: int = 0,
) -> None:
    """Write marker trajectories to CSV: ``frame,time_s,<label>_x_mm,<label>_y_mm,<label>_z_mm,...``.

    Missing samples are written as empty cells; ``frame`` is 0-based.

    Examples
    --------
    >>> import tempfile, os
    >>> p = os.path.join(tempfile.mkdtemp(), "x.csv")
    >>> write_csv(p, ["A"], 10.0, [[[1.0, 2.0, np.nan]]])
    >>> open(p).read().splitlines()
    ['frame,time_s,A_x_mm,A_y_mm,A_z_mm', '0,0,1,2,']
    """
    pts = _check_points(list(labels), points)
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["frame", "time_s"] + [f"{lab}_{ax}_mm" for lab in labels for ax in "xyz"])
        for k, row in enumerate(pts.reshape(pts.shape[0], -1)):
            fr = first_frame + k
            w.writerow([fr, f"{fr / rate:.10g}"] + ["" if not np.isfinite(v) else f"{v:.10g}" for v in row])
