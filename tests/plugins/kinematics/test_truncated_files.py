"""Marker files cut short: never a silent import of what happens to be left.

A C3D declares its frame range in the header, so a cut one is an error naming the declared and the
found frame counts. A text file cut inside a row is an error naming the line; one that merely holds
fewer rows than its header declares (the shared TRC is such an excerpt) reads with a warning.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest
from mirrorlab.core.errors import MirrorlabWarning
from mirrorlab.plugins.kinematics import KinematicsIOError, read_c3d, read_qualisys_tsv, read_trc
from mirrorlab.plugins.kinematics.errors import TruncatedMarkerFile

from tests.support import run_cli


def cut(src: Path, dst: Path, size: int) -> Path:
    dst.write_bytes(src.read_bytes()[:size])
    return dst


def test_a_cut_c3d_is_an_error_naming_declared_and_found_frames(tmp_path: Path, data_dir: Path) -> None:
    short = cut(data_dir / "mocap" / "markers_analogs.c3d", tmp_path / "short.c3d", 50_000)
    with pytest.raises(TruncatedMarkerFile) as info:
        read_c3d(short)
    err = info.value
    assert (err.path, err.declared, err.found) == (short, 580, 9) and isinstance(err, KinematicsIOError)
    assert str(err).startswith(f"{short}: cut short: the header declares 580 frames (1..580) but the file holds 9")


def test_cli_import_of_a_cut_c3d_fails_and_creates_nothing(tmp_path: Path, data_dir: Path) -> None:
    short = cut(data_dir / "mocap" / "markers_analogs.c3d", tmp_path / "short.c3d", 50_000)
    proc = run_cli("kinematics", "import", str(short), "--session", str(tmp_path / "s.h5"))
    assert proc.returncode == 1 and "declares 580 frames" in proc.stderr and "holds 9" in proc.stderr
    assert len(proc.stderr.splitlines()) == 1 and not (tmp_path / "s.h5").exists()


def test_a_trc_cut_inside_a_row_is_an_error_naming_the_line(tmp_path: Path, data_dir: Path) -> None:
    real = data_dir / "mocap" / "markers.trc"
    short = cut(real, tmp_path / "short.trc", 30_000)
    with pytest.raises(TruncatedMarkerFile, match=r"short.trc: cut short: line \d+ ends after \d+ of 155 fields") as info:
        read_trc(short)
    assert info.value.declared == 652


def test_a_trc_with_fewer_rows_than_declared_reads_with_a_warning(tmp_path: Path, data_dir: Path) -> None:
    real = data_dir / "mocap" / "markers.trc"
    with pytest.warns(MirrorlabWarning, match=r"markers.trc: the header declares 652 frames but the file holds 93"):
        data = read_trc(real)
    assert data.points.shape[0] == 93
    proc = run_cli("kinematics", "import", str(real), "--session", str(tmp_path / "s.h5"))
    assert proc.returncode == 0, proc.stderr
    assert proc.stderr.startswith("mirrorlab: warning: ") and "declares 652 frames" in proc.stderr
    assert len(proc.stderr.splitlines()) == 1


def test_a_cut_qualisys_tsv(tmp_path: Path, data_dir: Path) -> None:
    real = data_dir / "trajectories" / "6_throws_minimal_tracking_loss.tsv"
    text = real.read_bytes()
    inside = cut(real, tmp_path / "inside.tsv", 400_000)
    with pytest.raises(TruncatedMarkerFile, match=r"inside.tsv: cut short: line \d+ ends after \d+ of 35 fields"):
        read_qualisys_tsv(inside)
    whole_rows = cut(real, tmp_path / "rows.tsv", text.index(b"\n", 400_000) + 1)
    with pytest.warns(MirrorlabWarning, match=r"rows.tsv: the header declares 6282 frames but the file holds \d+"):
        read_qualisys_tsv(whole_rows)


def test_a_c3d_that_crashes_ezc3d_is_an_error_not_a_crash(tmp_path: Path, data_dir: Path) -> None:
    # one flipped bit in the parameter section makes ezc3d segfault (found by tests)
    data = bytearray((data_dir / "mocap" / "markers_analogs.c3d").read_bytes())
    data[7847] ^= 1 << 2
    bad = tmp_path / "flipped.c3d"
    bad.write_bytes(bytes(data))
    with pytest.raises(KinematicsIOError, match=r"flipped.c3d: the C3D reader \(ezc3d\) crashed on this file"):
        read_c3d(bad)


def test_reading_from_an_unguarded_script_runs_the_script_once(tmp_path: Path, data_dir: Path) -> None:
    # the isolated reader must not re-import the caller's main module (as multiprocessing would)
    script = tmp_path / "read.py"
    script.write_text("from mirrorlab.plugins.kinematics import read_c3d\n"
                      f"print(read_c3d({str(data_dir / 'mocap' / 'markers_analogs.c3d')!r}).points.shape)\n")
    proc = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout == "(580, 51, 3)\n"


@pytest.mark.parametrize(("lines", "missing"), [
    (1, "the header keys (DataRate, NumMarkers ...) (line 2), their values (line 3), the marker names (line 4), "
        "the coordinate labels (X1, Y1, Z1 ...) (line 5)"),
    (2, "their values (line 3), the marker names (line 4), the coordinate labels (X1, Y1, Z1 ...) (line 5)"),
    (4, "the coordinate labels (X1, Y1, Z1 ...) (line 5)"),
])
def test_a_trc_cut_inside_its_header_is_named_as_cut(tmp_path: Path, data_dir: Path, lines: int, missing: str) -> None:
    text = (data_dir / "mocap" / "markers.trc").read_text()
    short = tmp_path / "short.trc"
    short.write_text("".join(text.splitlines(keepends=True)[:lines]))
    with pytest.raises(TruncatedMarkerFile) as info:
        read_trc(short)
    assert str(info.value).startswith(f"{short}: cut short: the file ends after line {lines} of its 5-line header: "
                                      f"{missing} and the data rows are missing")
    assert info.value.declared == (652 if lines >= 3 else 0) and info.value.found == 0
    proc = run_cli("kinematics", "import", str(short), "--session", str(tmp_path / "s.h5"))
    assert proc.returncode == 1 and proc.stderr.startswith("mirrorlab: error: ") and "cut short" in proc.stderr
    assert "not a TRC file" not in proc.stderr and len(proc.stderr.splitlines()) == 1


def test_a_trc_that_ends_after_its_header_is_cut_short(tmp_path: Path, data_dir: Path) -> None:
    text = (data_dir / "mocap" / "markers.trc").read_text()
    short = tmp_path / "header.trc"
    short.write_text("".join(text.splitlines(keepends=True)[:6]))  # the 5 header lines and the empty line 6
    with pytest.raises(TruncatedMarkerFile, match=r"header.trc: cut short: the file ends after its header \(line 6\): "
                                                  r"none of the 652 frames it declares is there"):
        read_trc(short)
