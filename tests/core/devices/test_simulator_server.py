"""How the simulator server times stream lines and its device clock (a real pty, a real driver client)."""

from __future__ import annotations

import queue
import threading
import time
from collections.abc import Iterator

from mirrorlab.core.devices import Delay, LineClient, LineSimulator, SimulatorServer, open_port


class Scheduled(LineSimulator):
    """Streams one ``!S <ms>`` line at a device time set by ``AT <ms>``; never on a tick."""

    kind = "TEST"
    stream_tick = 30.0  # far longer than any test waits: only next_due_ms() can send the line

    def reset(self) -> None:
        super().reset()
        self.due: float | None = None

    def next_due_ms(self) -> float | None:
        return self.due

    def stream_lines(self) -> list[str]:
        if self.due is None or self.due > self.clock_ms:
            return []
        line, self.due = f"!S {int(self.due)}", None
        return [line]

    def cmd_AT(self, args: list[str]) -> Iterator[str]:
        self.due = self.clock_ms + float(args[0])
        yield "OK"


class Cycling(Scheduled):
    """Like :class:`Scheduled`, but the line's cycle is followed by a long computation in ``advance``
    that only ends once the test has received the line."""

    def reset(self) -> None:
        super().reset()
        self.received = threading.Event()

    def advance(self, seconds: float) -> None:
        super().advance(seconds)
        if self.due is not None and self.due <= self.clock_ms:
            self.send_due_lines()           # the finished sample leaves before the next cycle's work
            self.received.wait(30.0)        # "the next cycle": blocks until the host has the line


class Sleeper(LineSimulator):
    kind = "TEST"

    def cmd_NAP(self, args: list[str]) -> Iterator[str | Delay]:
        yield Delay(float(args[0]))
        yield "OK"

    def cmd_WORK(self, args: list[str]) -> Iterator[str]:
        time.sleep(float(args[0]))  # firmware busy without a modelled Delay: the time passes all the same
        yield "OK"


def lines_of(server: SimulatorServer) -> tuple[LineClient, queue.Queue[str]]:
    got: queue.Queue[str] = queue.Queue()
    return LineClient(open_port(server.url), "test device", 2.0, got.put), got


def close(client: LineClient, server: SimulatorServer) -> None:
    """Shorten the server's idle wait (a command wakes it to take the new tick), so it closes at once."""
    server.model.stream_tick = 0.01
    client.query("PING")
    client.close()


def test_a_stream_line_leaves_when_due_not_at_the_next_tick() -> None:
    with SimulatorServer(Scheduled()) as server:
        client, got = lines_of(server)
        client.query("STREAM ON")
        client.query("AT 50")
        assert got.get(timeout=10.0).startswith("S ")  # the 30 s tick would be far later
        close(client, server)


def test_a_due_line_is_sent_before_the_next_cycle_is_computed() -> None:
    model = Cycling()
    with SimulatorServer(model) as server:
        client, got = lines_of(server)
        client.query("STREAM ON")
        client.query("AT 20")
        line = got.get(timeout=10.0)  # would wait for the 30 s "cycle" if the line came after it
        model.received.set()
        assert line.startswith("S ")
        close(client, server)


def test_the_device_clock_keeps_step_with_the_wall_clock_through_commands() -> None:
    with SimulatorServer(Sleeper()) as server:
        client, _ = lines_of(server)
        first = client.query("TIME?").field(0, "ms", int)
        start = time.monotonic()
        for _ in range(10):  # the time commands take is device time too
            client.query("WORK 0.05")
        client.query("NAP 0.2")  # a REAL-clock Delay is slept and counted once
        device_ms = client.query("TIME?").field(0, "ms", int) - first
        wall_ms = (time.monotonic() - start) * 1000.0
        assert abs(device_ms - wall_ms) < 100.0, (device_ms, wall_ms)  # 500 ms of WORK lost would fail
        client.query("SIM:CLOCK FAST")
        before = client.query("TIME?").field(0, "ms", int)
        client.query("NAP 100")  # FAST: not slept, the device clock jumps by the Delay
        assert client.query("TIME?").field(0, "ms", int) - before >= 100_000
        client.close()
