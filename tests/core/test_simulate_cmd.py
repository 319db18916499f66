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
        assert act.set("target", 0.25) == 0.25 and act.query("TGT?").fields == ["250000"]
        act.close()
    finally:
        proc.send_signal(stop)
        out, err = proc.communicate(timeout=60)
    assert proc.returncode == 0, err
    assert "serving the actuator simulator (ACTU, seed 3, fast clock)" in err and "stopped" in err
