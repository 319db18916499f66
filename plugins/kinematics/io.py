"""Marker-trajectory file I/O: C3D (ezc3d), TRC, Qualisys TSV readers; C3D and CSV writers.

All readers return :class:`MarkerData` with positions in **mm** (converted from the file's unit)
and NaN for missing samples (C3D residual < 0, empty TRC cells, Qualisys all-zero triples).
"""

from __future__ import annotations

import csv
import itertools
import math
import os
import re
import struct
import warnings
from collections import Counter
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from mirrorlab.core import MirrorlabWarning
from numpy.typing import ArrayLike, NDArray

from .c3d_reader import read_c3d_arrays
from .errors import KinematicsIOError, TruncatedMarkerFile

__all__ = ["MarkerData", "read_c3d", "read_trc", "read_qualisys_tsv", "write_c3d", "write_csv", "resolve_label",
           "distinct_labels"]

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
        """Trajectory (T, 3) of one marker named as :func:`resolve_label` accepts (``RKNE#4``...).

        Raises
        ------
        KinematicsIOError
            If the label is unknown (the message lists close matches) or names several markers.
        """
        return self.points[:, resolve_label(self.labels, label)]


def _is_named(label: str, name: str) -> bool:
    return label == name or label.split(":")[-1] == name


def resolve_label(labels: list[str], wanted: str) -> int:
    """Column of marker ``wanted``: an exact label, ``LABEL#N`` or the unique label ending in ``:<wanted>``.

    ``LABEL#N`` picks marker ``N`` of the file (1-based, in file order), which must be labelled
    ``LABEL`` (or ``<prefix>:LABEL``): the way to name one of two markers that share a label.

    Raises
    ------
    KinematicsIOError
        Unknown label (the message lists close matches), or one that names several markers (the
        message lists them and how to pick each).

    Examples
    --------
    >>> resolve_label(["Subj:STER", "Subj:XIPH"], "XIPH")
    1
    >>> resolve_label(["RKNE", "LKNE", "RKNE"], "RKNE#3")
    2
    >>> try:
    ...     resolve_label(["RKNE", "LKNE", "RKNE"], "RKNE")
    ... except KinematicsIOError as exc:
    ...     print(exc)
    marker 'RKNE' is ambiguous: it names markers 1 ('RKNE') and 3 ('RKNE'); give 'RKNE#1' or 'RKNE#3'
    """
    exact = [i for i, lab in enumerate(labels) if lab == wanted]
    picked = re.fullmatch(r"(.+)#(\d+)", wanted)
    if not exact and picked:
        n = int(picked[2])
        if not 1 <= n <= len(labels) or not _is_named(labels[n - 1], picked[1]):
            which = f"marker {n} is {labels[n - 1]!r}" if 1 <= n <= len(labels) else f"there are {len(labels)} markers"
            raise KinematicsIOError(f"no marker {wanted!r}: {which}; LABEL#N names marker N (1-based) labelled LABEL")
        return n - 1
    found = exact or [i for i, lab in enumerate(labels) if lab.split(":")[-1] == wanted]
    if len(found) == 1:
        return found[0]
    if found:
        counts = Counter(labels)
        choices = [repr(labels[i] if counts[labels[i]] == 1 else f"{wanted}#{i + 1}") for i in found]
        raise KinematicsIOError(f"marker {wanted!r} is ambiguous: it names markers "
                                f"{_and([f'{i + 1} ({labels[i]!r})' for i in found])}; give {_and(choices, 'or')}")
    near = [lab for lab in labels if wanted.lower() in lab.lower()]
    raise KinematicsIOError(f"no marker {wanted!r}; similar labels: {near or labels[:12]}")


def _and(items: list[str], word: str = "and") -> str:
    return items[0] if len(items) == 1 else f"{', '.join(items[:-1])} {word} {items[-1]}"


def distinct_labels(labels: list[str]) -> list[str]:
    """``labels`` with ``#N`` (the marker's 1-based number) appended where a label names several markers.

    >>> distinct_labels(["RKNE", "LKNE", "RKNE"])
    ['RKNE#1', 'LKNE', 'RKNE#3']
    """
    counts = Counter(labels)
    return [f"{lab}#{k + 1}" if counts[lab] > 1 else lab for k, lab in enumerate(labels)]


def _warn_shared_labels(p: Path, labels: list[str]) -> None:
    """A :class:`~mirrorlab.core.errors.MirrorlabWarning` naming the labels several markers share."""
    shared = {lab: [k + 1 for k, x in enumerate(labels) if x == lab] for lab, n in Counter(labels).items() if n > 1}
    if shared:
        lab, where = next(iter(shared.items()))
        warnings.warn(MirrorlabWarning(
            f"{p}: markers share labels: " + ", ".join(f"{x!r} (markers {_and(list(map(str, ks)))})"
                                                       for x, ks in shared.items())
            + f"; such a label is refused as ambiguous: name one marker as LABEL#N (its number), e.g. "
              f"'{lab}#{where[-1]}'"), stacklevel=3)


def _c3d_point_frames(section: bytes, order: str) -> int | None:
    """The 16-bit ``POINT:FRAMES`` of a C3D parameter section (``None`` if absent or not 16-bit).

    Records from byte 4: int8 name length (0 ends), int8 group id (negative: a group's own record),
    the name, int16 offset to the next record from that word (0: last record); a parameter goes on
    with int8 type (2 = int16), uint8 dimension count, the dimensions and the values.
    """
    groups: dict[int, str] = {}
    frames: dict[int, int] = {}
    pos = 4
    while pos + 2 <= len(section):
        size, group = struct.unpack_from("bb", section, pos)
        at = pos + 2 + abs(size)
        if size == 0 or group == 0 or at + 4 > len(section):
            break
        name = section[pos + 2:at].decode("ascii", "replace").upper()
        offset, kind, dims = struct.unpack_from(order + "hbB", section, at)
        if group < 0:
            groups[-group] = name
        elif name == "FRAMES" and kind == 2 and at + 6 + dims <= len(section):
            frames[group] = struct.unpack_from(order + "H", section, at + 4 + dims)[0]
        if offset <= 0:
            break
        pos = at + offset
    return next((n for group, n in frames.items() if groups.get(group) == "POINT"), None)


def _c3d_layout(p: Path) -> tuple[int, int, int, int, int | None] | None:
    """Frame range and data layout of a C3D file.

    ``(first, last, data offset in bytes, bytes per frame, POINT:FRAMES)``, or ``None`` when the
    header is not one this can read (the reader then judges the file). Header words (16 bit,
    1-based): 1 parameter block | 2 points | 3 analog values per frame | 4 first frame | 5 last frame
    | 7-8 scale factor (float; negative = float data) | 9 first data block. Byte 3 of the
    parameter section is its number of blocks, byte 4 the processor: 84 Intel, 85 DEC (both
    little-endian), 86 MIPS (big).
    """
    with p.open("rb") as fh:
        header = fh.read(512)
        if len(header) < 512 or header[0] < 1:
            return None
        fh.seek((header[0] - 1) * 512)
        section = fh.read(4)
        if len(section) == 4 and section[2] > 0:  # byte 3: the section's length in blocks
            section += fh.read(512 * section[2] - 4)
    if len(section) < 4 or section[3] not in (84, 85, 86):
        return None
    order = ">" if section[3] == 86 else "<"
    points, analogs, first, last = struct.unpack_from(order + "4H", header, 2)
    (start,) = struct.unpack_from(order + "H", header, 16)
    scale_sign = header[{84: 15, 85: 13, 86: 12}[section[3]]] & 0x80
    return (first, last, (start - 1) * 512, (4 * points + analogs) * (4 if scale_sign else 2),
            _c3d_point_frames(section, order))


def _check_c3d_frames(p: Path) -> None:
    """Check the frames a C3D file holds against the frames it declares.

    The parameter section (``POINT:FRAMES``) declares the frame count; ezc3d and the ``c3d``
    package read that many. The header's first/last-frame words are a copy that some writers leave
    stale: a header that disagrees is a :class:`~mirrorlab.core.errors.MirrorlabWarning`, and a
    file holding fewer frames than ``POINT:FRAMES`` declares is :class:`TruncatedMarkerFile`.
    Without a 16-bit ``POINT:FRAMES`` the header's frame range is checked instead. (ezc3d reads
    whatever frames a cut file holds and adjusts its own copies of both, so the file is read here.)
    """
    layout = _c3d_layout(p)
    if layout is None:
        return
    first, last, offset, per_frame, in_parameters = layout
    in_header = last - first + 1
    declared = in_header if in_parameters is None else in_parameters
    if declared <= 0 or per_frame <= 0 or offset < 0:
        return
    found = max(0, (p.stat().st_size - offset) // per_frame)
    if found < declared:
        said = (f"the header declares {declared} frames ({first}..{last})" if declared == in_header else
                f"POINT:FRAMES declares {declared} frames (the header {in_header}, {first}..{last})")
        raise TruncatedMarkerFile(p, declared, found, f"{said} but the file holds {found}")
    if declared != in_header:
        warnings.warn(MirrorlabWarning(
            f"{p}: the header's frame range {first}..{last} ({in_header} frames) disagrees with POINT:FRAMES "
            f"({declared}); reading the {declared} frames the parameter section declares and the file holds"),
            stacklevel=3)


def read_c3d(path: os.PathLike[str] | str) -> MarkerData:
    """Read the 3-D points of a C3D file of any processor type (Intel, DEC, MIPS).

    Intel and DEC files are read with ezc3d, MIPS (SGI, big-endian) files with the ``c3d``
    package. The frame count is the one the parameter section declares (``POINT:FRAMES``).
    :class:`~mirrorlab.core.errors.MirrorlabWarning` when the header's frame range disagrees with
    it, when ``POINT:UNITS`` is absent (mm is assumed) and when a label names several markers.

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
        If the file holds fewer frames than it declares (it was cut short).
    KinematicsIOError
        If the file cannot be read or has no point data (the reader runs in a child process, so
        a damaged file that crashes it is reported here too).

    Examples
    --------
    >>> import tempfile, os
    >>> p = os.path.join(tempfile.mkdtemp(), "x.c3d")
    >>> write_c3d(p, ["A", "B", "C"], 100.0, np.zeros((4, 3, 3)))
    >>> d = read_c3d(p); d.labels, d.rate, d.points.shape
    (['A', 'B', 'C'], 100.0, (4, 3, 3))
    """
    p = _existing(path, "C3D")
    _check_c3d_frames(p)
    c = read_c3d_arrays(p)
    data = c.points  # (4, M, T)
    if data.ndim != 3 or data.shape[0] < 3 or data.shape[1] == 0 or data.shape[2] == 0:
        raise KinematicsIOError(f"{p}: the C3D file holds no 3-D points")
    if not (np.isfinite(c.rate) and c.rate > 0):
        raise KinematicsIOError(f"{p}: POINT:RATE is {c.rate}, not a frame rate; the file is damaged")
    units = [u.strip() for u in c.units if u.strip()]
    if not units:
        warnings.warn(MirrorlabWarning(f"{p}: no POINT:UNITS parameter; taking the points as mm (the usual C3D "
                                       "unit): check their scale"), stacklevel=2)
    pts = np.transpose(data[:3], (2, 1, 0)) * _scale(units[0] if units else "mm", p)
    if c.residuals.shape == (1, *data.shape[1:]):
        pts[c.residuals[0].T < 0] = np.nan
    n = pts.shape[1]  # a file may name fewer points than it holds: number the rest
    labels = c.labels[:n] + [f"point_{k + 1}" for k in range(len(c.labels), n)]
    _warn_shared_labels(p, labels)
    return MarkerData(labels, c.rate, pts, c.first_frame)


def _split(line: str, sep: str) -> list[str]:
    return line.rstrip("\r\n").split(sep)


def _declared(value: object) -> int | None:
    try:
        return int(str(value).strip())
    except ValueError:
        return None


def _existing(path: str | os.PathLike[str], kind: str) -> Path:
    """``path`` as a :class:`Path`, or :class:`KinematicsIOError` naming it when it is no file (``kind``: C3D, TRC...)."""
    p = Path(path)
    if not p.is_file():
        raise KinematicsIOError(f"{p}: no such {kind} file")
    return p


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


def _time(cells: list[str]) -> float:
    """The Time cell of a TRC data row, or NaN when it is empty or no number (only Frame# is read)."""
    try:
        return float(cells[1])
    except (IndexError, ValueError):
        return math.nan


def _refuse_infinite(p: Path, lineno: int, values: list[float], first_column: int) -> None:
    """:class:`KinematicsIOError` naming the line and column (1-based, ``first_column`` for
    ``values[0]``) of the first infinite value (``1e999``, ``inf``): no coordinate is infinite,
    and an inf would pass every filter and mean into the results."""
    bad = next((k for k, v in enumerate(values) if math.isinf(v)), None)
    if bad is not None:
        raise KinematicsIOError(f"{p}: line {lineno}, column {first_column + bad}: value {values[bad]} is not a "
                                "finite coordinate; correct it, or leave the cell empty for a missing marker")


def _check_order(p: Path, order: list[tuple[int, float, float]]) -> None:
    """:class:`KinematicsIOError` naming the first data row whose frame number (or time, where given)
    does not increase.

    Refused rather than sorted: the rows are read as frames at the file's rate from the first one,
    so rows out of order (or repeated) mean an exporter wrote something else than it declares, and
    sorting would hide it (and could not resolve a repeated frame).
    """
    for (line0, frame0, time0), (line1, frame1, time1) in itertools.pairwise(order):
        if frame1 <= frame0 or time1 <= time0:  # NaN (no Time) compares false
            what = (f"Frame# {frame1:g} after {frame0:g}" if frame1 <= frame0 else f"Time {time1:g} after {time0:g}")
            raise KinematicsIOError(f"{p}: line {line1}: {what} (line {line0}); the rows must be in increasing time "
                                    "order: sort them by Frame# and remove repeated frames")


#: The header lines of a TRC file, in order.
_TRC_HEADER = ("'PathFileType'", "the header keys (DataRate, NumMarkers ...)", "their values",
               "the marker names", "the coordinate labels (X1, Y1, Z1 ...)")


def read_trc(path: os.PathLike[str] | str) -> MarkerData:
    """Read a TRC file (tab- or comma-separated, PathFileType 4).

    All complete data rows are read; fewer rows than the header's ``NumFrames`` give a
    :class:`~mirrorlab.core.errors.MirrorlabWarning`, and so do values past the ``NumMarkers``
    markers (they are not read) and a label naming several markers. Empty cells are NaN.

    Returns
    -------
    MarkerData
        Points converted to mm from the header ``Units``; ``first_frame`` from the first row's
        ``Frame#`` (1-based in the file).

    Raises
    ------
    TruncatedMarkerFile
        If the file ends inside its header, after a header declaring frames, or inside a data row
        (it was cut short).
    KinematicsIOError
        On a malformed header or data row.
    """
    p = _existing(path, "TRC")
    text = p.read_text(errors="replace")
    lines = text.splitlines()
    if not lines or not lines[0].startswith("PathFileType"):
        raise KinematicsIOError(f"{p}: not a TRC file (first line must start with 'PathFileType')")
    sep = "\t" if len(lines) > 1 and "\t" in lines[1] else ","
    keys = [k.strip() for k in _split(lines[1], sep)] if len(lines) > 1 else []
    vals = [v.strip() for v in _split(lines[2], sep)] if len(lines) > 2 else []
    hdr = dict(zip(keys, vals))
    declared = _declared(hdr.get("NumFrames", ""))
    if len(lines) < len(_TRC_HEADER):
        missing = ", ".join(f"{what} (line {k})" for k, what in enumerate(_TRC_HEADER, start=1) if k > len(lines))
        raise TruncatedMarkerFile(p, declared or 0, 0, f"the file ends after line {len(lines)} of its "
                                                       f"{len(_TRC_HEADER)}-line header: {missing} and the data rows "
                                                       "are missing")
    try:
        rate = float(hdr.get("DataRate") or hdr["CameraRate"])
        n_markers = int(hdr["NumMarkers"])
    except (KeyError, ValueError) as exc:
        raise KinematicsIOError(f"{p}: TRC header lacks DataRate/NumMarkers ({exc})") from exc
    if not (np.isfinite(rate) and rate > 0) or not 0 < n_markers <= 100_000:
        raise KinematicsIOError(f"{p}: TRC header gives DataRate {rate} and NumMarkers {n_markers}; "
                                "expected a positive rate and marker count")
    scale = _scale(hdr.get("Units", "mm"), p)
    width = 2 + 3 * n_markers
    rows: list[list[float]] = []  # each as long as its row's values (at most NumMarkers'): padded once sized
    order: list[tuple[int, float, float]] = []  # (line, Frame#, Time) of each row
    last = None
    used_columns = 0
    beyond: tuple[int, int] | None = None  # (line, markers) of the first row holding values past NumMarkers
    for lineno, ln in enumerate(lines[5:], start=6):
        cells = _split(ln, sep)
        if not cells or not cells[0].strip():
            continue
        try:
            order.append((lineno, float(int(float(cells[0]))), _time(cells)))
            rows.append([float(v) if v.strip() else np.nan for v in cells[2:width]])
        except (ValueError, OverflowError):
            raise KinematicsIOError(f"{p}: line {lineno} is not a data row of numbers: {ln[:60]!r}") from None
        _refuse_infinite(p, lineno, rows[-1], 3)
        used = max((k + 1 for k, c in enumerate(cells) if c.strip()), default=0)
        used_columns = max(used_columns, min(used, width))
        if used > width and beyond is None:
            beyond = (lineno, math.ceil((used - 2) / 3))
        last = (lineno, len(cells), width)
    if not rows:
        if declared:
            raise TruncatedMarkerFile(p, declared, 0, f"the file ends after its header (line {len(lines)}): none of "
                                                      f"the {declared} frames it declares is there")
        raise KinematicsIOError(f"{p}: TRC file has no data rows")
    _check_rows(p, text, declared, len(rows), last)
    _check_order(p, order)
    if beyond is not None:
        warnings.warn(MirrorlabWarning(
            f"{p}: line {beyond[0]} holds values of {beyond[1]} markers but the header's NumMarkers is {n_markers}; "
            f"reading the first {n_markers}: correct NumMarkers (line 3) to read the others"), stacklevel=2)
    # Sized by the columns, not by NumMarkers alone: a header claiming 100 000 markers over 51 markers'
    # columns would otherwise fill gigabytes with NaN.
    coordinates = sum(1 for x in _split(lines[4], sep)[2:width] if x.strip())
    held = min(n_markers, max(math.ceil((used_columns - 2) / 3), math.ceil(coordinates / 3), 1))
    if held < n_markers:
        warnings.warn(MirrorlabWarning(
            f"{p}: the header's NumMarkers is {n_markers} but the coordinate labels (line 5) and the data rows hold "
            f"columns of {held} markers; reading {held}: correct NumMarkers (line 3)"), stacklevel=2)
    names = [x.strip() for x in _split(lines[3], sep)[2:]]
    labels = [x for x in names if x][:held]
    labels += [f"M{k + 1}" for k in range(len(labels), held)]
    _warn_shared_labels(p, labels)
    pts = np.full((len(rows), held, 3), np.nan)
    for i, row in enumerate(rows):
        values = row[:3 * held]
        pts[i].flat[:len(values)] = values
    pts *= scale
    frames = [int(frame) for _, frame, _ in order]
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
    p = _existing(path, "TSV")
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
        _refuse_infinite(p, lineno, rows[-1][1:], 3)
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
    _warn_shared_labels(p, labels)
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
