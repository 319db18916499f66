"""Crash safety: SIGKILL during recording, and reading a growing file from another process (SWMR)."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import h5py
import numpy as np
import pytest
from mirrorlab.core import Session, SessionError

from tests.support import run_cli

RATE = 200.0

RECORDER = textwrap.dedent(f"""
    import sys, time
    from mirrorlab.core import Session
    with Session.create(sys.argv[1], operator="crash-test") as s:
        s.add_instrument("thermo", "acme_thermometer", simulate=True, settings={{"rate": {RATE}}})
        s.start_recording()
        print("T0", s.clock.t0_monotonic, flush=True)
        time.sleep(120)
""")


def _start_recorder(path: Path, acme_site: Path) -> tuple[subprocess.Popen[str], float]:
    env = {**os.environ, "PYTHONPATH": str(acme_site)}
    proc = subprocess.Popen([sys.executable, "-c", RECORDER, str(path)], stdout=subprocess.PIPE, text=True, env=env)
    line = proc.stdout.readline()
    assert line.startswith("T0 "), f"recorder did not start: {line!r}"
    return proc, float(line.split()[1])


def test_sigkill_keeps_everything_older_than_one_second(tmp_path: Path, acme_site: Path) -> None:
    path = tmp_path / "crash.h5"
    proc, t0 = _start_recorder(path, acme_site)
    time.sleep(3.0)
    kill_session_time = time.monotonic() - t0
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait(timeout=10)

    with pytest.raises(OSError):
        h5py.File(path, "r")  # the pitfall: the superblock still says "open for write"
    with Session.open(path) as s:
        assert s.crashed and s.status == "open"
        times, values = s.stream("thermo", "temperature")
    older = times[times <= kill_session_time - 1.0]
    assert times.max() >= kill_session_time - 1.0, (times.max(), kill_session_time)
    # every sample up to kill - 1 s is there: no gaps at the device's rate
    expected = (kill_session_time - 1.0 - older.min()) * RATE
    assert len(older) >= expected - 2, (len(older), expected)
    assert np.all(np.diff(times) > 0) and np.all(np.isfinite(values))

    check = run_cli("session", "check", str(path))
    assert check.returncode == 1
    assert "INCOMPLETE" in check.stdout and "the recording was killed" in check.stdout
    with pytest.raises(SessionError, match="session close .* --aborted"):
        Session.open(path, writable=True)

    close = run_cli("session", "close", str(path), "--aborted")
    assert close.returncode == 0, close.stderr
    assert "repaired" in close.stdout and not path.with_name("crash.h5.recording").exists()
    with h5py.File(path, "r") as f:  # a normal open works again
        assert f.attrs["status"] == "aborted"
        assert f["instruments/thermo/temperature/time"].shape[0] == len(times)
    after = run_cli("session", "check", str(path))  # readable again, but it did not finish
    assert after.returncode == 1 and "INCOMPLETE (status 'aborted'" in after.stdout, after.stdout
    assert "flagged" not in after.stdout and "killed" not in after.stdout


def test_another_process_reads_the_growing_file(tmp_path: Path, acme_site: Path) -> None:
    path = tmp_path / "live.h5"
    proc, _ = _start_recorder(path, acme_site)
    try:
        time.sleep(1.0)
        reader = textwrap.dedent("""
            import sys, time, h5py
            with h5py.File(sys.argv[1], "r", libver="latest", swmr=True) as f:
                ds = f["instruments/thermo/temperature/time"]
                counts = []
                for _ in range(4):
                    ds.refresh()
                    counts.append(ds.shape[0])
                    time.sleep(0.7)
                print(*counts)
        """)
        out = subprocess.run([sys.executable, "-c", reader, str(path)], capture_output=True, text=True, timeout=60)
        assert out.returncode == 0, out.stderr
        counts = [int(c) for c in out.stdout.split()]
        assert counts[0] > 0 and all(b > a for a, b in zip(counts, counts[1:], strict=False)), counts
        # a live writer is recognised: no repair underneath it
        check = run_cli("session", "check", str(path))
        assert check.returncode == 1 and f"being recorded right now by pid {proc.pid}" in check.stdout
        close = run_cli("session", "close", str(path), "--aborted")
        assert close.returncode == 1 and f"being written by pid {proc.pid}" in close.stderr
    finally:
        proc.kill()
        proc.wait(timeout=10)


ANALYSIS = textwrap.dedent("""
    import sys, threading
    import numpy as np
    from mirrorlab.core import Algorithm, Port, Session

    class Stuck(Algorithm):
        name = "stuck"
        version = "0"
        description = "says it started, then never ends (the test kills it)"
        inputs = (Port("values", "(N,) anything"),)
        outputs = (Port("mean", "() mean"),)

        def run(self, inputs, params, context):
            print("RUNNING", flush=True)
            threading.Event().wait()

    with Session.open(sys.argv[1], writable=True) as s:
        s.run(Stuck, {"values": "/truth/series/data"})
""")


def test_sigkill_during_an_algorithm_run_leaves_a_repairable_file(tmp_path: Path) -> None:
    """The file is in SWMR mode while an algorithm runs: killed then, it opens and `session close` repairs it."""
    path = tmp_path / "analysed.h5"
    with Session.create(path, operator="crash-test") as s:
        s.write_group("truth/series", {"time": np.arange(5.0), "data": np.arange(5.0) ** 2})
    proc = subprocess.Popen([sys.executable, "-c", ANALYSIS, str(path)], stdout=subprocess.PIPE, text=True)
    try:
        assert proc.stdout.readline().strip() == "RUNNING"
        check = run_cli("session", "check", str(path))
        assert check.returncode == 1 and f"results are being written right now by pid {proc.pid}" in check.stdout
    finally:
        proc.kill()
        proc.wait(timeout=10)
    check = run_cli("session", "check", str(path))
    assert check.returncode == 1 and "writing results into it was killed" in check.stdout, check.stdout
    with Session.open(path) as s:  # through SWMR: everything written before the run is there
        assert s.crashed
        assert s.read("truth/series/data").tolist() == [0.0, 1.0, 4.0, 9.0, 16.0]
    close = run_cli("session", "close", str(path))
    assert close.returncode == 0, close.stderr
    assert "repaired" in close.stdout
    with h5py.File(path, "r") as f:  # a normal open works again
        assert f.attrs["status"] == "closed" and f["truth/series/data"].shape == (5,)


def test_an_open_dataset_of_an_older_format_runs_unshared(tmp_path: Path) -> None:
    """HDF5 refuses SWMR mode while an object of a pre-1.10 format is open: the run goes on unshared,
    and sharing on purpose says what holds it."""
    path = tmp_path / "mixed.h5"
    with Session.create(path, operator="crash-test"):
        pass
    with h5py.File(path, "a") as f:  # another program adds data in h5py's default (oldest) format
        f["t10"], f["v10"] = np.arange(10.0), np.zeros((10, 3))
    with Session.open(path, writable=True) as s:
        held = s._store.file["v10"]  # a test of the store: an h5py object of the old format held open
        with pytest.raises(SessionError, match="cannot be shared with other processes"):
            with s.shared_for_reading():
                pass
        ref = s.run("filter", {"time": "/t10", "values": "/v10"})
        assert ref.status == "ok" and held.shape == (10, 3)
