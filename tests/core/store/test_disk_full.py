"""A full disk ends a recording with one error line and a readable file, never a crash (exit 139).

The recordings go to a real small file system: a tmpfs of 8 MB mounted for the test (root only).
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import h5py
import pytest
from mirrorlab.core.errors import SessionError
from mirrorlab.core.store.recorder import RESERVE_FLOOR, RESERVE_SECONDS, reserve_bytes

from tests.support import REPO

MB = 1 << 20


@pytest.fixture
def small_disk(tmp_path: Path) -> Iterator[Path]:
    """An 8 MB tmpfs, unmounted after the test."""
    if os.geteuid() != 0:
        pytest.skip("mounting a small tmpfs (`mount -t tmpfs -o size=8m`) needs root; CI runs these tests as root")
    disk = tmp_path / "disk"
    disk.mkdir()
    subprocess.run(["mount", "-t", "tmpfs", "-o", "size=8m", "tmpfs", str(disk)], check=True)
    try:
        yield disk
    finally:
        subprocess.run(["umount", "-l", str(disk)], check=True)


def _record(out: Path, reserve_mb: str, *args: str) -> subprocess.Popen[str]:
    env = {**os.environ, "MIRRORLAB_DISK_RESERVE_MB": reserve_mb}
    return subprocess.Popen([sys.executable, "-m", "mirrorlab.core.cli", "record", *args, "--simulate",
                             "--out", str(out), "--no-progress"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=REPO, env=env)


def _assert_one_line_and_kept(out: Path, stderr: str, code: int | None, why: str) -> int:
    """Exit 1, one line saying the disk is full and what was kept, the file readable as it says; returns
    the samples kept per stream."""
    assert code == 1, stderr
    lines = stderr.strip().splitlines()
    assert len(lines) == 1, stderr
    said = re.fullmatch(rf"mirrorlab: error: the disk of {re.escape(str(out.parent))} is full \({why}.*\): "
                        rf"the recording stopped after [\d.]+ s; everything written until then \((\d+) samples in "
                        rf"(\d+) streams\) is kept in {re.escape(str(out))}; free some space or record to another disk",
                        lines[0])
    assert said, lines[0]
    with h5py.File(out, "r") as f:  # closed normally: no crash flags, no repair needed
        assert f.attrs["status"] == "aborted"
        streams = [g for inst in f["instruments"].values() for g in inst.values() if isinstance(g, h5py.Group)]
        lengths = [(g["data"].shape[0], g["time"].shape[0]) for g in streams]
        messages = [m.decode() for m in f["log"]["message"]]
    assert len(streams) == int(said[2])
    assert sum(n for n, _ in lengths) == int(said[1]) and all(n == t for n, t in lengths), lengths
    assert any("is full" in m for m in messages), messages
    assert sorted(p.name for p in out.parent.iterdir() if p.name.startswith(out.name)) == [out.name]
    return min(n for n, _ in lengths)


def test_a_disk_that_fills_up_ends_the_recording_with_what_was_written(small_disk: Path) -> None:
    """No reserve: HDF5 itself runs into ENOSPC (exit 139 and unreadable files before)."""
    out = small_disk / "film.h5"
    proc = _record(out, "0", "film_scanner", "--fast", "--seconds", "120", "--scene-frames", "100")
    stdout, stderr = proc.communicate(timeout=300)
    kept = _assert_one_line_and_kept(out, stderr, proc.returncode, "no space left")
    assert kept > 0
    with h5py.File(out, "r") as f:
        frames = f["instruments/dev/frames/data"]
        assert frames[kept - 1].any()  # the last kept frame is a frame, not HDF5's fill value
        assert list(f["instruments/dev/frame_index/data"][:kept]) == list(range(kept))


def test_a_disk_filled_by_another_program_stops_the_recording_at_the_reserve(small_disk: Path) -> None:
    out = small_disk / "angle.h5"
    proc = _record(out, "1", "angle_source", "--seconds", "600")
    try:
        marker = out.with_name(out.name + ".recording")
        deadline = time.monotonic() + 120
        while not marker.exists():
            assert proc.poll() is None and time.monotonic() < deadline, proc.communicate()
            time.sleep(0.05)
        time.sleep(1.0)  # some samples on disk (the recorder flushes every 0.5 s)
        free = os.statvfs(small_disk).f_bavail * os.statvfs(small_disk).f_frsize
        fd = os.open(small_disk / "filler", os.O_WRONLY | os.O_CREAT)
        try:
            os.posix_fallocate(fd, 0, free - MB // 2)  # another program leaves 0.5 MB free, below the 1 MB reserve
        finally:
            os.close(fd)
        stdout, stderr = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
    os.remove(small_disk / "filler")
    assert _assert_one_line_and_kept(out, stderr, proc.returncode, r"[\d.]+ MB free, below the reserve of 1.0 MB") > 0


def test_a_disk_below_the_reserve_records_nothing(small_disk: Path) -> None:
    out = small_disk / "none.h5"
    proc = _record(out, "", "angle_source", "--seconds", "5")  # the default reserve: 50 MB
    stdout, stderr = proc.communicate(timeout=120)
    assert proc.returncode == 1
    assert re.fullmatch(rf"mirrorlab: error: the disk of {re.escape(str(small_disk))} is full \([\d.]+ MB free, below "
                        rf"the reserve of {RESERVE_FLOOR / MB:.1f} MB kept free while recording; MIRRORLAB_DISK_RESERVE_MB "
                        rf"sets it\): nothing was recorded into {re.escape(str(out))}; free some space or record to "
                        "another disk", stderr.strip()), stderr


def test_the_reserve_is_the_floor_or_seconds_of_data(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("MIRRORLAB_DISK_RESERVE_MB", raising=False)
    assert reserve_bytes(0.0) == RESERVE_FLOOR
    rate = 2 * RESERVE_FLOOR / RESERVE_SECONDS  # bytes/s: its seconds of data exceed the floor
    assert reserve_bytes(rate) == int(RESERVE_SECONDS * rate)
    monkeypatch.setenv("MIRRORLAB_DISK_RESERVE_MB", "3")
    assert reserve_bytes(0.0) == 3 * MB
    monkeypatch.setenv("MIRRORLAB_DISK_RESERVE_MB", "0")
    assert reserve_bytes(rate) == 0
    for bad in ("lots", "-1", "inf"):
        monkeypatch.setenv("MIRRORLAB_DISK_RESERVE_MB", bad)
        with pytest.raises(SessionError, match="MIRRORLAB_DISK_RESERVE_MB"):
            reserve_bytes(0.0)
