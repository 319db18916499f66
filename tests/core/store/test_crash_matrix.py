"""The crash matrix: a real ``mirrorlab`` process killed (SIGKILL) at every phase of a session's life
leaves a file that ``session check`` / ``info`` / ``close`` and the read API open, with everything
written before the kill (issue 20, item 1).

The process is stopped at each phase by ``crashpoint/sitecustomize.py`` (test-only, on
``PYTHONPATH``), which writes a marker file there and waits: the test kills it once the marker is
there, so no kill depends on timing. Between stop and kill the test also checks that a file a live
process writes is never repaired under it and is reported as such.
"""

from __future__ import annotations

import os
import shutil
import signal
import stat
import subprocess
import sys
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import h5py
import numpy as np
import pytest
from mirrorlab.core import Session, SessionError

from tests.support import run_cli

CRASHPOINT = Path(__file__).with_name("crashpoint")
_SCRIPT = Path(sys.executable).with_name("mirrorlab")
#: The console script, the real entry point (``python -m`` where the interpreter has none beside it).
MIRRORLAB = [str(_SCRIPT)] if _SCRIPT.exists() else [sys.executable, "-m", "mirrorlab.core.cli"]

#: A short recording of a finite virtual film (no port): preview, record to the end, one analysis step.
RECORD = """\
[session]
description = "crash matrix"
[instruments.cam]
plugin = "film_scanner"
settings = { source = "virtual", scene = "rssr", scene_frames = 20, frame_rate = 100.0, lines = 16 }
[[steps]]
action = "preview"
seconds = 0.05
[[steps]]
action = "acquire"
seconds = 0
[[steps]]
action = "run"
algorithm = "derivatives"
inputs = { time = "/instruments/cam/frames/time", values = "/instruments/cam/frame_index/data" }
"""
#: Two analysis steps, the second on the first's results.
ANALYSE = """\
[[steps]]
action = "run"
algorithm = "filter"
inputs = { time = "/instruments/cam/frames/time", values = "/instruments/cam/frame_index/data" }
[[steps]]
action = "run"
algorithm = "derivatives"
inputs = { time = "@filter/time", values = "@filter/filtered" }
"""

SESSION_FILE = "mirrorlab.core.store.session_file"


@dataclass(frozen=True)
class Phase:
    name: str
    command: str  # "new", "record" or "analyse"
    stop_at: str  # MIRRORLAB_CRASH_AT (see crashpoint/sitecustomize.py)
    results: int = 0  # analysis results finished before the kill
    recorded: bool = False  # the recording was over (stopped and flushed) before the kill


PHASES = [
    Phase("session new", "new", f"{SESSION_FILE}:SessionFile.create:after"),
    Phase("setup", "record", f"{SESSION_FILE}:SessionFile.write_instrument:after"),
    Phase("preview", "record", "event:acquisition_started"),
    Phase("recording", "record", "event:recording_started"),
    Phase("stop", "record", f"{SESSION_FILE}:SessionFile.stop_recording:after", recorded=True),
    Phase("post-recording step running", "record", "mirrorlab.core.compute:execute:before", recorded=True),
    Phase("post-recording step writing", "record", f"{SESSION_FILE}:SessionFile.write_result:before", recorded=True),
    Phase("close", "record", f"{SESSION_FILE}:SessionFile.finish:after", recorded=True),
    Phase("analysis step 1 running", "analyse", "mirrorlab.core.compute:execute:before#1"),
    Phase("analysis step 1 writing", "analyse", f"{SESSION_FILE}:SessionFile.write_result:before#1"),
    Phase("analysis between steps", "analyse", f"{SESSION_FILE}:SessionFile.write_result:after#1", results=1),
    Phase("analysis step 2 writing", "analyse", f"{SESSION_FILE}:SessionFile.write_result:before#2", results=1),
    Phase("analysis close", "analyse", f"{SESSION_FILE}:SessionFile.finish:after", results=2),
]


#: Every process :func:`stop_at` started in the running test (see :func:`no_process_left`).
_started: list[subprocess.Popen[str]] = []


@pytest.fixture(autouse=True)
def no_process_left() -> Iterator[None]:
    """A test that fails before its kill leaves its process waiting at the crash point: end it."""
    yield
    while _started:
        proc = _started.pop()
        if proc.poll() is None:
            proc.kill()
            proc.communicate(timeout=30)


def stop_at(spec: str, args: list[str], folder: Path, timeout: float = 60.0) -> subprocess.Popen[str]:
    """Start ``mirrorlab args`` in ``folder`` and return it once it stopped at ``spec``."""
    mark = folder / "stopped-at"
    mark.unlink(missing_ok=True)
    env = {**os.environ, "MIRRORLAB_CRASH_AT": spec, "MIRRORLAB_CRASH_MARK": str(mark),
           "PYTHONPATH": os.pathsep.join(filter(None, [str(CRASHPOINT), os.environ.get("PYTHONPATH")]))}
    proc = subprocess.Popen([*MIRRORLAB, *args], cwd=folder, env=env, text=True,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    _started.append(proc)
    deadline = time.monotonic() + timeout
    while not mark.exists():  # written by the process once it stands at the phase
        if proc.poll() is not None:
            out, err = proc.communicate()
            pytest.fail(f"mirrorlab ended (exit {proc.returncode}) before {spec}: {out}{err}")
        assert time.monotonic() < deadline, f"mirrorlab did not reach {spec} in {timeout} s"
        time.sleep(0.02)
    return proc


def kill(proc: subprocess.Popen[str]) -> None:
    os.kill(proc.pid, signal.SIGKILL)
    proc.communicate(timeout=30)
    assert proc.returncode == -signal.SIGKILL


@pytest.fixture(scope="module")
def recorded(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """A finished recording, and a copy of it with the analysis run to its end (the reference)."""
    folder = tmp_path_factory.mktemp("recorded")
    (folder / "record.toml").write_text(RECORD)
    (folder / "analyse.toml").write_text(ANALYSE)
    done = subprocess.run([*MIRRORLAB, "run", "record.toml", "--out", "recorded.h5", "--no-progress"], cwd=folder,
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    shutil.copy(folder / "recorded.h5", folder / "analysed.h5")
    done = subprocess.run([*MIRRORLAB, "run", "analyse.toml", "--session", "analysed.h5", "--no-progress"],
                          cwd=folder, capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    return folder / "recorded.h5", folder / "analysed.h5"


def assert_opens(path: Path) -> tuple[int, str]:
    """``session check`` and ``info`` answer (check: exit 0, or 1 naming what is unfinished), the
    read API opens it; returns check's exit code and output."""
    check = run_cli("session", "check", str(path))
    assert check.returncode in (0, 1) and check.stderr == "", (check.stdout, check.stderr)
    assert ("complete" if check.returncode == 0 else "INCOMPLETE") in check.stdout.splitlines()[0]
    assert "damaged" not in check.stdout
    info = run_cli("session", "info", str(path))
    assert info.returncode == 0 and info.stderr == "", info.stderr
    with Session.open(path) as s:
        assert s.attrs["mirrorlab_schema"] == 2 and s.session_id
    return check.returncode, check.stdout


@pytest.mark.slow
@pytest.mark.parametrize("phase", PHASES, ids=[p.name for p in PHASES])
def test_a_kill_at_any_phase_leaves_a_file_that_opens_with_what_was_written(
        phase: Phase, recorded: tuple[Path, Path], tmp_path: Path) -> None:
    path = tmp_path / "session.h5"
    (tmp_path / "record.toml").write_text(RECORD)
    (tmp_path / "analyse.toml").write_text(ANALYSE)
    if phase.command == "new":
        args = ["session", "new", path.name, "--operator", "crash", "--description", "killed"]
    elif phase.command == "record":
        args = ["run", "record.toml", "--out", path.name, "--no-progress"]
    else:
        shutil.copy(recorded[0], path)
        args = ["run", "analyse.toml", "--session", path.name, "--no-progress"]
    proc = stop_at(phase.stop_at, args, tmp_path)
    # the process lives: its file is reported as being written by it, and nothing repairs it
    check = run_cli("session", "check", str(path))
    assert check.returncode == 1 and f"pid {proc.pid}" in check.stdout + check.stderr, (check.stdout, check.stderr)
    assert "check the path and the disk" not in check.stderr and "did not finish" not in check.stderr
    refusal = f"(right now|being written) by pid {proc.pid}|another process \\(pid {proc.pid}\\)"
    with pytest.raises(SessionError, match=refusal):
        Session.open(path, writable=True)
    kill(proc)

    code, report = assert_opens(path)
    with Session.open(path) as s:
        attrs, members = s.attrs, s.members()
        if phase.command == "new":
            assert (attrs["operator"], attrs["description"], attrs["status"]) == ("crash", "killed", "open")
            assert code == 1 and "run `mirrorlab session close FILE --aborted`" in report
        elif phase.command == "record":
            assert attrs["description"] == "crash matrix" and "cam" in s.members("instruments")
            assert code == 1 and "status is 'open'" in report  # the recording did not finish
            if phase.name != "setup" and "frames" in s.members("instruments/cam"):
                times, frames = s.stream("cam", "frames")
                assert len(times) == len(frames) and np.all(np.diff(times) > 0)
            if phase.recorded:  # everything recorded was flushed at the stop
                with Session.open(recorded[0]) as ref:
                    assert len(s.stream("cam", "frames").times) > 0 and "truth" in members
                    assert s.stream("cam", "frames").data.shape[1:] == ref.stream("cam", "frames").data.shape[1:]
        else:
            assert attrs["status"] == "closed"
            ok = [r for r in s.results() if r.status == "ok"]
            with Session.open(recorded[0]) as before:  # the recording's own result, then the analysis's
                assert len(ok) == len(before.results()) + phase.results, [r.path for r in s.results()]
            with Session.open(recorded[1]) as ref:  # finished results are the reference run's, bit for bit
                for got in ok:
                    outputs, expected = s.result(got).outputs, ref.result(got.path).outputs
                    assert outputs.keys() == expected.keys()
                    for name in outputs:
                        np.testing.assert_array_equal(outputs[name], expected[name])
                assert s.stream("cam", "frames").data.tobytes() == ref.stream("cam", "frames").data.tobytes()

    # `session close` repairs in place: the file keeps its inode and its permissions
    path.chmod(0o664)
    before = path.stat()
    close = run_cli("session", "close", str(path), *(["--aborted"] if phase.command != "analyse" else []))
    assert close.returncode == 0, close.stderr
    after = path.stat()
    assert (after.st_ino, stat.S_IMODE(after.st_mode)) == (before.st_ino, 0o664)
    with h5py.File(path, "r") as f:  # a plain open works again
        assert f.attrs["status"] == ("closed" if phase.command == "analyse" else "aborted")


@pytest.mark.slow
def test_a_kill_before_a_new_file_has_its_header_leaves_nothing_at_its_path(tmp_path: Path) -> None:
    """Killed while HDF5 creates it, the new file is a hidden draft: the path stays free."""
    path = tmp_path / "new.h5"
    proc = stop_at(f"{SESSION_FILE}:_move_new:before", ["session", "new", path.name], tmp_path)
    kill(proc)
    assert not path.exists() and len(list(tmp_path.glob(".new.h5.*.draft"))) == 1
    made = run_cli("session", "new", str(path))
    assert made.returncode == 0, made.stderr
    assert_opens(path)


def test_a_file_flagged_by_a_killed_writer_opens_after_its_flags_are_cleared(tmp_path: Path) -> None:
    """HDF5's own refusal ("file is already open for write") without SWMR: cleared, reported, kept."""
    path = tmp_path / "plain.h5"
    with Session.create(path, operator="plain") as s:
        s.write_group("truth/series", {"data": np.arange(5.0)})
    writer = subprocess.Popen([sys.executable, "-c", "import sys, h5py; f = h5py.File(sys.argv[1], 'a'); "
                               "print('open', flush=True); sys.stdin.read()", str(path)],
                              stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    assert writer.stdout.readline() == "open\n"
    held = run_cli("session", "check", str(path))  # a live writer in normal mode: named, not repaired
    assert held.returncode == 1, held.stdout
    assert f"open for writing in another process (pid {writer.pid})" in held.stderr, held.stderr
    assert "check the path and the disk" not in held.stderr
    kill(writer)
    with pytest.raises(OSError, match="already open for write"):
        h5py.File(path, "r")
    check = run_cli("session", "check", str(path))
    assert check.returncode == 0, (check.stdout, check.stderr)
    assert "its open flag was cleared (everything that process had saved is kept)" in check.stdout
    with Session.open(path) as s:
        assert s.read("truth/series/data").tolist() == [0.0, 1.0, 2.0, 3.0, 4.0] and not s.recovered
