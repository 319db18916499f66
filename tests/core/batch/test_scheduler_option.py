"""``--scheduler``: a bad address is a usage error (exit 2), nothing listening fails at once (exit 1)."""

from __future__ import annotations

import socket
import time
from pathlib import Path

import pytest
from mirrorlab.core.session import Session

from tests.support import REPO, run_cli

ANALYSIS = str(REPO / "sessions" / "rssr_analysis.toml")


@pytest.fixture
def session(tmp_path: Path) -> Path:
    path = tmp_path / "s.h5"
    with Session.create(path):
        pass
    return path


@pytest.mark.parametrize(("address", "reason"), [
    ("tcp://127.0.0.1:99999", "port 99999 is not 1-65535"),
    ("tcp://127.0.0.1:0", "port 0 is not 1-65535"),
    ("head", "is not HOST:PORT"),
    ("tcp://:8786", "is not HOST:PORT"),
    ("http://head:8786", "a scheduler address is tcp://, tls://, ws://, wss:// HOST:PORT"),
])
def test_a_bad_scheduler_address_is_a_usage_error(address: str, reason: str, session: Path, tmp_path: Path) -> None:
    """It exited 1 with ValueError, and port 99999 was waited on for 10 s."""
    for command in (["run", ANALYSIS, "--session", str(session)], ["batch", ANALYSIS, str(session), "--out",
                                                                   str(tmp_path / "b")]):
        proc = run_cli(*command, "--scheduler", address, "--no-progress")
        assert proc.returncode == 2, proc.stderr
        assert f"mirrorlab: error: argument --scheduler: {address!r}" in proc.stderr and reason in proc.stderr


def test_a_scheduler_port_nobody_listens_on_fails_at_once(session: Path) -> None:
    with socket.socket() as probe:  # a free port, closed again: nothing listens there
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    start = time.monotonic()
    proc = run_cli("run", ANALYSIS, "--session", str(session), "--scheduler", f"127.0.0.1:{port}", "--no-progress")
    assert proc.returncode == 1
    assert proc.stderr.startswith(f"mirrorlab: error: no Dask scheduler answers at tcp://127.0.0.1:{port} "
                                  "(Connection refused); start one with `dask scheduler`"), proc.stderr
    # Dask's client retries a refused connection for CONNECT_TIMEOUT (10 s); the probe answers in one round trip
    assert time.monotonic() - start < 5.0
