"""The runtime through the CLI (subprocesses): controllers in recipes, Ctrl-C in ``mirrorlab run``."""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import time
from pathlib import Path

import h5py
import pytest

from tests.support import REPO, run_cli

LOOP = REPO / "sessions" / "follow_loop.toml"


def test_a_controller_recipe_records_the_loop(tmp_path: Path) -> None:
    out = tmp_path / "loop.h5"
    proc = run_cli("run", str(LOOP), "--out", str(out), "--no-progress", "--set", "steps.1.seconds=1")
    assert proc.returncode == 0, proc.stderr
    assert "loop/latency:" in proc.stdout and "loop/output.target:" in proc.stdout
    with h5py.File(out, "r") as f:
        g = f["controllers/loop"]
        assert json.loads(g.attrs["inputs"]) == {"input": "sensor/angle"}
        assert g["output.target/data"].shape[0] == g["latency/data"].shape[0] > 0
        assert f["instruments/sensor/angle/data"].shape[0] > 50
    info = run_cli("session", "info", str(out))
    assert "controller loop: follow 1.0.0 (input <- sensor/angle, output -> actuator)" in info.stdout


def test_controller_bindings_fail_the_check_naming_the_key(tmp_path: Path) -> None:
    cases = {
        "controllers.loop.settings.parameter=speed":
            "controllers.loop.instruments.output: actuator 'actuator' has no live-settable speed",
        'controllers.loop.inputs.input="camera/frames"':
            "controllers.loop.inputs.input: 'camera/frames' is not '<instrument>/<stream>' of an instrument",
        'controllers.loop.instruments.output="nobody"':
            "controllers.loop.instruments.output: no instrument 'nobody' in the recipe",
        'controllers.loop.plugin="nothing"': "controllers.loop.plugin: no controller named 'nothing'",
    }
    for override, message in cases.items():
        proc = run_cli("run", str(LOOP), "--check", "--set", override)
        assert proc.returncode == 2 and message in proc.stderr, (override, proc.stderr)


@pytest.mark.parametrize("inherited", ["default", "ignored"])
def test_first_ctrl_c_stops_cleanly_and_logs_why(tmp_path: Path, inherited: str) -> None:
    """Also when started with SIGINT ignored, as a shell starts a background job (``cmd &`` in a script):
    a SIGINT sent to it is meant."""
    out = tmp_path / "loop.h5"
    ignore = (lambda: signal.signal(signal.SIGINT, signal.SIG_IGN)) if inherited == "ignored" else None
    proc = subprocess.Popen([sys.executable, "-m", "mirrorlab.core.cli", "run", str(LOOP), "--out", str(out),
                             "--no-progress", "--set", "steps.1.seconds=600"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=REPO, preexec_fn=ignore)
    try:
        lock = out.with_name(out.name + ".recording")  # the live writer's marker: the acquire step runs
        deadline = time.monotonic() + 120
        while not lock.exists():
            assert proc.poll() is None and time.monotonic() < deadline, proc.communicate()
            time.sleep(0.05)
        proc.send_signal(signal.SIGINT)
        stdout, stderr = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:  # a failed wait: no recorder left running for 600 s
            proc.kill()
            proc.communicate()
    assert proc.returncode == 1, stderr
    assert "stopped on request during step 1 (acquire); later steps were not run" in stderr
    with h5py.File(out, "r") as f:
        assert f.attrs["status"] == "closed" and f["instruments/sensor/angle/data"].shape[0] > 0
    with h5py.File(out, "r") as f:
        messages = [m.decode() for m in f["log"]["message"]]
    assert any("session closed: stopped on request during step 1 (acquire)" in m for m in messages)
