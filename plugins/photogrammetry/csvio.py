"""CSV files of 2-D marker image coordinates (input) and of reconstructed 3-D points (output).

Marker CSV (``mirrorlab reconstruct --markers FILE``): comma-separated, one row per frame and marker::

    # comment lines start with '#'
    frame,marker,x,y,xv,yv
    0,0,812.4,401.2,233.9,388.0
    0,1,790.1,455.7,,            <- mirror image not seen: empty (or nan)

* ``frame`` and ``marker`` are integers >= 0 and are the array indices (frame f, marker m is
  element ``[f, m]``; frames or markers absent from the file are missing, NaN).
* Coordinate columns by name; which ones are needed depends on the method (``x, y``: the direct
  image; ``xv, yv``: the mirror image). Other columns are ignored. Empty or ``nan`` = not seen.

Calibration points CSV (``mirrorlab calibrate --points FILE``): columns ``x,y`` (image, px) and
``plane_x,plane_y`` (mm on the calibration plane), one row per point, every value required.

Points CSV (``--out FILE``): ``frame,marker,X,Y,Z`` in mm (plus quality columns such as ``gap``),
one row per frame and marker, ``nan`` where not reconstructed.

Malformed input raises :class:`~mirrorlab.core.errors.ValidationError` naming the file, the line
and the reason (the CLI exits with code 2).
"""

from __future__ import annotations

import csv
import os
import warnings
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TextIO

import numpy as np
from mirrorlab.core import Problem, ValidationError
from numpy.typing import NDArray

__all__ = ["MarkerTable", "read_marker_csv", "read_columns_csv", "write_points_csv", "read_points_csv"]

#: Largest frames × markers array a CSV may describe (guards against a typo such as frame 10**9).
MAX_CELLS = 200_000_000


@dataclass(frozen=True)
class MarkerTable:
    """Marker coordinates read from a CSV file.

    Attributes
    ----------
    columns : dict of str -> ndarray (frames, markers)
        Each requested coordinate column, NaN where absent or empty.
    path : Path
    rows : int
        Data rows read.
    """

    columns: dict[str, NDArray[np.float64]]
    path: Path
    rows: int

    def xy(self, x: str = "x", y: str = "y") -> NDArray[np.float64]:
        """Stack two columns into (frames, markers, 2)."""
        return np.stack([self.columns[x], self.columns[y]], axis=-1)


def _fail(path: Path, line: int, reason: str) -> ValidationError:
    return ValidationError([Problem(f"line {line}", reason, str(path))])


def _records(p: Path, names: Sequence[str]) -> Iterator[tuple[int, list[str]]]:
    """Yield ``(line number, cells of the named columns)`` of every data row; check file and header."""
    if not p.is_file():
        raise ValidationError([Problem("file", "no such CSV file; check the path", str(p))])
    with p.open(newline="", encoding="utf-8-sig") as fh:
        try:
            yield from _rows(p, fh, names)
        except UnicodeDecodeError as exc:
            raise ValidationError([Problem("file", f"not UTF-8 text (byte {exc.start}); save it as a UTF-8 CSV",
                                           str(p))]) from None
        except csv.Error as exc:
            raise ValidationError([Problem("file", f"not a readable CSV ({exc})", str(p))]) from None


def _rows(p: Path, fh: TextIO, names: Sequence[str]) -> Iterator[tuple[int, list[str]]]:
    header: list[str] | None = None
    for lineno, row in enumerate(csv.reader(fh), start=1):
        if not row or not "".join(row).strip() or row[0].lstrip().startswith("#"):
            continue
        cells = [c.strip() for c in row]
        if header is None:
            header = [c.lower() for c in cells]
            missing = [c for c in names if c not in header]
            if missing:
                raise _fail(p, lineno, f"header {','.join(cells)} lacks the column(s) {', '.join(missing)}; "
                                       f"expected at least {','.join(names)}")
            cols = [header.index(c) for c in names]
            continue
        if len(cells) < len(header):
            raise _fail(p, lineno, f"{len(cells)} fields, the header has {len(header)}")
        yield lineno, [cells[c] for c in cols]
    if header is None:
        raise _fail(p, 1, "the file is empty; expected a header " + ",".join(names))


def _number(p: Path, lineno: int, name: str, text: str, allow_missing: bool) -> float:
    if not text or text.lower() == "nan":
        if allow_missing:
            return np.nan
        raise _fail(p, lineno, f"column {name}: a value is required")
    try:
        value = float(text)
    except ValueError:
        raise _fail(p, lineno, f"column {name}: {text!r} is not a number"
                               + (" (leave it empty if not seen)" if allow_missing else "")) from None
    if not np.isfinite(value):
        raise _fail(p, lineno, f"column {name}: {text!r} is not finite")
    return value


def read_marker_csv(path: str | os.PathLike[str], required: Sequence[str] = ("x", "y")) -> MarkerTable:
    """Read a marker CSV (see the module docstring) into (frames, markers) arrays.

    Parameters
    ----------
    path : path-like
    required : sequence of str
        Coordinate columns that must be present in the header.

    Returns
    -------
    MarkerTable

    Raises
    ------
    ValidationError
        Missing file or header column, a bad number, a negative or non-integer frame/marker, a short
        row, or a (frame, marker) given twice; names file and line.

    Examples
    --------
    >>> import tempfile, os
    >>> p = os.path.join(tempfile.mkdtemp(), "m.csv")
    >>> _ = open(p, "w").write("frame,marker,x,y\\n0,1,10.5,20\\n1,0,,\\n")
    >>> t = read_marker_csv(p)
    >>> t.xy().shape, t.xy()[0, 1].tolist(), bool(np.isnan(t.xy()[1, 0]).all())
    ((2, 2, 2), [10.5, 20.0], True)
    """
    p = Path(path)
    frames: list[int] = []
    markers: list[int] = []
    values: list[list[float]] = []
    seen: dict[tuple[int, int], int] = {}
    for lineno, cells in _records(p, ("frame", "marker", *required)):
        try:
            f, m = int(cells[0]), int(cells[1])
        except ValueError:
            raise _fail(p, lineno, f"frame and marker must be integers, got {cells[0]!r}, {cells[1]!r}") from None
        if f < 0 or m < 0:
            raise _fail(p, lineno, f"frame and marker must be >= 0, got {f}, {m}")
        if (f, m) in seen:
            raise _fail(p, lineno, f"frame {f}, marker {m} was already given on line {seen[(f, m)]}")
        seen[(f, m)] = lineno
        values.append([_number(p, lineno, name, text, True) for name, text in zip(required, cells[2:])])
        frames.append(f)
        markers.append(m)
    if not frames:
        raise _fail(p, 2, "no data rows after the header")
    fa, ma = np.asarray(frames), np.asarray(markers)
    shape = (int(fa.max()) + 1, int(ma.max()) + 1)
    if shape[0] * shape[1] > MAX_CELLS:
        k = int(np.argmax(fa))
        raise _fail(p, seen[(int(fa[k]), int(ma[k]))],
                    f"frame/marker numbers up to {shape[0] - 1}/{shape[1] - 1} would need a {shape[0]} x {shape[1]} "
                    "array; number frames and markers from 0")
    va = np.asarray(values, dtype=float).reshape(len(frames), len(required))
    columns = {}
    for j, name in enumerate(required):
        a = np.full(shape, np.nan)
        a[fa, ma] = va[:, j]
        columns[name] = a
    return MarkerTable(columns, p, len(frames))


def read_columns_csv(path: str | os.PathLike[str], required: Sequence[str]) -> dict[str, NDArray[np.float64]]:
    """Read named numeric columns (every value required), e.g. calibration points ``x,y,plane_x,plane_y``.

    Raises
    ------
    ValidationError
        Missing file or column, an empty or non-numeric value, no rows; names file and line.

    Examples
    --------
    >>> import tempfile, os
    >>> p = os.path.join(tempfile.mkdtemp(), "c.csv")
    >>> _ = open(p, "w").write("x,y,plane_x,plane_y\\n1,2,10,20\\n")
    >>> read_columns_csv(p, ("x", "plane_y"))["plane_y"].tolist()
    [20.0]
    """
    p = Path(path)
    rows = [[_number(p, lineno, n, t, False) for n, t in zip(required, cells)]
            for lineno, cells in _records(p, required)]
    if not rows:
        raise _fail(p, 2, "no data rows after the header")
    data = np.asarray(rows, dtype=float)
    return {name: data[:, j] for j, name in enumerate(required)}


def write_points_csv(path: str | os.PathLike[str], points: NDArray[np.float64],
                     extra: Mapping[str, NDArray[np.float64]] | None = None) -> Path:
    """Write (frames, markers, 3) points (mm) and optional (frames, markers) columns as CSV.

    Examples
    --------
    >>> import tempfile, os
    >>> p = write_points_csv(os.path.join(tempfile.mkdtemp(), "p.csv"), np.ones((1, 2, 3)), {"gap": np.zeros((1, 2))})
    >>> p.read_text().splitlines()[:2]
    ['frame,marker,X,Y,Z,gap', '0,0,1,1,1,0']
    """
    P = np.asarray(points, float)
    F, M = P.shape[:2]
    f, m = np.meshgrid(np.arange(F), np.arange(M), indexing="ij")
    cols = [f.ravel(), m.ravel(), *P.reshape(-1, 3).T]
    names = ["frame", "marker", "X", "Y", "Z"]
    for name, value in (extra or {}).items():
        cols.append(np.asarray(value, float).reshape(F * M))
        names.append(name)
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    np.savetxt(out, np.column_stack(cols), delimiter=",", header=",".join(names), comments="",
               fmt=["%d", "%d"] + ["%.17g"] * (len(cols) - 2))
    return out


def read_points_csv(path: str | os.PathLike[str]) -> tuple[NDArray[np.float64], dict[str, NDArray[np.float64]]]:
    """Read a points CSV written by :func:`write_points_csv`: points (frames, markers, 3) and extra columns.

    Raises
    ------
    ValidationError
        Missing file, a header other than ``frame,marker,X,Y,Z[,...]``, a non-numeric value, a
        negative or non-integer frame/marker, or no rows; names the file.

    Examples
    --------
    >>> import tempfile, os
    >>> p = write_points_csv(os.path.join(tempfile.mkdtemp(), "p.csv"), np.ones((1, 2, 3)), {"gap": np.zeros((1, 2))})
    >>> pts, extra = read_points_csv(p)
    >>> pts.shape, sorted(extra)
    ((1, 2, 3), ['gap'])
    """
    p = Path(path)
    head = "frame,marker,X,Y,Z"
    try:
        with p.open(encoding="utf-8") as fh:
            names = [c.strip() for c in fh.readline().split(",")]
        if names[:5] != head.split(","):
            raise ValueError(f"the header is {','.join(names)[:60]!r}, expected {head}[,...]")
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)  # "empty input file": reported below
            data = np.loadtxt(p, delimiter=",", skiprows=1, ndmin=2)
        if data.shape[0] == 0 or data.shape[1] != len(names):
            raise ValueError(f"{data.shape[0]} rows of {data.shape[1]} columns under a header of {len(names)}")
    except (OSError, UnicodeDecodeError, ValueError) as exc:
        reason = exc.strerror if isinstance(exc, OSError) else str(exc)
        raise ValidationError([Problem("file", f"not a points CSV of mirrorlab ({reason}); write it with "
                                               "`mirrorlab reconstruct --out`", str(p))]) from None
    index = data[:, :2]
    if not (np.all(np.isfinite(index)) and np.all(index >= 0) and np.all(index == np.round(index))):
        raise ValidationError([Problem("file", "frame and marker must be integers >= 0", str(p))])
    f, m = index.astype(np.int64).T
    F, M = int(f.max()) + 1, int(m.max()) + 1
    if F * M > MAX_CELLS:
        raise ValidationError([Problem("file", f"frame/marker numbers up to {F - 1}/{M - 1} would need a {F} x {M} "
                                               "array; number frames and markers from 0", str(p))])
    pts = np.full((F, M, 3), np.nan)
    pts[f, m] = data[:, 2:5]
    extra = {}
    for j, name in enumerate(names[5:], start=5):
        a = np.full((F, M), np.nan)
        a[f, m] = data[:, j]
        extra[name] = a
    return pts, extra
