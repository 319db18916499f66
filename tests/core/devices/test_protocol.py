"""The line protocol client against a real simulator over a pty: replies, errors, abort, resynchronisation."""

from __future__ import annotations

import threading
import time
from collections.abc import Iterator

import pytest
from mirrorlab.core import DeviceDisconnected, DeviceReplyError, DeviceTimeout, ProtocolError
from mirrorlab.core.devices import Delay, LineClient, LineSimulator, SimulatorServer, open_port


class Slow(LineSimulator):
    kind = "TEST"

    def __init__(self, seed: int = 0) -> None:
        super().__init__(seed)
        self.running = threading.Event()  # set while SLOW runs: tests abort on it, not after a delay

    def cmd_SLOW(self, args: list[str]) -> Iterator[str | Delay]:
        self.running.set()
        for i in range(int(args[0]) if args else 5):
            yield f"D {i}"
            yield Delay(0.1)
        self.running.clear()
        yield "OK done"


@pytest.fixture(params=["pty", "tcp"])
def client(request: pytest.FixtureRequest) -> Iterator[tuple[LineClient, SimulatorServer]]:
    with SimulatorServer(Slow(), request.param) as server:
        c = LineClient(open_port(server.url), "test device", timeout=2.0)
        yield c, server
        c.close()


def test_reply_with_data_lines_and_errors(client: tuple[LineClient, SimulatorServer]) -> None:
    c, _ = client
    reply = c.query("SLOW")
    assert reply.fields == ["done"] and reply.data == [f"D {i}" for i in range(5)]
    with pytest.raises(DeviceReplyError, match="E01 unknown command FOO") as info:
        c.query("FOO")
    assert info.value.code == "E01"
    assert c.query("ERR?").fields == ["E01", "unknown", "command", "FOO"]


def test_a_late_reply_is_never_taken_for_the_next_command(client: tuple[LineClient, SimulatorServer]) -> None:
    c, _ = client
    with pytest.raises(DeviceTimeout, match="did not answer 'SLOW' within 0.1 s"):
        c.query("SLOW", timeout=0.1)
    # SLOW's "OK done" arrives later; the next command resynchronises and gets its own reply
    assert c.query("*IDN?").fields[0] == "TEST"
    time.sleep(0.6)
    assert c.query("PING").fields == ["PONG"]


def test_abort_interrupts_a_running_command(client: tuple[LineClient, SimulatorServer]) -> None:
    c, server = client
    aborter = threading.Thread(target=lambda: server.model.running.wait(60) and c.abort())
    aborter.start()
    with pytest.raises(DeviceReplyError, match="E09 aborted"):
        c.query("SLOW 600", timeout=120)  # 60 s unless aborted: the abort comes while it runs
    aborter.join()
    assert c.query("PING").fields == ["PONG"]  # ABORT's own OK was consumed
    c.abort()  # with nothing running: a plain ABORT command
    assert c.query("PING").fields == ["PONG"]


def test_garbage_is_reported_then_the_line_recovers(client: tuple[LineClient, SimulatorServer]) -> None:
    c, server = client
    server.endpoint.faults.garble = 0.2
    errors = set()
    for _ in range(20):
        try:
            c.query("*IDN?", timeout=0.3)
        except (ProtocolError, DeviceTimeout) as exc:
            errors.add(type(exc))
        if ProtocolError in errors:
            break
    server.endpoint.faults.garble = 0.0
    assert ProtocolError in errors and c.garbage_lines > 0
    assert c.query("*IDN?").fields[0] == "TEST"


@pytest.mark.parametrize("transport", ["pty", "tcp"])
def test_the_simulator_survives_disconnects_racing_its_reads(transport: str) -> None:
    """Unplugging from another thread while the server waits for bytes must never kill the server.

    (Over a pty the serving thread once selected on the descriptor that ``disconnect`` had just
    closed, died with EBADF, and every reconnect then timed out.)
    """
    with SimulatorServer(Slow(), transport) as server:
        for _ in range(300):
            server.disconnect()
        assert server.serving, "the simulator's serving thread died"
        c = LineClient(open_port(server.url), "test device", timeout=2.0)
        try:
            assert c.query("PING").fields == ["PONG"]
        finally:
            c.close()


def test_writing_to_a_hung_up_pty_is_a_disconnect() -> None:
    """pyserial's flush() raises termios.error on a hung-up pty; the client reports a disconnect."""
    with SimulatorServer(Slow(), "pty") as server:
        c = LineClient(open_port(server.url), "test device", timeout=0.5)
        try:
            server.disconnect()
            for _ in range(3):
                with pytest.raises((DeviceDisconnected, DeviceTimeout)):
                    c.query("PING")
        finally:
            c.close()
