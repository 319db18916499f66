"""Simulators: device models that speak an instrument's line protocol over a real byte stream.

A :class:`LineSimulator` is the device model. It implements the common commands of
``instruments.md`` §0.2 (``*IDN?``, ``PING``, ``*RST``, ``STAT?``, ``TIME?``, ``STREAM``, ``ERR?``
and the ``SIM:`` commands) and dispatches the rest to ``cmd_<WORD>`` methods of the subclass. A
handler is a generator: it yields reply lines (data lines, then the terminal line) and may yield
:class:`Delay` to model time. The :class:`SimulatorServer` runs the model in a thread on a
pseudo-terminal or TCP endpoint, sleeps through delays in real-time mode (``SIM:CLOCK REAL``) or
only advances the simulated clock (``SIM:CLOCK FAST``), and between yielded lines watches for
``ABORT`` so a running command can be aborted as the protocol requires.
"""

from __future__ import annotations

import logging
import random
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
        return "cmd_" + word.upper().replace("*", "").replace("?", "_Q").replace(":", "_")

    def handle(self, line: str) -> Lines:
        words = line.split()
        if not words:
            raise CommandError("E02", "empty command")
        handler = getattr(self, self.handler_name(words[0]), None)
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
        try:
            value = int(text) if integer else float(text)
        except ValueError:
            raise CommandError("E02", f"not a number: {text}") from None
        if not lo <= value <= hi:
            raise CommandError("E03", f"{text} outside {lo:g}..{hi:g}")
        return value

    # -- common commands (§0.2) ------------------------------------------------------------------
    def cmd_IDN_Q(self, args: list[str]) -> Lines:
        yield f"OK {self.kind} {self.vendor} {self.model} {self.firmware} {self.serial_number}"

    def cmd_PING(self, args: list[str]) -> Lines:
        yield "OK PONG"

    def cmd_RST(self, args: list[str]) -> Lines:
        self.reset()
        yield "OK"

    def cmd_STAT_Q(self, args: list[str]) -> Lines:
        yield f"OK {self.state} {','.join(sorted(self.flags)) or '-'}"

    def cmd_TIME_Q(self, args: list[str]) -> Lines:
        yield f"OK {int(self.clock_ms)}"

    def cmd_STREAM(self, args: list[str]) -> Lines:
        self.streaming = self.keyword(args, "STREAM ON|OFF") == "ON"
        yield "OK"

    def cmd_ERR_Q(self, args: list[str]) -> Lines:
        yield f"OK {self.last_error[0]} {self.last_error[1]}"

    def cmd_ABORT(self, args: list[str]) -> Lines:
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
            self.faults.clear()
        else:
            name = args[0].upper()
            if name not in self.fault_names():
                raise CommandError("E03", f"unknown fault {name}; known: {' '.join(self.fault_names()) or '-'}")
            self.faults[name] = args[1:]
        yield "OK"

    def cmd_SIM_FAULT_Q(self, args: list[str]) -> Lines:
        yield from self.fault_lines()
        yield "OK"

    def cmd_SIM_TRUTH_Q(self, args: list[str]) -> Lines:
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


class SimulatorServer:
    """Serve a :class:`LineSimulator` on a pty (default) or TCP endpoint from a daemon thread.

    Use as a context manager::

        with SimulatorServer(MyModel(seed=1)) as server:
            driver = MyInstrument("dev", port=server.url)

    ``server.endpoint.faults`` injects transport faults; :meth:`disconnect` simulates unplugging.
    A pty is linked at ``link`` (default: ``<link_dir>/tty<KIND>``, in a temporary folder unless
    ``link_dir`` is given); TCP listens on 127.0.0.1 ``port`` (0: any free port).
    """

    def __init__(self, model: LineSimulator, transport: str = "pty", link_dir: Path | None = None, *,
                 link: Path | None = None, port: int = 0) -> None:
        self.model = model
        self._tmpdir = None
        if transport == "pty":
            if link is None and link_dir is None:
                self._tmpdir = tempfile.TemporaryDirectory(prefix="mirrorlab-sim-")
                link_dir = Path(self._tmpdir.name)
            where = Path(link) if link is not None else Path(str(link_dir)) / f"tty{model.kind}"
            self.endpoint: Endpoint = PtyEndpoint(where, seed=model.seed)
        elif transport == "tcp":
            self.endpoint = TcpEndpoint(port=port, seed=model.seed)
        else:
            raise ValueError(f"transport must be 'pty' or 'tcp', not {transport!r}")
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._serve, name=f"simulator {model.kind}", daemon=True)
        self._pending = b""
        self._connection = 0  # counts disconnects: bytes read from a dropped connection are discarded
        self.lock = threading.RLock()  # held while the model changes; tests may hold it to inspect

    @property
    def url(self) -> str:
        return self.endpoint.url

    @property
    def serving(self) -> bool:
        """Whether the serving thread is alive (it ends only with :meth:`close`)."""
        return self._thread.is_alive()

    def start(self) -> SimulatorServer:
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
            self._pending = b""
            self._connection += 1

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
        while not self._stop.is_set():
            if not self.endpoint.wait_connection(self._stop):
                return
            self._serve_connection()

    def _send(self, line: str) -> None:
        self.endpoint.send(line.encode("ascii") + b"\n")

    def _next_line(self, timeout: float) -> str | None:
        """The next complete command line, ``""`` on timeout, ``None`` if the driver hung up."""
        while b"\n" not in self._pending and b"\x18" not in self._pending:
            connection = self._connection
            data = self.endpoint.recv(timeout)  # outside the lock: disconnect() may run meanwhile
            if data is None:
                return None
            if not data:
                return ""
            with self.lock:
                if connection == self._connection:  # else: the old driver's bytes, not the new one's
                    self._pending += data
        if self._pending.startswith(b"\x18"):
            self._pending = self._pending[1:]
            return "ABORT"
        raw, _, self._pending = self._pending.partition(b"\n")
        return raw.rstrip(b"\r").replace(b"\x18", b"").decode("ascii", errors="replace")

    def _abort_requested(self) -> bool:
        data = self.endpoint.recv(0)
        if data:
            self._pending += data
        if b"\x18" in self._pending:
            self._pending = self._pending.replace(b"\x18", b"", 1)
            return True
        lines = self._pending.split(b"\n")
        for i, raw in enumerate(lines[:-1]):
            if raw.strip().upper() == b"ABORT":
                del lines[i]
                self._pending = b"\n".join(lines)
                return True
        return False

    def _serve_connection(self) -> None:
        # The device clock follows the wall clock (plus, in FAST mode, the skipped Delays of
        # commands): ``synced`` is the monotonic time up to which the model has been advanced.
        synced = time.monotonic()
        self.model._line_sink = self._send_stream
        while not self._stop.is_set():
            line = self._next_line(timeout=self._wait(synced))
            if line is None:
                self.endpoint.disconnect()
                return
            with self.lock:
                now = time.monotonic()
                if now > synced:  # a REAL Delay cut short by ABORT leaves the clock ahead for a moment
                    self.model.advance(now - synced)
                    synced = now
                if self.endpoint.faults.stall:
                    continue
                if line:
                    slept = self._run_command(line)
                    synced += 0.0 if self.model.fast else slept  # REAL: the Delays passed on the wall clock too
                self._send_stream()

    def _wait(self, synced: float) -> float:
        """Seconds to wait for a command: until the model's next due line, at most one tick."""
        tick = self.model.stream_tick
        with self.lock:
            due = None if self.endpoint.faults.stall else self.model.next_due_ms()
            if due is None:
                return tick
            device_now = self.model.clock_ms + (time.monotonic() - synced) * 1000.0
        return min(tick, max(0.0, (due - device_now) / 1000.0))

    def _send_stream(self) -> None:
        """Send the model's due stream lines (nothing while the device is stalled)."""
        if self.model.streaming and not self.endpoint.faults.stall:
            for s in self.model.stream_lines():
                self._send(s)

    def _run_command(self, line: str) -> float:
        """Run one command; returns the simulated seconds its :class:`Delay` s advanced the clock."""
        model = self.model
        delayed = 0.0
        if line.strip().upper() == "ABORT":
            self._send("OK")
            return delayed
        try:
            for item in model.handle(line):
                if isinstance(item, Delay):
                    model.advance(item.seconds)
                    delayed += item.seconds
                    if not model.fast:
                        self._sleep_watching_abort(item.seconds)
                    if self._abort_requested():
                        model.last_error = ("E09", "aborted")
                        self._send("ERR E09 aborted")
                        self._send("OK")
                        return delayed
                else:
                    self._send(item)
        except CommandError as exc:
            model.last_error = (exc.code, exc.text)
            self._send(f"ERR {exc.code} {exc.text}")
        except Exception as exc:  # a model bug answers like firmware would: a hardware fault
            log.exception("simulator %s failed on %r", model.kind, line)
            model.last_error = ("E08", f"simulator fault {type(exc).__name__}")
            self._send(f"ERR E08 simulator fault {type(exc).__name__}: {exc}"[:200])
        return delayed

    def _sleep_watching_abort(self, seconds: float) -> None:
        end = time.monotonic() + seconds
        while (remaining := end - time.monotonic()) > 0 and not self._stop.is_set():
            data = self.endpoint.recv(min(remaining, 0.02))
            if data:
                self._pending += data
                if b"\x18" in self._pending or b"ABORT" in self._pending.upper():
                    return
