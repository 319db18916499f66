"""Damaged session files: every ``session`` command answers at once with one plain line and exit 1.

Truncated, bit-flipped, non-HDF5 files and folders, and crash-flagged files (read through SWMR,
where HDF5 retries damaged metadata for minutes unless told otherwise). The first tests run the
console script in subprocesses; the hypothesis tests cut and flip real session files at random
offsets and run every command through one worker process (the same ``main`` as the script).
"""

from __future__ import annotations

import hashlib
import os
import re
import signal
import struct
import subprocess
import sys
import textwrap
from collections.abc import Iterator
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from mirrorlab.core import DamagedFileError, Session, SessionError

from tests.cli_worker import CliWorker
from tests.support import make_small_session, run_cli

#: Far above the time an answer takes (tens of ms in-process, about a second for a fresh process on
#: a loaded machine), far below HDF5's retry loops (minutes): only a hang exceeds it.
HANG_S = 30.0

#: Every ``session`` command that reads an existing file (FILE is replaced by the file's path).
COMMANDS = (
    ("info", "FILE"), ("info", "FILE", "--json"), ("tree", "FILE"), ("check", "FILE"),
    ("close", "FILE"), ("close", "FILE", "--aborted"), ("export", "FILE", "thermo/temperature"),
)

#: HDF5 detail that must never reach the user: buffer addresses, open flags, key = value dumps.
HDF5_DETAIL = re.compile(r"0x[0-9a-f]{6,}|flags = |errno = |time = |H5[A-Z]|Traceback", re.IGNORECASE)

CRASH = textwrap.dedent("""
    import os, signal, sys
    from mirrorlab.core import Session
    s = Session.create(sys.argv[1])
    s.add_instrument("thermo", "acme_thermometer", simulate=True, settings={"rate": 100})
    s.start_recording()  # SWMR from here on: the superblock says "open for write"
    os.kill(os.getpid(), signal.SIGKILL)
""")


def sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def argv(command: tuple[str, ...], path: Path) -> list[str]:
    return ["session", *(str(path) if a == "FILE" else a for a in command)]


def assert_one_line_failure(proc: subprocess.CompletedProcess[str], path: Path) -> str:
    """Exit 1 and exactly one line on stderr, naming the file, with no HDF5 internals."""
    lines = proc.stderr.strip().splitlines()
    assert proc.returncode == 1, (proc.args, proc.returncode, proc.stdout, proc.stderr)
    assert len(lines) == 1, (proc.args, proc.stderr)
    assert lines[0].startswith("mirrorlab: error: ") and str(path) in lines[0], lines
    assert not HDF5_DETAIL.search(lines[0]), lines
    return lines[0]


def flip_bit(data: bytes, offset: int, bit: int) -> bytes:
    damaged = bytearray(data)
    damaged[offset] ^= 1 << bit
    return bytes(damaged)


def root_header_offset(data: bytes) -> int:
    """Byte offset of the root group's object header (superblock v2/v3: its 4th address, at byte 36)."""
    assert data[:8] == b"\x89HDF\r\n\x1a\n" and data[8] in (2, 3) and data[9] == 8, data[:12]
    return struct.unpack_from("<Q", data, 36)[0]


@pytest.fixture(scope="module")
def good(tmp_path_factory: pytest.TempPathFactory, acme_site: Path) -> Iterator[Path]:
    path = make_small_session(tmp_path_factory.mktemp("good") / "good.h5", acme_site)
    digest = sha256(path)
    yield path
    assert sha256(path) == digest, "the good file was changed"


@pytest.fixture(scope="module")
def crashed(tmp_path_factory: pytest.TempPathFactory, acme_site: Path) -> Path:
    """A session whose recorder was SIGKILLed: flagged open for write, readable only through SWMR."""
    path = tmp_path_factory.mktemp("crashed") / "crashed.h5"
    proc = subprocess.run([sys.executable, "-c", CRASH, str(path)], timeout=120,
                          env={**os.environ, "PYTHONPATH": str(acme_site)})
    assert proc.returncode == -signal.SIGKILL
    with Session.open(path) as s:  # the pitfall's precondition: only the SWMR fallback opens it
        assert s.crashed and s.status == "open"
    os.remove(str(path) + ".recording")  # as after a reboot: the marker would name a dead pid anyway
    return path


@pytest.fixture(scope="module")
def cli() -> Iterator[CliWorker]:
    with CliWorker() as worker:
        yield worker


def damaged_copies(good: Path, crashed: Path, where: Path) -> dict[str, Path]:
    data, crash = good.read_bytes(), crashed.read_bytes()
    copies = {
        "truncated": data[:100_000],  # `head -c 100000 demo.h5 > trunc.h5`
        "bit-flipped": flip_bit(data, root_header_offset(data) + 20, 2),
        "not HDF5": b"time,value\n0.0,293.1\n",
        "empty": b"",
        "crashed, truncated": crash[:3000],
        "crashed, bit-flipped": flip_bit(crash, root_header_offset(crash) + 20, 2),
    }
    paths = {}
    for name, content in copies.items():
        paths[name] = where / (name.replace(", ", "-").replace(" ", "-") + ".h5")
        paths[name].write_bytes(content)
    paths["folder"] = where / "folder.h5"
    paths["folder"].mkdir()
    return paths


def check_damaged_answer(proc: subprocess.CompletedProcess[str], name: str, path: Path, before: str | None) -> None:
    line = assert_one_line_failure(proc, path)
    if name == "folder":
        assert "is a folder, not a session file" in line, line
    else:
        assert "truncated or damaged HDF5 file" in line and "backup" in line, line
    if before is not None:
        assert sha256(path) == before, f"{name}: {proc.args} changed the file"


#: The console script, each damage with another command (the issue's reports first).
SCRIPT_CASES = (("truncated", COMMANDS[0]), ("bit-flipped", COMMANDS[3]), ("not HDF5", COMMANDS[2]),
                ("empty", COMMANDS[6]), ("crashed, truncated", COMMANDS[5]), ("crashed, bit-flipped", COMMANDS[1]),
                ("folder", COMMANDS[4]))


@pytest.mark.parametrize(("name", "command"), SCRIPT_CASES, ids=[c[0] for c in SCRIPT_CASES])
def test_console_script_answers_one_line(name: str, command: tuple[str, ...], good: Path, crashed: Path,
                                         tmp_path: Path) -> None:
    path = damaged_copies(good, crashed, tmp_path)[name]
    before = sha256(path) if path.is_file() else None
    check_damaged_answer(run_cli(*argv(command, path), timeout=HANG_S), name, path, before)


def test_every_command_answers_one_line_for_every_damage(good: Path, crashed: Path, cli: CliWorker,
                                                          tmp_path: Path) -> None:
    for name, path in damaged_copies(good, crashed, tmp_path).items():
        before = sha256(path) if path.is_file() else None
        for command in COMMANDS:
            check_damaged_answer(cli.run(*argv(command, path), timeout=HANG_S), name, path, before)


def test_messages_say_what_is_wrong(good: Path, crashed: Path, tmp_path: Path) -> None:
    paths = damaged_copies(good, crashed, tmp_path)
    with pytest.raises(DamagedFileError, match=r"only 100,000 of its [\d,]+ bytes are there .*copy it again"):
        Session.open(paths["truncated"])
    with pytest.raises(DamagedFileError, match=r"not an HDF5 file, or a truncated or damaged HDF5 file \(no HDF5 signature\)"):
        Session.open(paths["not HDF5"])
    with pytest.raises(DamagedFileError, match=r"damaged HDF5 file \(incorrect metadata checksum"):
        Session.open(paths["crashed, bit-flipped"])
    (paths["folder"] / "a.h5").write_bytes(b"")
    with pytest.raises(SessionError, match=r"folder\.h5 is a folder, not a session file; .* \(it holds a\.h5\)"):
        Session.open(paths["folder"])


def test_creating_where_one_cannot_write_says_so_in_plain_words(tmp_path: Path) -> None:
    # /sys refuses new files even to root: a real "read-only folder" on any Linux machine
    for target, words in ((Path("/sys/mirrorlab-test.h5"), "Permission denied; check the permissions"),
                          (tmp_path / "file.txt" / "s.h5", "Not a directory")):
        (tmp_path / "file.txt").write_text("not a folder")
        proc = run_cli("session", "new", str(target), timeout=HANG_S)
        line = assert_one_line_failure(proc, target)
        assert f"cannot create {target}: {words}" in line, line


# -- fuzzing ------------------------------------------------------------------------------------

def run_all_commands(cli: CliWorker, path: Path) -> None:
    """Every command on ``path``: exit 0 or one plain line with exit 1. Only a successful ``close``
    (of a crash-flagged file: repair and new status) may change the file."""
    for command in COMMANDS:
        before = path.read_bytes()
        proc = cli.run(*argv(command, path), timeout=HANG_S)
        assert proc.returncode in (0, 1), (proc.args, proc.returncode, proc.stderr)
        if proc.returncode == 1 and not proc.stderr and command[0] in ("check", "close"):
            # not an error: `check` found the session incomplete, `close` found it already closed
            assert proc.stdout.startswith(f"{path}: INCOMPLETE") or "is already" in proc.stdout, proc.stdout
        elif proc.returncode == 1:
            assert_one_line_failure(proc, path)
        else:
            assert "Traceback" not in proc.stderr, proc.stderr
        if proc.returncode == 1 or command[0] != "close":
            assert path.read_bytes() == before, f"{command} changed the file"


#: Metadata sits mostly in the first few KiB (superblock, object headers, heaps); half of the
#: flips land there, the rest anywhere (chunk indexes, the log's and the recording's chunks).
def offsets(size: int) -> st.SearchStrategy[int]:
    return st.one_of(st.integers(0, min(size, 16384) - 1), st.integers(0, size - 1))


FUZZ = settings(deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])


@settings(FUZZ, max_examples=30)
@given(data=st.data())
def test_fuzz_bit_flips(data: st.DataObject, good: Path, cli: CliWorker, tmp_path: Path) -> None:
    raw = good.read_bytes()
    offset, bit = data.draw(offsets(len(raw)), "offset"), data.draw(st.integers(0, 7), "bit")
    path = tmp_path / "flipped.h5"
    path.write_bytes(flip_bit(raw, offset, bit))
    run_all_commands(cli, path)


@settings(FUZZ, max_examples=15)
@given(data=st.data())
def test_fuzz_truncation(data: st.DataObject, good: Path, cli: CliWorker, tmp_path: Path) -> None:
    raw = good.read_bytes()
    path = tmp_path / "cut.h5"
    path.write_bytes(raw[:data.draw(st.integers(0, len(raw) - 1), "length")])
    run_all_commands(cli, path)


@settings(FUZZ, max_examples=15)
@given(data=st.data())
def test_fuzz_crashed_files(data: st.DataObject, crashed: Path, cli: CliWorker, tmp_path: Path) -> None:
    """Crash-flagged files are read through SWMR, where damaged metadata used to retry for minutes."""
    raw = crashed.read_bytes()
    path = tmp_path / "crashed-damaged.h5"
    if data.draw(st.booleans(), "cut"):
        path.write_bytes(raw[:data.draw(st.integers(0, len(raw) - 1), "length")])
    else:
        path.write_bytes(flip_bit(raw, data.draw(offsets(len(raw)), "offset"), data.draw(st.integers(0, 7), "bit")))
    run_all_commands(cli, path)
