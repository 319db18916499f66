"""``mirrorlab simulate``: a simulator served for other programs, driven here by the real driver."""

from __future__ import annotations

import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from mirrorlab.instruments.reference import Actuator

from tests.raw_line import RawClient
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


def test_another_interface_is_served_only_when_asked_and_with_a_warning() -> None:
    """``--tcp PORT`` and ``--tcp 127.0.0.1:PORT`` listen on the loopback interface, silently; ``--tcp
    0.0.0.0:PORT`` on every interface, saying that anyone who reaches it commands the simulator."""
    for where, address in (("0", "socket://127.0.0.1:"), ("127.0.0.1:0", "socket://127.0.0.1:")):
        proc, url = serve("actuator", "--tcp", where)
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=30)
        assert url.startswith(address) and "warning" not in err, err
    proc, url = serve("actuator", "--tcp", "0.0.0.0:0")
    try:
        assert url.startswith("socket://0.0.0.0:")
        with RawClient(f"socket://127.0.0.1:{url.rpartition(':')[2]}") as c:   # reached on any interface
            assert c.ask("PING") == ["OK PONG"]
    finally:
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=30)
    assert f"mirrorlab: warning: listening on {url}, reachable from other machines; the line protocol has no " \
           "authentication" in err


@pytest.mark.parametrize(("args", "code", "message"), [
    (["--tcp", "localhost:http"], 2, "--tcp: 'localhost:http' is not [HOST:]PORT"),
    (["--tcp", "70000"], 2, "--tcp: '70000' is not [HOST:]PORT"),
    (["--baud", "0"], 2, "--baud: 0 is not a line speed"),
    (["--tcp", "192.0.2.1:0"], 1, "cannot serve on 192.0.2.1:0"),   # TEST-NET: no address of this machine
])
def test_a_wrong_address_or_baud_rate_is_one_clear_error(args: list[str], code: int, message: str) -> None:
    from tests.support import run_cli

    result = run_cli("simulate", "actuator", *args, "--for", "0.1")
    assert result.returncode == code and f"mirrorlab: error: {message}" in result.stderr, result.stderr
    assert len(result.stderr.strip().splitlines()) == 1


def test_baud_paces_the_simulator_as_the_real_line_would() -> None:
    """At 9600 baud (960 bytes/s) a 1000 Hz angle stream cannot go through: the bytes never come faster than
    the line carries them, and the lines it drops are announced by ``!OVF``."""
    proc, url = serve("angle_source", "--tcp", "0", "--baud", "9600")
    try:
        with RawClient(url) as c:
            assert c.ask("RATE 1000") == ["OK 1000"]
            c.send(b"STREAM ON\n")
            start = time.monotonic()
            received = b""
            while time.monotonic() - start < 2.0:
                received += c.read_some(0.1)
            elapsed = time.monotonic() - start
    finally:
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=30)
    assert "paced to 9600 baud" in err
    assert len(received) <= (elapsed + 0.01) * 960 + 10    # 10 bits a byte; a 10 ms chunk may go ahead
    assert re.search(rb"\n!OVF [1-9][0-9]*\n", received)


def test_pty_refuses_an_existing_path_that_is_not_a_link(tmp_path: Path) -> None:
    """``--pty EXISTING_FILE`` replaced the file by the pty link, then deleted it at exit."""
    from tests.support import run_cli

    for taken in (tmp_path / "notes.txt", tmp_path / "tty.new"):
        taken.write_text("precious\n")
        link = taken.with_suffix("") if taken.suffix == ".new" else taken
        proc = run_cli("simulate", "actuator", "--pty", str(link), "--for", "0.2")
        assert proc.returncode == 2
        assert (f"mirrorlab: error: --pty: {taken} exists and is not a link: it would be replaced, then deleted at "
                "exit; give a new path (an old pty link is fine)") in proc.stderr
        assert taken.read_text() == "precious\n"
    old = tmp_path / "ttyOLD"
    old.symlink_to("/dev/pts/no-such-pty")  # left by a simulator that was killed
    proc = run_cli("simulate", "actuator", "--pty", str(old), "--for", "0.2")
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == str(old) and not old.is_symlink()
