"""``mirrorlab simulate``: a simulator served for other programs, driven here by the real driver."""

from __future__ import annotations

import signal
import subprocess
import sys
from pathlib import Path

import pytest
from mirrorlab.instruments.reference import Actuator

from tests.support import REPO


def serve(*args: str) -> tuple[subprocess.Popen[str], str]:
    proc = subprocess.Popen([sys.executable, "-m", "mirrorlab.core.cli", "simulate", *args],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=REPO)
    assert proc.stdout is not None
    address = proc.stdout.readline().strip()  # the first line names the address
    assert address, proc.communicate(timeout=30)
    return proc, address


@pytest.mark.parametrize(("transport", "stop"), [("tcp", signal.SIGINT), ("pty", signal.SIGTERM)])
def test_a_served_simulator_answers_the_driver_until_interrupted(tmp_path: Path, transport: str,
                                                                 stop: signal.Signals) -> None:
    """Served until Ctrl-C (SIGINT) or SIGTERM, either of which ends it cleanly with exit code 0."""
    where = ["--tcp", "0"] if transport == "tcp" else ["--pty", str(tmp_path / "ttyACT")]
    proc, address = serve("actuator", *where, "--seed", "3", "--clock", "fast")
    try:
        assert address.startswith("socket://127.0.0.1:") if transport == "tcp" else address == str(tmp_path / "ttyACT")
        act = Actuator("act", port=address)
        act.connect()
        assert act.identify().kind == "ACTU"
        act.configure()
        assert act.set("target", 0.25).wait() == 0.25 and act.query("TGT?").fields == ["250000"]
        act.close()
    finally:
        proc.send_signal(stop)
        out, err = proc.communicate(timeout=60)
    assert proc.returncode == 0, err
    assert "serving the actuator simulator (ACTU, seed 3, fast clock)" in err and "stopped" in err


def test_a_simulator_served_for_a_time_says_when_it_stops() -> None:
    """With --for the start message says when it stops (it said "stop with Ctrl-C"); without, Ctrl-C."""
    from tests.support import run_cli

    timed = run_cli("simulate", "actuator", "--tcp", "0", "--for", "0.2")
    assert timed.returncode == 0, timed.stderr
    assert timed.stderr.strip().endswith("stops after 0.2 s (or Ctrl-C)"), timed.stderr
    proc, _ = serve("actuator", "--tcp", "0")
    assert proc.stderr is not None
    started = proc.stderr.readline()
    proc.send_signal(signal.SIGINT)
    proc.communicate(timeout=30)
    assert started.strip().endswith("real clock); stop with Ctrl-C"), started
