"""Simulators: device models that speak an instrument's line protocol over a real byte stream.

A :class:`LineSimulator` is the device model. It implements the common commands of
``instruments.md`` §0.2 (``*IDN?``, ``PING``, ``*RST``, ``STAT?``, ``TIME?``, ``STREAM``, ``ERR?``
and the ``SIM:`` commands) and dispatches the rest to ``cmd_<WORD>`` methods of the subclass. A
handler is a generator: it yields reply lines (data lines, then the terminal line) and may yield
:class:`Delay` to model time. The :class:`SimulatorServer` runs the model in a thread on a
pseudo-terminal or TCP endpoint, sleeps through delays in real-time mode (``SIM:CLOCK REAL``) or
only advances the simulated clock (``SIM:CLOCK FAST``), and between yielded lines watches for
``ABORT`` so a running command can be aborted as the protocol requires.

The server serves one client at a time (a second one gets ``ERR E10 busy``), starts every client
with an empty input buffer, keeps the device clock running while no client is connected, answers
every line it cannot take (too long, bytes outside ASCII, a bug of the model: ``ERR E99 internal``)
with one error line and goes on, and tells a client that reads too slowly how many stream lines it
lost (``!OVF <n>``). ``docs/instruments/connecting.md`` is the contract.
"""

from __future__ import annotations

import enum
import logging
import random
import re
import tempfile
import threading
import time
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TypeVar

from .transport import Endpoint, PtyEndpoint, TcpEndpoint

log = logging.getLogger(__name__)

Lines = Iterator["str | Delay"]
T = TypeVar("T")

#: Longest command line, characters without its LF (and the CR before it): ``instruments.md`` §0.2.
MAX_LINE = 200
#: The byte that aborts like ``ABORT`` (CAN), wherever it comes.
ABORT_BYTE = b"\x18"
#: Input kept while a command runs (more waits in the transport until the device reads again), bytes.
INPUT_LIMIT = 4096
#: Output waiting to be sent beyond which the device reads no further command, bytes.
REPLY_BACKLOG = 1 << 20
#: Output waiting beyond which a stream line is dropped (counted in ``!OVF``) when the line is not paced, bytes.
STREAM_BACKLOG = 1 << 16

_INTEGER = re.compile(r"[+-]?[0-9]+")
_NUMBER = re.compile(r"[+-]?([0-9]+\.?[0-9]*|\.[0-9]+)([eE][+-]?[0-9]+)?")
_WORD = re.compile(r"(\*?)([A-Z][A-Z0-9]*(?::[A-Z][A-Z0-9]*)*)(\??)")
#: Handlers of the IEEE 488.2 common commands, the only words written with a leading ``*``.
_STARRED = frozenset({"cmd_IDN_Q", "cmd_RST"})


def printable(text: str) -> str:
    """``text`` with every character outside printable ASCII written as ``\\xNN`` (``\\uNNNN`` beyond 0xFF).

    Lines go out through it (a reply that echoes a stray byte stays one ASCII line), and command
    lines are read through it (such a byte is part of its word, as the client will see it echoed).

    Examples
    --------
    >>> printable("PING\\xff µrad\\t")
    'PING\\\\xff \\\\xb5rad\\\\x09'
    """
    return "".join(c if " " <= c <= "~" else f"\\x{ord(c):02x}" if ord(c) < 0x100 else f"\\u{ord(c):04x}"
                   for c in text)


def _bound(value: float) -> str:
    """A range bound as written in an ``E03`` reply: whole numbers in full (``3141593``, not ``3.14159e+06``)."""
    return str(int(value)) if float(value).is_integer() else f"{value:g}"


def fixed(value: float, decimals: int) -> str:
    """``value`` with ``decimals`` decimals, never ``-0.000``: a value that rounds to zero is written unsigned.

    Examples
    --------
    >>> fixed(-0.0004, 3), fixed(-0.0006, 3), fixed(2.5, 1)
    ('0.000', '-0.001', '2.5')
    """
    return f"{round(value, decimals) + 0.0:.{decimals}f}"


@dataclass(frozen=True)
class Delay:
    """Simulated time spent by a command, in seconds."""

    seconds: float


class CommandError(Exception):
    """Raised inside a handler to answer ``ERR <code> <text>``."""

    def __init__(self, code: str, text: str) -> None:
        super().__init__(f"{code} {text}")
        self.code = code
        self.text = text


class LineSimulator:
    """Base device model. Subclasses set the identity attributes and add ``cmd_*`` handlers.

    Handler names: the command word upper-cased with ``*``, ``?`` and ``:`` replaced
    (``THR?`` → ``cmd_THR_Q``, ``SIM:TRUTH?`` → ``cmd_SIM_TRUTH_Q``). Handlers receive the argument
    words and yield lines; raising :class:`CommandError` answers ``ERR``.
    """

    kind = "GENERIC"
    #: Longest wait, s, between the server's looks at the model when no command arrives and
    #: :meth:`next_due_ms` names nothing sooner (idle time still passes on the device clock).
    stream_tick = 0.01
    vendor = "mirrorlab"
    model = "SIM"
    firmware = "1.0"
    serial_number = "0001"

    def __init__(self, seed: int = 0) -> None:
        self.seed = seed
        self.fast = False
        self.clock_ms = 0.0
        self.streaming = False
        self.faults: dict[str, list[str]] = {}
        self.flags: set[str] = set()
        self.last_error = ("E00", "none")
        self.rng = random.Random(seed)
        #: Stream lines the model could not send (it skipped samples after a pause); the server reports them in ``!OVF``.
        self.lost_lines = 0
        self._line_sink: Callable[[], None] | None = None
        self.reset()

    # -- state -----------------------------------------------------------------------------------
    def reset(self) -> None:
        """Power-on state of the device model (subclasses extend and call super)."""
        self.streaming = False
        self.flags = set()
        self.last_error = ("E00", "none")

    @property
    def state(self) -> str:
        return "IDLE"

    def advance(self, seconds: float) -> None:
        """Advance the simulated clock (the server calls this; subclasses may extend)."""
        self.clock_ms += seconds * 1000.0

    def stream_lines(self) -> list[str]:
        """Unsolicited ``!`` lines due now while streaming (subclasses override)."""
        return []

    def next_due_ms(self) -> float | None:
        """Device time (ms) at which the model next has a stream line or scheduled work due.

        The server wakes then, so a sample leaves as soon as it is ready rather than at the next
        :attr:`stream_tick`. ``None`` (the default): nothing scheduled, the server looks every tick.
        """
        return None

    def send_due_lines(self) -> None:
        """Send the stream lines due by now, before :meth:`advance` starts long work.

        A device sends a finished sample before it begins its next cycle; a model whose
        ``advance`` computes a whole cycle at once calls this first, so the computation does not
        delay the line. Served, the lines leave at once; unserved (unit tests) they wait in
        :meth:`stream_lines`.
        """
        if self._line_sink is not None:
            self._line_sink()

    def raise_fault(self, code: str, text: str) -> str:
        """Record a fault arising outside a command; return the ``!ERR`` line to send."""
        self.last_error = (code, text)
        return f"!ERR {code} {text}"

    # -- dispatch --------------------------------------------------------------------------------
    @staticmethod
    def handler_name(word: str) -> str:
        """The handler of a command word, any case (``THR?`` → ``cmd_THR_Q``, ``*IDN?`` → ``cmd_IDN_Q``); ``""`` for a
        word that cannot be a command (``*`` only before the common ``*IDN?`` and ``*RST``).

        >>> LineSimulator.handler_name("sim:truth?"), LineSimulator.handler_name("IDN?")
        ('cmd_SIM_TRUTH_Q', '')
        """
        match = _WORD.fullmatch(word.upper())
        if match is None:
            return ""
        star, body, query = match.groups()
        name = "cmd_" + body.replace(":", "_") + ("_Q" if query else "")
        return name if bool(star) == (name in _STARRED) else ""

    @staticmethod
    def words(line: str) -> list[str]:
        """The words of a command line: separated by spaces (any number), bytes outside printable ASCII
        written ``\\xNN`` as part of their word (:func:`printable`).

        >>> LineSimulator.words(" THR  12\\t")
        ['THR', '12\\\\x09']
        """
        return [w for w in printable(line).split(" ") if w]

    def handle(self, line: str) -> Lines:
        """The reply of one command line (nothing for a line with no word: it is no command)."""
        words = self.words(line)
        if not words:
            return iter(())
        name = self.handler_name(words[0])
        handler = getattr(self, name, None) if name else None
        if handler is None:
            raise CommandError("E01", f"unknown command {words[0]}")
        return handler(words[1:])

    def execute(self, line: str) -> list[str]:
        """Run one command in-process, without a server: its reply lines (``ERR ...`` included).

        Delays advance the simulated clock only (as ``SIM:CLOCK FAST``); for unit tests of a model.
        """
        out: list[str] = []
        try:
            for item in self.handle(line):
                if isinstance(item, Delay):
                    self.advance(item.seconds)
                else:
                    out.append(item)
        except CommandError as exc:
            self.last_error = (exc.code, exc.text)
            out.append(f"ERR {exc.code} {exc.text}")
        return out

    @staticmethod
    def expect(args: list[str], n: int, usage: str) -> None:
        if len(args) != n:
            raise CommandError("E02", f"usage: {usage}")

    @staticmethod
    def keyword(args: list[str], usage: str) -> str:
        """The one argument of a command whose ``usage`` ends in its choices (``STREAM ON|OFF``), upper-cased;
        anything else answers ``ERR E02 usage: ...``.

        >>> LineSimulator.keyword(["on"], "STREAM ON|OFF")
        'ON'
        """
        if len(args) != 1 or args[0].upper() not in usage.split()[-1].split("|"):
            raise CommandError("E02", f"usage: {usage}")
        return args[0].upper()

    @staticmethod
    def number(text: str, lo: float, hi: float, integer: bool = True) -> float:
        """The value of a numeric argument within ``lo..hi`` (``ERR E03`` outside).

        An integer argument is digits with an optional sign (``12``, ``-3``); any other is a decimal
        number, optionally with an exponent (``12``, ``-0.5``, ``2e+06``). Anything else (``1.5`` for
        an integer, ``nan``, ``0x10``, ``1_000``) answers ``ERR E02``.

        >>> LineSimulator.number("-3", -10, 10), LineSimulator.number("2.5e1", 0, 100, integer=False)
        (-3, 25.0)
        """
        if integer and not _INTEGER.fullmatch(text):
            raise CommandError("E02", f"not an integer: {text}")
        if not integer and not _NUMBER.fullmatch(text):
            raise CommandError("E02", f"not a number: {text}")
        value = int(text) if integer else float(text)
        if not lo <= value <= hi:
            raise CommandError("E03", f"{text} outside {_bound(lo)}..{_bound(hi)}")
        return value

    @staticmethod
    def fixed(value: float, decimals: int) -> str:
        """:func:`fixed`: a reply field with ``decimals`` decimals, never ``-0.000``."""
        return fixed(value, decimals)

    # -- common commands (§0.2) ------------------------------------------------------------------
    def cmd_IDN_Q(self, args: list[str]) -> Lines:
        self.expect(args, 0, "*IDN?")
        yield f"OK {self.kind} {self.vendor} {self.model} {self.firmware} {self.serial_number}"

    def cmd_PING(self, args: list[str]) -> Lines:
        self.expect(args, 0, "PING")
        yield "OK PONG"

    def cmd_RST(self, args: list[str]) -> Lines:
        self.expect(args, 0, "*RST")
        self.reset()
        yield "OK"

    def cmd_STAT_Q(self, args: list[str]) -> Lines:
        self.expect(args, 0, "STAT?")
        yield f"OK {self.state} {','.join(sorted(self.flags)) or '-'}"

    def cmd_TIME_Q(self, args: list[str]) -> Lines:
        self.expect(args, 0, "TIME?")
        yield f"OK {int(self.clock_ms)}"

    def cmd_STREAM(self, args: list[str]) -> Lines:
        self.streaming = self.keyword(args, "STREAM ON|OFF") == "ON"
        yield "OK"

    def cmd_ERR_Q(self, args: list[str]) -> Lines:
        self.expect(args, 0, "ERR?")
        yield f"OK {self.last_error[0]} {self.last_error[1]}"

    def cmd_ABORT(self, args: list[str]) -> Lines:
        self.expect(args, 0, "ABORT")
        yield "OK"

    def cmd_SIM_SEED(self, args: list[str]) -> Lines:
        self.expect(args, 1, "SIM:SEED <n>")
        self.seed = int(self.number(args[0], 0, 2**63))
        self.rng = random.Random(self.seed)
        yield "OK"

    def cmd_SIM_CLOCK(self, args: list[str]) -> Lines:
        self.fast = self.keyword(args, "SIM:CLOCK REAL|FAST") == "FAST"
        yield "OK"

    def cmd_SIM_FAULT(self, args: list[str]) -> Lines:
        if not args:
            raise CommandError("E02", "usage: SIM:FAULT <name> <value...> | CLEAR")
        if args[0].upper() == "CLEAR":
            self.expect(args, 1, "SIM:FAULT CLEAR")
            self.faults.clear()
        else:
            name = args[0].upper()
            if name not in self.fault_names():
                raise CommandError("E03", f"unknown fault {name}; known: {' '.join(self.fault_names()) or '-'}")
            self.faults[name] = args[1:]
        yield "OK"

    def cmd_SIM_FAULT_Q(self, args: list[str]) -> Lines:
        self.expect(args, 0, "SIM:FAULT?")
        yield from self.fault_lines()
        yield "OK"

    def cmd_SIM_TRUTH_Q(self, args: list[str]) -> Lines:
        self.expect(args, 0, "SIM:TRUTH?")
        for line in self.truth_lines():
            yield f"TRUTH {line}"
        yield "OK"

    def fault_names(self) -> tuple[str, ...]:
        """Names accepted by ``SIM:FAULT`` (subclasses override)."""
        return ()

    def truth_lines(self) -> list[str]:
        """Ground-truth quantities for ``SIM:TRUTH?`` (subclasses override)."""
        return []

    def fault_value(self, name: str, index: int = 0, default: float = 0.0) -> float:
        values = self.faults.get(name)
        return float(values[index]) if values and len(values) > index else default

    def fault_lines(self) -> list[str]:
        """``FAULT <name> <values>`` (``-`` for none) of every fault set, by name: ``SIM:FAULT?`` and the truth list them."""
        return [f"FAULT {name} {' '.join(values) or '-'}" for name, values in sorted(self.faults.items())]


class SimulatedWorld:
    """A session's shared simulated world: its settings, the session clock, and what simulators build from them.

    A recipe's ``[world]`` table (validated against the :attr:`Instrument.world_parameters` of its
    simulated instruments) becomes one ``SimulatedWorld`` per session
    (:meth:`mirrorlab.core.Session.set_world`). Each simulator that shares it asks for the scene
    through :meth:`shared`, so the first one builds it and the others get the same object: one
    scene, on one clock, for every simulated instrument of the session.

    Parameters
    ----------
    settings
        The world's settings (typed values of the ``[world]`` table).
    clock
        The session clock, s (the world's time base).

    Examples
    --------
    >>> w = SimulatedWorld({"scene": "still"}, clock=lambda: 1.5)
    >>> a = w.shared("tracking", lambda settings, clock: [settings["scene"], clock()])
    >>> a, w.shared("tracking", lambda settings, clock: None) is a
    (['still', 1.5], True)
    """

    def __init__(self, settings: Mapping[str, Any], clock: Callable[[], float]) -> None:
        self.settings = dict(settings)
        self.clock = clock
        self._built: dict[str, Any] = {}
        self._lock = threading.Lock()

    def shared(self, key: str, build: Callable[[Mapping[str, Any], Callable[[], float]], T]) -> T:
        """The object stored under ``key``, built once by ``build(settings, clock)``."""
        with self._lock:
            if key not in self._built:
                self._built[key] = build(self.settings, self.clock)
            return self._built[key]

    def get(self, key: str) -> Any:
        """The object built under ``key``, or ``None`` if no simulator built it yet."""
        with self._lock:
            return self._built.get(key)


class _Input(enum.Enum):
    """What the server read that is no command line."""

    ABORT = "the byte 0x18"
    TOO_LONG = "a line longer than MAX_LINE"


class SimulatorServer:
    """Serve a :class:`LineSimulator` on a pty (default) or TCP endpoint from a daemon thread.

    Use as a context manager::

        with SimulatorServer(MyModel(seed=1)) as server:
            driver = MyInstrument("dev", port=server.url)

    ``server.endpoint.faults`` injects transport faults; :meth:`disconnect` simulates unplugging.
    A pty is linked at ``link`` (default: ``<link_dir>/tty<KIND>``, in a temporary folder unless
    ``link_dir`` is given); TCP listens on ``host`` (default the loopback interface) ``port`` (0: any
    free port). ``baud`` paces what the simulator sends to that many bits/s of 8N1, as a real line
    would (``None``: as fast as the client reads).
    """

    def __init__(self, model: LineSimulator, transport: str = "pty", link_dir: Path | None = None, *,
                 link: Path | None = None, port: int = 0, host: str = "127.0.0.1", baud: int | None = None) -> None:
        self.model = model
        self._tmpdir = None
        if transport == "pty":
            if link is None and link_dir is None:
                self._tmpdir = tempfile.TemporaryDirectory(prefix="mirrorlab-sim-")
                link_dir = Path(self._tmpdir.name)
            where = Path(link) if link is not None else Path(str(link_dir)) / f"tty{model.kind}"
            self.endpoint: Endpoint = PtyEndpoint(where, seed=model.seed, baud=baud)
        elif transport == "tcp":
            self.endpoint = TcpEndpoint(host, port, seed=model.seed, baud=baud)
        else:
            raise ValueError(f"transport must be 'pty' or 'tcp', not {transport!r}")
        #: Output waiting beyond which a stream line is dropped: half a second of a paced line, bytes.
        self.stream_backlog = max(256, baud // 20) if baud else STREAM_BACKLOG
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._serve, name=f"simulator {model.kind}", daemon=True)
        self._pending = b""           # input of the current client not yet taken as commands
        self._overlong = False        # the line being received passed MAX_LINE: discard it up to its LF
        self._client = 0              # the endpoint generation whose input _pending holds
        self._lost = 0                # stream lines dropped since the last !OVF line
        self._synced = time.monotonic()   # monotonic time up to which the model's clock has been advanced
        self._failing = ""            # the internal error last reported outside a command
        self.lock = threading.RLock()  # held while the model changes; tests may hold it to inspect

    @property
    def url(self) -> str:
        return self.endpoint.url

    @property
    def serving(self) -> bool:
        """Whether the serving thread is alive (it ends only with :meth:`close`)."""
        return self._thread.is_alive()

    def start(self) -> SimulatorServer:
        self._synced = time.monotonic()
        self._thread.start()
        return self

    def __enter__(self) -> SimulatorServer:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.close()

    def disconnect(self) -> None:
        """Drop the current connection, as if the device were unplugged and plugged in again."""
        with self.lock:
            self.endpoint.disconnect()
            self._forget_input()

    def close(self) -> None:
        self._stop.set()
        self.endpoint.faults.stall = False
        if self._thread.is_alive():
            self._thread.join(timeout=2.0)
        self.endpoint.close()
        if self._tmpdir is not None:
            self._tmpdir.cleanup()

    # -- serving ---------------------------------------------------------------------------------
    def _serve(self) -> None:
        self.model._line_sink = self._send_stream
        while not self._stop.is_set():
            try:
                self._step()
                self._failing = ""
            except Exception as exc:  # the model's own bug outside any command: reported, and serving goes on
                self._internal_error(exc)

    def _step(self) -> None:
        """Wait for a command (or the model's next due line), keep the device clock and streams going, run it."""
        command = self._next_command(self._wait())
        with self.lock:
            self._catch_up()
            if self.endpoint.faults.stall:
                return      # the device hangs: no answer, no stream (a line read meanwhile is lost)
            self._send_stream()
            if command is not None:
                slept = self._run(command)
                if not self.model.fast:
                    self._synced += slept   # REAL: the Delays passed on the wall clock too
                self._send_stream()

    def _catch_up(self) -> None:
        """Advance the device clock to the wall clock (plus, in FAST mode, the skipped Delays of commands)."""
        now = time.monotonic()
        if now > self._synced:  # a REAL Delay cut short by ABORT leaves the clock ahead for a moment
            elapsed, self._synced = now - self._synced, now   # first: a model failing here fails once per stretch
            self.model.advance(elapsed)

    def _internal_error(self, exc: Exception) -> None:
        text = f"internal {type(exc).__name__}: {exc}"
        if text != self._failing:   # a fault that persists is reported once
            log.error("simulator %s failed outside a command", self.model.kind, exc_info=exc)
            self._failing = text
            with self.lock:
                self._send(self.model.raise_fault("E99", text)[:MAX_LINE])
        self._stop.wait(0.01)

    def _send(self, line: str) -> None:
        self.endpoint.send(printable(line).encode("ascii") + b"\n")

    def _forget_input(self) -> None:
        """A client came or went: what the last one sent, and its lost-line count, are not the next one's."""
        self._client = self.endpoint.generation
        self._pending, self._overlong, self._lost = b"", False, 0

    def _read(self, timeout: float) -> None:
        """Wait up to ``timeout`` s for the client's bytes and keep them in ``_pending``."""
        generation, data = self.endpoint.recv(timeout)  # outside the lock: disconnect() may run meanwhile
        with self.lock:
            if self.endpoint.generation != self._client:
                self._forget_input()
            if data and generation == self._client:    # else: the bytes of a client that has gone
                self._pending += data

    def _next_command(self, timeout: float) -> str | _Input | None:
        """The next command line (or ABORT byte, or too long a line), waiting up to ``timeout`` s; ``None`` if none."""
        if self.endpoint.backlog > REPLY_BACKLOG:   # the client does not read its replies: the device waits
            self._stop.wait(timeout)
            return None
        command = self._take_command()
        if command is None:
            self._read(timeout)
            command = self._take_command()
        return command

    def _take_command(self) -> str | _Input | None:
        """Take the next complete command from ``_pending``, if there is one."""
        with self.lock:
            pending = self._pending
            newline, cancel = pending.find(b"\n"), pending.find(ABORT_BYTE)
            if cancel >= 0 and (newline < 0 or cancel < newline):
                self._pending, self._overlong = pending[cancel + 1:], False   # the line it interrupts goes with it
                return _Input.ABORT
            if newline < 0:
                if len(pending) > MAX_LINE + 1:            # no LF in reach: drop the line as it comes
                    self._pending, self._overlong = b"", True
                return None
            raw, self._pending = pending[:newline].rstrip(b"\r"), pending[newline + 1:]
            if self._overlong or len(raw) > MAX_LINE:
                self._overlong = False
                return _Input.TOO_LONG
            return raw.decode("latin-1")   # byte for character: printable() shows the stray ones as \xNN

    def _read_while_running(self, timeout: float) -> None:
        if len(self._pending) > INPUT_LIMIT:
            time.sleep(timeout)             # enough is waiting: the rest stays in the transport
        else:
            self._read(timeout)

    def _abort_requested(self) -> bool:
        """Whether the byte 0x18 or an ``ABORT`` line came (taken from the input: acted on at once)."""
        self._read_while_running(0)
        rest = _without_abort(self._pending)
        if rest is None:
            return False
        self._pending = rest
        return True

    def _wait(self) -> float:
        """Seconds to wait for a command: until the model's next due line, at most one tick."""
        tick = self.model.stream_tick
        with self.lock:
            due = None if self.endpoint.faults.stall else self.model.next_due_ms()
            if due is None:
                return tick
            device_now = self.model.clock_ms + (time.monotonic() - self._synced) * 1000.0
        return min(tick, max(0.0, (due - device_now) / 1000.0))

    def _send_stream(self) -> None:
        """Send the model's due unsolicited lines (nothing while the device is stalled).

        A stream line that finds more than :attr:`stream_backlog` bytes waiting is dropped and
        counted; ``!OVF <n>`` tells the client as soon as there is room. ``!ERR`` lines are never
        dropped. With no client connected the lines go nowhere, as on an unplugged line.
        """
        if self.endpoint.faults.stall:
            return
        lines = self.model.stream_lines() if self.model.streaming else []
        self._lost += self.model.lost_lines
        self.model.lost_lines = 0
        if not self.endpoint.connected:
            self._lost = 0
            return
        for line in lines:
            if line.startswith("!ERR "):
                self._send(line)
            elif self.endpoint.backlog > self.stream_backlog:
                self._lost += 1
            else:
                self._report_lost()
                self._send(line)
        if self.endpoint.backlog <= self.stream_backlog:
            self._report_lost()

    def _report_lost(self) -> None:
        if self._lost:
            self._send(f"!OVF {self._lost}")
            self._lost = 0

    def _run(self, command: str | _Input) -> float:
        """Answer one input; returns the simulated seconds its :class:`Delay` s advanced the clock."""
        if command is _Input.ABORT:
            self._send("OK")          # nothing runs: ABORT just replies
            return 0.0
        if command is _Input.TOO_LONG:
            text = f"line too long: over {MAX_LINE} characters; the whole line was discarded"
            self.model.last_error = ("E02", text)
            self._send(f"ERR E02 {text}")
            return 0.0
        return self._run_command(command)

    def _run_command(self, line: str) -> float:
        """Run one command line; returns the simulated seconds its :class:`Delay` s advanced the clock.

        Its reply goes to the client that sent it only: one that leaves meanwhile takes it along.
        """
        model, client = self.model, self._client
        delayed = 0.0

        def reply(text: str) -> None:
            if self.endpoint.generation == client:
                self._send(text)

        try:
            for item in model.handle(line):
                if isinstance(item, Delay):
                    model.advance(item.seconds)
                    delayed += item.seconds
                    if not model.fast:
                        self._sleep_watching_abort(item.seconds)
                    if self._abort_requested():
                        model.last_error = ("E09", "aborted")
                        reply("ERR E09 aborted")
                        reply("OK")
                        return delayed
                else:
                    reply(item)
        except CommandError as exc:
            model.last_error = (exc.code, exc.text)
            reply(f"ERR {exc.code} {exc.text}")
        except Exception as exc:  # a bug of the model: the simulator says so and goes on
            log.exception("simulator %s failed on %r", model.kind, line)
            text = f"internal {type(exc).__name__}: {exc}"[:MAX_LINE]
            model.last_error = ("E99", text)
            reply(f"ERR E99 {text}")
        return delayed

    def _sleep_watching_abort(self, seconds: float) -> None:
        end = time.monotonic() + seconds
        while (remaining := end - time.monotonic()) > 0 and not self._stop.is_set():
            self._read_while_running(min(remaining, 0.02))
            if _without_abort(self._pending) is not None:
                return


def _without_abort(pending: bytes) -> bytes | None:
    """``pending`` input without its first abort, ``None`` if it holds none: the byte 0x18 (with the
    incomplete line it interrupts) or else a whole ``ABORT`` line among the lines waiting."""
    cancel = pending.find(ABORT_BYTE)
    if cancel >= 0:
        start = pending.rfind(b"\n", 0, cancel) + 1
        return pending[:start] + pending[cancel + 1:]
    lines = pending.split(b"\n")
    for i, raw in enumerate(lines[:-1]):
        if raw.rstrip(b"\r").strip(b" ").upper() == b"ABORT":
            return b"\n".join(lines[:i] + lines[i + 1:])
    return None
