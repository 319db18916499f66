"""What any client meets on a served simulator (``docs/instruments/connecting.md``), spoken in raw bytes over
a real TCP socket or pty: stray bytes, half lines, a second client, long lines, a slow reader, the clock."""

from __future__ import annotations

import re
import socket
import time
from collections.abc import Iterator

import pytest
from mirrorlab.core.devices import CommandError, Delay, Lines, LineSimulator, SimulatorServer
from mirrorlab.core.devices.simulator import MAX_LINE, REPLY_BACKLOG
from mirrorlab.instruments.reference.models import ActuatorModel, AngleSourceModel

from tests.raw_line import RawClient

TRANSPORTS = ["tcp", "pty"]


class Buggy(LineSimulator):
    """A model with the bugs a simulator must survive: a command that raises, a usage outside ASCII, and a
    clock that fails once when told to."""

    kind = "TEST"

    def reset(self) -> None:
        super().reset()
        self.fail_advance = False

    def cmd_BUG(self, args: list[str]) -> Lines:
        yield "DATA before the bug"
        raise ZeroDivisionError("division by zero")

    def cmd_WAIT(self, args: list[str]) -> Lines:
        raise CommandError("E02", "usage: WAIT <µs>")

    def cmd_BIG(self, args: list[str]) -> Lines:
        for i in range(100):
            yield f"D {i:03d} {'x' * 94}"
        yield "OK"

    def cmd_TRIP(self, args: list[str]) -> Lines:
        self.fail_advance = True
        yield "OK"

    def advance(self, seconds: float) -> None:
        super().advance(seconds)
        if self.fail_advance:
            self.fail_advance = False
            raise RuntimeError("the clock tripped")


class Counting(LineSimulator):
    """Streams ``!N <k> <padding>`` lines, numbered, at ``rate`` per second: a stream whose losses show."""

    kind = "TEST"

    def __init__(self, rate: float, width: int = 60) -> None:
        self.rate, self.width = rate, width
        super().__init__()

    def reset(self) -> None:
        super().reset()
        self.sent = 0

    def next_due_ms(self) -> float | None:
        return 1000.0 * self.sent / self.rate if self.streaming else None

    def stream_lines(self) -> list[str]:
        lines = []
        while 1000.0 * self.sent / self.rate <= self.clock_ms:
            lines.append(f"!N {self.sent} {'x' * self.width}")
            self.sent += 1
        return lines


@pytest.fixture(params=TRANSPORTS)
def actuator(request: pytest.FixtureRequest) -> Iterator[SimulatorServer]:
    with SimulatorServer(ActuatorModel(), request.param) as server:
        yield server


def test_stray_bytes_get_one_escaped_error_line_each_and_the_simulator_goes_on() -> None:
    with SimulatorServer(Buggy(), "tcp") as server, RawClient(server.url) as c:
        assert c.ask(b"\xff") == ["ERR E01 unknown command \\xff"]
        assert c.ask(b"PING\xff") == ["ERR E01 unknown command PING\\xff"]
        assert c.ask("PÏNG".encode()) == ["ERR E01 unknown command P\\xc3\\x8fNG"]      # UTF-8: two bytes
        assert c.ask(b"PI\rNG\t") == ["ERR E01 unknown command PI\\x0dNG\\x09"]         # a tab is no separator
        assert c.ask(b"PING \x00") == ["ERR E02 usage: PING"]
        assert c.ask("WAIT") == ["ERR E02 usage: WAIT <\\xb5s>"]                         # a usage text with µ
        assert c.ask(b"ping\r") == ["OK PONG"]


def test_a_bug_of_the_model_is_an_internal_error_and_serving_goes_on() -> None:
    with SimulatorServer(Buggy(), "tcp") as server, RawClient(server.url) as c:
        assert c.ask("BUG") == ["DATA before the bug", "ERR E99 internal ZeroDivisionError: division by zero"]
        assert c.ask("ERR?") == ["OK E99 internal ZeroDivisionError: division by zero"]
        assert c.ask("TRIP") == ["OK"]                # the clock then fails once, outside any command
        assert c.line() == "!ERR E99 internal RuntimeError: the clock tripped"
        assert c.ask("PING") == ["OK PONG"] and server.serving
        before = int(c.ask("TIME?")[0].split()[1])
        time.sleep(0.05)
        assert int(c.ask("TIME?")[0].split()[1]) > before   # the clock goes on after it


def gone(server: SimulatorServer) -> None:
    """Wait until the simulator has seen its client hang up. Over TCP a new client is told apart at once; a
    pty is one line shared by whoever opens it, and the simulator sees its hang-up when it next looks
    (at once while idle), so a program that reopens it faster may meet the previous one's half line."""
    deadline = time.monotonic() + 10.0
    while server.endpoint.connected and time.monotonic() < deadline:
        time.sleep(0.001)


@pytest.mark.parametrize("transport", TRANSPORTS)
def test_a_half_line_does_not_survive_its_connection(transport: str) -> None:
    with SimulatorServer(ActuatorModel(), transport) as server:
        for half, rest in ((b"PIN", b"PING"), (b"TGT 5", b"0")):
            with RawClient(server.url) as first:
                first.ask("PING")       # connected for sure: the half line is this client's
                first.send(half)
            if transport == "pty":
                gone(server)
            with RawClient(server.url) as second:
                if rest == b"PING":
                    assert second.ask(rest) == ["OK PONG"]                     # not "unknown command PINPING"
                else:
                    assert second.ask(rest) == ["ERR E01 unknown command 0"]  # not TGT 50
                    assert second.ask("TGT?") == ["OK 0"]
            if transport == "pty":  # before the next client: else its first line may go with this one's
                gone(server)


def test_a_second_client_is_told_busy_and_closed_the_first_goes_on() -> None:
    with SimulatorServer(ActuatorModel(), "tcp") as server, RawClient(server.url) as first:
        assert first.ask("PING") == ["OK PONG"]
        with RawClient(server.url) as second:
            second.send(b"PING\n")
            assert second.line() == "ERR E10 busy: another client is connected; try again when it has disconnected"
            with pytest.raises(EOFError):
                second.line()
        assert first.ask("*IDN?")[0].startswith("OK ACTU")
        first.send(b"PI")
        first.close()
        with RawClient(server.url) as third:     # at once: the first one's hang-up is seen when the next one comes
            assert third.ask("PING") == ["OK PONG"]


@pytest.mark.parametrize("transport", TRANSPORTS)
def test_the_device_clock_and_the_state_go_on_without_a_client(transport: str) -> None:
    """TIME? counts the time between two clients; settings and the stream persist (as on a real device, which
    opening a port does not reset); the stream lines of the time nobody listened are not delivered late."""
    with SimulatorServer(ActuatorModel(), transport) as server:
        with RawClient(server.url) as c:
            assert c.ask("RATE 100") == ["OK 100"] and c.ask("TGT 1000") == ["OK 1000"]
            assert c.ask("STREAM ON") == ["OK"]
            before = int(c.ask("TIME?")[0].split()[1])
            left = time.monotonic()
        time.sleep(0.5)
        gone(server)
        with RawClient(server.url) as c:
            back = time.monotonic()
            first_stream_line = c.line()
            now = int(c.ask("TIME?")[0].split()[1])
            assert c.ask("TGT?") == ["OK 1000"]
            assert c.ask("STREAM OFF") == ["OK"]
    # TIME? is whole ms: the device time passed is at least the wall time between the two queries, less 1 ms
    assert now - before >= (back - left) * 1000.0 - 1.0
    stamp_ms = int(first_stream_line.split()[1]) / 1000.0
    assert first_stream_line.startswith("!P ") and stamp_ms >= before + (back - left) * 1000.0 - 10.0 - 1.0


def test_empty_lines_get_no_reply_and_a_long_line_one_error(actuator: SimulatorServer) -> None:
    with RawClient(actuator.url) as c:
        c.send(b"\n   \n\r\n")
        assert c.ask("PING") == ["OK PONG"]          # the first reply is PING's: nothing for the empty lines
        longest = "X" * MAX_LINE
        assert c.ask(longest) == [f"ERR E01 unknown command {longest}"]
        too_long = ["ERR E02 line too long: over 200 characters; the whole line was discarded"]
        assert c.ask("X" * (MAX_LINE + 1)) == too_long
        c.send(b"TGT 7" + b"0" * 1_000_000)        # a megabyte without LF: dropped as it comes, answered once
        assert c.ask(b"") == too_long and c.ask("TGT?") == ["OK 0"]
        assert c.ask("PING") == ["OK PONG"]


def test_the_abort_byte_answers_ok_and_cancels_the_line_it_interrupts(actuator: SimulatorServer) -> None:
    with RawClient(actuator.url) as c:
        c.send(b"TGT 12\x1834\n")
        assert c.reply() == ["OK"]                              # ABORT with nothing running
        assert c.reply() == ["ERR E01 unknown command 34"]      # "TGT 12" went with it
        assert c.ask("TGT?") == ["OK 0"]


def test_a_reader_too_slow_for_the_stream_is_told_how_many_lines_it_lost() -> None:
    """Paced to 9600 baud (960 bytes/s) a stream of 70-byte lines at 100 Hz cannot keep up: every gap in
    the numbered lines is announced by ``!OVF <n>`` with its exact size, and the line is never faster
    than its baud rate."""
    with SimulatorServer(Counting(rate=100.0), "tcp", baud=9600) as server, RawClient(server.url) as c:
        c.send(b"STREAM ON\n")
        start = time.monotonic()
        received = b""
        while time.monotonic() - start < 3.0:
            received += c.read_some(0.1)
        elapsed = time.monotonic() - start
        c.send(b"STREAM OFF\n")
    # 10 bits a byte, plus one 10 ms chunk the line may hold ahead
    assert len(received) <= (elapsed + 0.01) * 9600 / 10 + 10
    lines = received.decode("ascii").split("\n")[:-1]
    assert lines[0] == "OK"
    expected, announced, notices = 0, 0, 0
    for line in lines[1:]:
        if line.startswith("!OVF "):
            announced, notices = int(line.split()[1]), notices + 1
            continue
        k = int(line.split()[1])
        assert k == expected + announced, f"line {k} after {expected - 1}: {announced} announced lost"
        expected, announced = k + 1, 0
    assert notices > 0 and expected > 10


def test_a_paced_line_that_keeps_up_loses_nothing() -> None:
    with SimulatorServer(Counting(rate=10.0, width=20), "tcp", baud=115200) as server, RawClient(server.url) as c:
        assert c.ask("STREAM ON") == ["OK"]
        lines = [c.line() for _ in range(10)]
        c.ask("STREAM OFF")
    assert [int(line.split()[1]) for line in lines] == list(range(10))


def test_a_client_that_reads_nothing_is_not_answered_without_end() -> None:
    """The device reads no further command while a megabyte of replies waits for the client: memory stays
    bounded (10 kB replies, and a few thousand commands already read and waiting)."""
    with SimulatorServer(Buggy(), "tcp") as server:
        sock = socket.socket()
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
        sock.connect(("127.0.0.1", int(server.url.rpartition(":")[2])))
        sock.setblocking(False)
        most, deadline = 0, time.monotonic() + 60.0
        while time.monotonic() < deadline and most <= REPLY_BACKLOG:
            try:
                sock.send(b"BIG\n" * 1000)
            except BlockingIOError:
                time.sleep(0.01)
            most = max(most, server.endpoint.backlog)
        stop = time.monotonic() + 1.0
        while time.monotonic() < stop:
            most = max(most, server.endpoint.backlog)
            time.sleep(0.01)
        sock.close()
    assert REPLY_BACKLOG < most <= REPLY_BACKLOG + 10_100   # reached, and passed by one reply at most


@pytest.mark.parametrize("start", [0, 128])
def test_every_reply_line_the_simulator_sends_is_printable_ascii(start: int) -> None:
    """Each byte (but LF and the abort byte) in a command word comes back as itself or ``\\xNN``."""
    sent = bytes(b for b in range(start, start + 128) if b not in b"\n\x18 ")
    with SimulatorServer(Buggy(), "tcp") as server, RawClient(server.url) as c:
        (line,) = c.ask(b"X" + sent)
    assert re.fullmatch(r"[ -~]*", line)
    assert line == "ERR E01 unknown command X" + "".join(chr(b) if 0x20 < b < 0x7f else f"\\x{b:02x}" for b in sent)


class Napping(AngleSourceModel):
    """An angle source with a command that takes modelled time: in FAST mode the clock jumps over it."""

    def cmd_NAP(self, args: list[str]) -> Lines:
        yield Delay(float(args[0]))
        yield "OK"


def test_stream_samples_a_fast_clock_jumps_over_are_announced_lost() -> None:
    """At most 100 samples of a jump are sent; ``!OVF n`` counts the rest, exactly: the stamps on either side
    of it are n + 1 periods apart."""
    model = Napping()
    model.fast = True
    with SimulatorServer(model, "tcp") as server, RawClient(server.url) as c:
        assert c.ask("RATE 100") == ["OK 100"]
        c.send(b"STREAM ON\nNAP 10\n")
        lines = []
        while not (lines and lines[-1].startswith("!OVF ")):
            lines.append(c.line())
        after = [c.line() for _ in range(100)]
        assert c.ask("STREAM OFF") == ["OK"]
    before = [line for line in lines if line.startswith("!A ")][-1]
    lost = int(lines[-1].split()[1])
    assert lost >= 890
    assert int(after[0].split()[1]) - int(before.split()[1]) == (lost + 1) * 10_000    # µs
    assert all(line.startswith("!A ") for line in after)
