"""C3D files from other machines and writers read as their own tools read them.

* Processor types: the same points written on an Intel (84), a DEC (85: VAX floats) and a MIPS/SGI
  machine (86: big-endian) read identically. The DEC and MIPS copies are made here by
  :func:`convert`, a byte-level converter of this test module written from the C3D manual (not the
  code under test: mirrorlab reads MIPS files through the ``c3d`` package, DEC files through
  ezc3d).
* A header whose last-frame word disagrees with ``POINT:FRAMES`` and the data present: the file
  reads (with a one-line warning) instead of being refused as cut short.
* A file without ``POINT:UNITS``: read as mm with a warning.
"""

from __future__ import annotations

import struct
import warnings
from pathlib import Path

import c3d
import numpy as np
import pytest
from mirrorlab.core.errors import MirrorlabWarning
from mirrorlab.plugins.kinematics import read_c3d, write_c3d
from mirrorlab.plugins.kinematics.errors import TruncatedMarkerFile

from tests.support import run_cli

INTEL, DEC, MIPS = 84, 85, 86
#: Header words (1-based, 16 bit) holding integers and the first words of floats (C3D manual, header
#: table): points, analogs, first/last frame, max gap, data block, analogs per frame, the
#: label/event keys and counts; floats: scale factor, frame rate, 18 event times.
HEADER_INTS = (2, 3, 4, 5, 6, 9, 10, 148, 149, 150, 151, 152)
HEADER_FLOATS = (7, 11, *range(153, 188, 2))


def _floats(raw: bytes, proc: int) -> bytes:
    """Little-endian IEEE floats re-encoded for ``proc``."""
    v = np.frombuffer(raw, "<f4")
    if proc == MIPS:
        return v.astype(">f4").tobytes()
    # VAX F: a value v has the bit pattern of the IEEE float 4 v (exponent bias 129 against 127)
    # with its two 16-bit halves swapped. VAX has no NaN (a missing sample's residual is -1 anyway),
    # and -0 is its reserved operand: both become 0.
    v4 = np.where(np.isfinite(v) & (v != 0), v, 0).astype("<f4") * np.float32(4)
    bits = v4.view("<u4")
    return ((bits >> np.uint32(16)) | (bits << np.uint32(16))).astype("<u4").tobytes()


def convert(src: bytes, proc: int) -> bytes:
    """An Intel C3D file (``src``) as written on a DEC or MIPS machine."""
    out = bytearray(src)
    words = ">" if proc == MIPS else "<"

    def ints(at: int, n: int = 1) -> None:
        out[at:at + 2 * n] = np.frombuffer(src, "<i2", n, at).astype(words + "i2").tobytes()

    def floats(at: int, n: int = 1) -> None:
        out[at:at + 4 * n] = _floats(src[at:at + 4 * n], proc)

    for w in HEADER_INTS:
        ints(2 * (w - 1))
    for w in HEADER_FLOATS:
        floats(2 * (w - 1))
    section = (src[0] - 1) * 512
    out[section + 3] = proc
    pos, end = section + 4, section + 512 * src[section + 2]
    while pos < end:
        size, group = struct.unpack_from("<bb", src, pos)
        if size == 0 or group == 0:
            break
        at = pos + 2 + abs(size)
        (offset,) = struct.unpack_from("<h", src, at)
        ints(at)
        if group > 0:  # a parameter: type, dimensions, values
            kind, ndims = struct.unpack_from("<bB", src, at + 2)
            count = int(np.prod(list(src[at + 4:at + 4 + ndims])))
            if kind == 2:
                ints(at + 4 + ndims, count)
            elif kind == 4:
                floats(at + 4 + ndims, count)
        if offset == 0:
            break
        pos = at + offset
    (data_block,) = struct.unpack_from("<H", src, 16)
    (scale,) = struct.unpack_from("<f", src, 12)
    start = (data_block - 1) * 512
    if scale < 0:
        floats(start, (len(src) - start) // 4)
    else:
        ints(start, (len(src) - start) // 2)
    return bytes(out)


def _copies(intel: Path) -> dict[int, Path]:
    paths = {INTEL: intel}
    for proc in (DEC, MIPS):
        paths[proc] = intel.with_name(f"{intel.stem}-{proc}.c3d")
        paths[proc].write_bytes(convert(intel.read_bytes(), proc))
        assert paths[proc].read_bytes()[512 * (paths[proc].read_bytes()[0] - 1) + 3] == proc
    return paths


def _points(frames: int = 25, markers: int = 4) -> np.ndarray:
    pts = np.random.default_rng(7).normal(0.0, 400.0, (frames, markers, 3))
    pts[3:6, 1] = np.nan  # an occlusion
    return pts


def _same(a, b) -> None:
    assert (a.labels, a.rate, a.first_frame) == (b.labels, b.rate, b.first_frame)
    assert np.array_equal(a.points, b.points, equal_nan=True)  # the same float32 words, bit for bit


def test_the_same_float_trial_from_intel_dec_and_mips_machines_reads_identically(tmp_path: Path) -> None:
    pts = _points()
    intel = tmp_path / "trial.c3d"
    write_c3d(intel, ["RKNE", "LKNE", "RANK", "LANK"], 120.0, pts)
    paths = _copies(intel)
    read = {proc: read_c3d(p) for proc, p in paths.items()}
    assert np.allclose(read[INTEL].points, pts, equal_nan=True, atol=1e-4 * 400)  # float32 storage
    assert np.isnan(read[INTEL].points[3:6, 1]).all()
    _same(read[DEC], read[INTEL])
    _same(read[MIPS], read[INTEL])


def test_the_real_trial_converted_to_dec_and_mips_reads_identically(tmp_path: Path, data_dir: Path) -> None:
    intel = tmp_path / "markers_analogs.c3d"
    intel.write_bytes((data_dir / "mocap" / "markers_analogs.c3d").read_bytes())
    paths = _copies(intel)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # Vicon's header, units and labels agree: nothing to warn about
        ref = read_c3d(intel)
        for proc in (DEC, MIPS):
            _same(read_c3d(paths[proc]), ref)
    assert ref.points.shape == (580, 51, 3)


@pytest.mark.filterwarnings("ignore:No analog data found in file:UserWarning")  # the c3d Writer's remark
def test_an_integer_mips_file_reads_exactly_like_its_intel_copy(tmp_path: Path) -> None:
    # SGI-era files often store points as 16-bit integers times POINT:SCALE; this one is written
    # by the c3d package's Writer (an independent writer), then converted to MIPS
    pts = _points(12, 3)
    w = c3d.Writer(point_rate=60.0, point_scale=0.05)
    frames = np.zeros((12, 3, 5))
    frames[..., :3] = np.nan_to_num(pts)
    frames[..., 3] = np.where(np.isnan(pts).any(-1), -1.0, 0.0)
    w.add_frames([(f, np.zeros((0, 0))) for f in frames])
    w.set_point_labels(["A", "B", "C"])
    intel = tmp_path / "int.c3d"
    with intel.open("wb") as fh:
        w.write(fh)
    paths = _copies(intel)
    ref = read_c3d(intel)
    assert np.allclose(ref.points, pts, equal_nan=True, atol=0.05)  # 16-bit words of 0.05 mm
    for proc in (DEC, MIPS):
        _same(read_c3d(paths[proc]), ref)


def test_the_cli_imports_a_mips_file(tmp_path: Path) -> None:
    intel = tmp_path / "trial.c3d"
    write_c3d(intel, ["A", "B", "C", "D"], 100.0, _points())
    mips = _copies(intel)[MIPS]
    proc = run_cli("kinematics", "import", str(mips), "--session", str(tmp_path / "s.h5"), "--json")
    assert proc.returncode == 0 and proc.stderr == "", proc.stderr
    assert '"frames": 25' in proc.stdout and '"rate_hz": 100.0' in proc.stdout


def _set_header_last_frame(path: Path, last: int, order: str = "<") -> None:
    data = bytearray(path.read_bytes())
    struct.pack_into(order + "H", data, 8, last)  # word 5
    path.write_bytes(bytes(data))


@pytest.mark.parametrize(("proc", "last"), [(INTEL, 95), (INTEL, 10), (MIPS, 95)])
def test_a_stale_header_frame_range_is_a_warning_not_a_cut_file(tmp_path: Path, proc: int, last: int) -> None:
    # 25 frames of 4 markers fill 1600 bytes: a header claiming 95 frames (1..95) would be "cut short"
    # if the header were believed; POINT:FRAMES (25) and the data agree
    pts = _points()
    intel = tmp_path / "trial.c3d"
    write_c3d(intel, ["A", "B", "C", "D"], 100.0, pts)
    ref = read_c3d(intel)
    path = _copies(intel)[proc]
    _set_header_last_frame(path, last, ">" if proc == MIPS else "<")
    with pytest.warns(MirrorlabWarning) as caught:
        got = read_c3d(path)
    _same(got, ref)
    assert len(caught) == 1 and str(caught[0].message) == (
        f"{path}: the header's frame range 1..{last} ({last} frames) disagrees with POINT:FRAMES (25); "
        "reading the 25 frames the parameter section declares and the file holds")


def test_the_cli_imports_a_file_with_a_stale_header_with_one_warning_line(tmp_path: Path) -> None:
    path = tmp_path / "trial.c3d"
    write_c3d(path, ["A", "B", "C", "D"], 100.0, _points())
    _set_header_last_frame(path, 95)
    proc = run_cli("kinematics", "import", str(path), "--session", str(tmp_path / "s.h5"))
    assert proc.returncode == 0, proc.stderr
    assert proc.stderr.startswith("mirrorlab: warning: ") and "disagrees with POINT:FRAMES (25)" in proc.stderr
    assert len(proc.stderr.splitlines()) == 1 and "25 frames" in proc.stdout


def test_a_file_cut_below_its_point_frames_is_still_cut_short(tmp_path: Path) -> None:
    path = tmp_path / "trial.c3d"
    write_c3d(path, ["A", "B", "C", "D"], 100.0, _points(60))
    data = path.read_bytes()
    start = (struct.unpack_from("<H", data, 16)[0] - 1) * 512
    path.write_bytes(data[:start + 20 * 64])  # 20 of 60 frames of 4 float points (64 bytes)
    _set_header_last_frame(path, 20)  # and a header "fixed" to what is left
    with pytest.raises(TruncatedMarkerFile, match=r"cut short: POINT:FRAMES declares 60 frames \(the header 20, "
                                                  r"1\.\.20\) but the file holds 20") as info:
        read_c3d(path)
    assert (info.value.declared, info.value.found) == (60, 20)


def _rename_point_parameter(path: Path, old: bytes, new: bytes) -> None:
    """Rename parameter POINT:``old`` in place (a record is: name length, group id, name, ...)."""
    data = bytearray(path.read_bytes())
    group = -struct.unpack_from("b", data, data.index(b"POINT") - 1)[0]  # a group's record has id -g
    hits = [i for i in range(len(data)) if data.startswith(old, i) and data[i - 2] == len(old) and data[i - 1] == group]
    assert len(hits) == 1 and len(old) == len(new)
    data[hits[0]:hits[0] + len(new)] = new
    path.write_bytes(bytes(data))


def test_a_file_without_point_units_reads_as_mm_with_a_warning(tmp_path: Path) -> None:
    pts = _points()
    path = tmp_path / "trial.c3d"
    write_c3d(path, ["A", "B", "C", "D"], 100.0, pts)
    ref = read_c3d(path)
    _rename_point_parameter(path, b"UNITS", b"UNITZ")
    with pytest.warns(MirrorlabWarning, match=r"trial.c3d: no POINT:UNITS parameter; taking the points as mm"):
        got = read_c3d(path)
    _same(got, ref)
    proc = run_cli("kinematics", "import", str(path), "--session", str(tmp_path / "s.h5"))
    assert proc.returncode == 0, proc.stderr
    assert proc.stderr.startswith("mirrorlab: warning: ") and "no POINT:UNITS" in proc.stderr
    assert len(proc.stderr.splitlines()) == 1
