"""Fuzz the marker and point file readers: damaged real files and random text.

Every reader either returns consistent data or raises a typed :class:`MirrorlabError` whose message
names the file; nothing else escapes, nothing hangs (pytest-timeout bounds each test generously).
"""

from __future__ import annotations

import tempfile
import warnings
from collections.abc import Callable, Iterator
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from mirrorlab.core.errors import MirrorlabError, MirrorlabWarning
from mirrorlab.plugins.kinematics import MarkerData, read_c3d, read_qualisys_tsv, read_trc
from mirrorlab.plugins.kinematics.cli import read_mot
from mirrorlab.plugins.photogrammetry.csvio import read_columns_csv, read_marker_csv, read_points_csv

from tests.strategies import damaged, fuzz
from tests.support import SHARED_DATA


def _real(relative: str, rows: int | None = None) -> st.SearchStrategy[bytes]:
    """Damaged copies of a real file of ../shared/data (read when first drawn: the test is marked ``data``)."""
    def read() -> bytes:
        data = (SHARED_DATA / relative).read_bytes()
        return data if rows is None else b"".join(data.splitlines(keepends=True)[:rows])
    return st.deferred(lambda: damaged(read(), hot=HOT[relative]))


#: Bytes of each file where the damage is concentrated (headers, parameter blocks, first rows).
HOT = {"mocap/markers_analogs.c3d": 16 * 512, "mocap/markers.trc": 3000,
       "trajectories/6_throws_minimal_tracking_loss.tsv": 1500, "mocap/inverse_kin.mot": 1200}
MARKER_CSV = b"# 2-D markers\nframe,marker,x,y,xv,yv\n0,0,812.4,401.2,233.9,388.0\n0,1,790.1,455.7,,\n" \
             b"1,0,811.0,402.5,234.1,387.2\n1,1,791.3,454.9,230.0,nan\n"
POINTS_CSV = b"frame,marker,X,Y,Z,gap\n0,0,1,2,3,0.5\n0,1,4,5,6,0.25\n1,0,7,8,9,0\n1,1,nan,nan,nan,nan\n"

#: ezc3d runs in a child process (about 0.3 s per file here); the text readers take milliseconds.
BINARY, TEXT = fuzz(25), fuzz(150)


@pytest.fixture(scope="module")
def folder() -> Iterator[Path]:
    with tempfile.TemporaryDirectory() as name:
        yield Path(name)


def outcome(reader: Callable[[Path], object], path: Path, data: bytes) -> object:
    """Run ``reader`` on ``data`` written to ``path``; a typed error must name the file."""
    path.write_bytes(data)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", MirrorlabWarning)  # fewer rows than declared: allowed
        try:
            return reader(path)
        except MirrorlabError as exc:
            assert path.name in str(exc), f"{type(exc).__name__} does not name the file: {exc}"
            return exc


def consistent(result: object) -> None:
    if isinstance(result, MarkerData):
        assert result.points.ndim == 3 and result.points.shape[1:] == (len(result.labels), 3)
        assert result.points.shape[0] > 0 and np.isfinite(result.rate) and result.rate > 0


@pytest.mark.data
@pytest.mark.timeout(120)
@BINARY
@given(data=_real("mocap/markers_analogs.c3d"))
def test_c3d(folder: Path, data: bytes) -> None:
    consistent(outcome(read_c3d, folder / "fuzz.c3d", data))


@pytest.mark.data
@pytest.mark.timeout(120)
@TEXT
@given(data=_real("mocap/markers.trc") | st.text(max_size=400).map(str.encode))
def test_trc(folder: Path, data: bytes) -> None:
    consistent(outcome(read_trc, folder / "fuzz.trc", data))


@pytest.mark.data
@pytest.mark.timeout(120)
@TEXT
# the header and the first 150 rows of the Qualisys export (the whole file is slow to fuzz)
@given(data=_real("trajectories/6_throws_minimal_tracking_loss.tsv", rows=162) | st.text(max_size=400).map(str.encode))
def test_qualisys_tsv(folder: Path, data: bytes) -> None:
    consistent(outcome(read_qualisys_tsv, folder / "fuzz.tsv", data))


@pytest.mark.timeout(120)
@TEXT
@given(data=damaged(MARKER_CSV) | st.text(max_size=300).map(str.encode))
def test_marker_csv(folder: Path, data: bytes) -> None:
    result = outcome(lambda p: read_marker_csv(p, ("x", "y", "xv", "yv")), folder / "markers.csv", data)
    if not isinstance(result, MirrorlabError):
        assert result.xy().shape[-1] == 2


@pytest.mark.timeout(120)
@TEXT
@given(data=damaged(MARKER_CSV.replace(b"xv,yv", b"plane_x,plane_y").replace(b",,", b",1,2"))
       | st.text(max_size=300).map(str.encode))
def test_columns_csv(folder: Path, data: bytes) -> None:
    outcome(lambda p: read_columns_csv(p, ("x", "y", "plane_x", "plane_y")), folder / "points.csv", data)


@pytest.mark.timeout(120)
@TEXT
@given(data=damaged(POINTS_CSV) | st.text(max_size=300).map(str.encode))
def test_points_csv(folder: Path, data: bytes) -> None:
    result = outcome(read_points_csv, folder / "out.csv", data)
    if not isinstance(result, MirrorlabError):
        points, extra = result
        assert points.ndim == 3 and points.shape[2] == 3
        assert all(v.shape == points.shape[:2] for v in extra.values())


@pytest.mark.data
@pytest.mark.timeout(120)
@TEXT
@given(data=_real("mocap/inverse_kin.mot") | st.text(max_size=300).map(str.encode))
def test_opensim_mot(folder: Path, data: bytes) -> None:
    result = outcome(lambda p: read_mot(p, "elbow_flexion"), folder / "reference.mot", data)
    if not isinstance(result, MirrorlabError):
        time, values = result
        assert time.shape == values.shape and time.ndim == 1 and time.size > 0
