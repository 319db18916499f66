"""One writer per session file, and the stop signals: real ``mirrorlab`` processes against a recording in progress.

A first ``mirrorlab run`` records a simulated closed loop (``follow_loop.toml``) for up to 10 min; every
command that would write its file, run as a second process, is refused with one line naming the writer,
while readers keep reading it; SIGTERM and SIGHUP then stop the first as its first Ctrl-C does.
"""

from __future__ import annotations

import fcntl
import json
import os
import pty
import signal
import struct
import subprocess
import sys
import termios
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import h5py
import pytest

from tests.support import REPO, run_cli

LOOP = REPO / "sessions" / "follow_loop.toml"
ANALYSIS = REPO / "sessions" / "rssr_analysis.toml"


def _start(*args: str) -> subprocess.Popen[str]:
    return subprocess.Popen([sys.executable, "-m", "mirrorlab.core.cli", *args, "--no-progress"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=REPO)


def _wait_recording(proc: subprocess.Popen[str], out: Path) -> None:
    """Until the recording runs: ``<file>.recording`` exists while the recorder writes (SWMR)."""
    marker = out.with_name(out.name + ".recording")
    deadline = time.monotonic() + 120
    while not marker.exists():
        assert proc.poll() is None and time.monotonic() < deadline, proc.communicate()
        time.sleep(0.05)


@pytest.fixture
def recording(tmp_path: Path) -> Iterator[tuple[subprocess.Popen[str], Path]]:
    """A ``mirrorlab run`` recording into ``live.h5`` (its acquire step lasts 600 s unless stopped)."""
    out = tmp_path / "live.h5"
    proc = _start("run", str(LOOP), "--out", str(out), "--set", "steps.1.seconds=600")
    try:
        _wait_recording(proc, out)
        yield proc, out
    finally:
        if proc.poll() is None:
            proc.kill()
        proc.communicate(timeout=60)


def _stop(proc: subprocess.Popen[str], sig: signal.Signals) -> tuple[str, str]:
    proc.send_signal(sig)
    return proc.communicate(timeout=120)


def _assert_closed_cleanly(out: Path, stderr: str, code: int | None, name: str) -> None:
    """What the first Ctrl-C gives: exit 1, the step stopped on request, the file closed and complete."""
    assert code == 1, stderr
    assert f"mirrorlab: {name}: stopping after the current step's work ends" in stderr, stderr
    assert "stopped on request during step 1 (acquire); later steps were not run" in stderr, stderr
    assert "Traceback" not in stderr, stderr
    with h5py.File(out, "r") as f:
        assert f.attrs["status"] == "closed"
        assert f["instruments/sensor/angle/data"].shape[0] == f["instruments/sensor/angle/time"].shape[0] > 0
        messages = [m.decode() for m in f["log"]["message"]]
    assert any("session closed: stopped on request during step 1 (acquire)" in m for m in messages), messages
    check = run_cli("session", "check", str(out))
    assert check.returncode == 0 and "complete (status 'closed'" in check.stdout, check.stdout
    assert not out.with_name(out.name + ".lock").exists()


def test_a_live_file_refuses_every_other_writer_and_serves_readers(
        recording: tuple[subprocess.Popen[str], Path]) -> None:
    proc, out = recording
    lock = json.loads(out.with_name(out.name + ".lock").read_text())
    assert lock["pid"] == proc.pid and lock["command"] == "mirrorlab run"
    since = time.strftime("%H:%M:%S", time.localtime(lock["started"]))
    refusal = (f"mirrorlab: error: {out} is being written by pid {proc.pid} (mirrorlab run, since {since}); "
               "wait for it to finish or stop it")
    session_id = json.loads(run_cli("session", "info", str(out), "--json").stdout)["attributes"]["session_id"]
    writers = {
        "run --overwrite": ["run", str(LOOP), "--out", str(out), "--overwrite", "--no-progress"],
        "demo --overwrite": ["demo", "--out", str(out), "--overwrite", "--no-progress"],
        "record --overwrite": ["record", "angle_source", "--simulate", "--out", str(out), "--overwrite",
                               "--seconds", "1", "--no-progress"],
        "tui --overwrite": ["tui", str(LOOP), "--out", str(out), "--overwrite"],
        "run --session": ["run", str(ANALYSIS), "--session", str(out), "--no-progress"],
        "analyze": ["analyze", "derivatives", str(out), "--input", "time=/instruments/sensor/angle/time",
                    "--input", "values=/instruments/sensor/angle/data", "--no-progress"],
        "session close": ["session", "close", str(out)],
        "session close --aborted": ["session", "close", str(out), "--aborted"],
    }
    for what, args in writers.items():
        second = run_cli(*args, fresh=True)  # a new process: the lock belongs to processes
        assert (second.returncode, second.stderr.strip()) == (1, refusal), what
    assert run_cli("session", "info", str(out)).returncode == 0
    assert run_cli("session", "tree", str(out)).returncode == 0
    exported = run_cli("session", "export", str(out), "sensor/angle")
    assert exported.returncode == 0 and len(exported.stdout.splitlines()) > 2, exported.stderr
    check = run_cli("session", "check", str(out))
    assert f"being recorded right now by pid {proc.pid} (mirrorlab run, since {since})" in check.stdout

    stdout, stderr = _stop(proc, signal.SIGINT)
    _assert_closed_cleanly(out, stderr, proc.returncode, "Ctrl-C")
    with h5py.File(out, "r") as f:  # the first recording, whole: no second session mixed in
        assert f.attrs["session_id"] == session_id and "controllers/loop" in f and len(f["results"]) == 0


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGHUP])
def test_sigterm_and_sighup_stop_run_as_the_first_ctrl_c(recording: tuple[subprocess.Popen[str], Path],
                                                         sig: signal.Signals) -> None:
    proc, out = recording
    stdout, stderr = _stop(proc, sig)
    _assert_closed_cleanly(out, stderr, proc.returncode, sig.name)


def test_sigterm_stops_record_as_the_first_ctrl_c(tmp_path: Path) -> None:
    out = tmp_path / "record.h5"
    proc = _start("record", "angle_source", "--simulate", "--out", str(out), "--seconds", "600")
    try:
        _wait_recording(proc, out)
        stdout, stderr = _stop(proc, signal.SIGTERM)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 1, stderr
    assert "mirrorlab: SIGTERM: stopping" in stderr and "stopped on request after" in stderr, stderr
    assert "dev/angle:" in stdout, stdout
    with h5py.File(out, "r") as f:
        assert f.attrs["status"] == "closed" and f["instruments/dev/angle/data"].shape[0] > 0
    assert run_cli("session", "check", str(out)).returncode == 0


def test_a_killed_writer_leaves_no_lock_behind(tmp_path: Path) -> None:
    """kill -9 cannot release anything itself: the operating system drops the lock with the process."""
    out = tmp_path / "killed.h5"
    proc = _start("record", "angle_source", "--simulate", "--out", str(out), "--seconds", "600")
    _wait_recording(proc, out)
    proc.kill()
    proc.communicate(timeout=60)
    assert out.with_name(out.name + ".lock").exists()  # the file stays; nobody holds its lock
    check = run_cli("session", "check", str(out))
    assert "being recorded right now" not in check.stdout and "killed" in check.stdout, check.stdout
    assert out.with_name(out.name + ".spare").exists()
    close = run_cli("session", "close", str(out), "--aborted", fresh=True)
    assert close.returncode == 0, close.stderr
    assert sorted(p.name for p in out.parent.iterdir()) == [out.name]  # no marker, lock or spare left
    again = run_cli("record", "angle_source", "--simulate", "--out", str(out), "--overwrite", "--seconds", "0.5",
                    "--no-progress", fresh=True)
    assert again.returncode == 0, again.stderr
    assert not out.with_name(out.name + ".lock").exists()


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGHUP])
def test_sigterm_and_sighup_quit_the_console_as_ctrl_q(tmp_path: Path, sig: signal.Signals) -> None:
    """The console on a real pty, recording (key r): the signal closes the session file cleanly."""
    out = tmp_path / "console.h5"
    master, slave = pty.openpty()
    fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", 30, 100, 0, 0))
    proc = subprocess.Popen([sys.executable, "-m", "mirrorlab.core.cli", "tui", str(LOOP), "--out", str(out)],
                            stdin=slave, stdout=slave, stderr=slave, cwd=REPO, start_new_session=True,
                            env={**os.environ, "TERM": "xterm-256color", "COLUMNS": "100", "LINES": "30"})
    os.close(slave)
    screen = bytearray()
    reader = threading.Thread(target=_drain, args=(master, screen), daemon=True)
    reader.start()
    try:
        deadline = time.monotonic() + 120
        while not (out.with_name(out.name + ".lock").exists() and b"Record" in screen):  # the console is up
            assert proc.poll() is None and time.monotonic() < deadline, bytes(screen)[-2000:]
            time.sleep(0.1)
        os.write(master, b"r")
        _wait_recording(proc, out)
        time.sleep(0.5)
        proc.send_signal(sig)
        assert proc.wait(timeout=120) == 0, bytes(screen)[-2000:]
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
        os.close(master)
    with h5py.File(out, "r") as f:
        assert f.attrs["status"] == "closed" and f["instruments/sensor/angle/data"].shape[0] > 0
    assert run_cli("session", "check", str(out)).returncode == 0
    assert not out.with_name(out.name + ".lock").exists()


def _drain(fd: int, into: bytearray) -> None:
    """Read what the console draws (a full pty would block it)."""
    while True:
        try:
            chunk = os.read(fd, 65536)
        except OSError:  # closed
            return
        if not chunk:
            return
        into += chunk
