"""The line protocol driver shared by every mirrorlab serial instrument (spec ``instruments.md`` §0.2).

Rules it enforces: one command at a time; each command ends with exactly one terminal line,
``OK[ fields]`` or ``ERR <code> <text>``; data lines start with an upper-case tag; unsolicited lines
start with ``!`` and arrive only between complete lines. A reader thread owns the port's input: it
splits lines, hands ``!`` lines to ``on_unsolicited`` and queues the rest for the command waiting
on them. Every wait has a timeout; bytes that break the rules raise :class:`ProtocolError`.
"""

from __future__ import annotations

import logging
import queue
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, TypeVar, overload

import serial

from ..errors import DeviceDisconnected, DeviceReplyError, DeviceTimeout, ProtocolError
from .transport import SerialPort

try:  # pyserial's POSIX back end lets termios.error (not an OSError) out of flush() on a hung-up tty
    from termios import error as _TermiosError
    _PORT_ERRORS: tuple[type[Exception], ...] = (serial.SerialException, OSError, _TermiosError)
except ImportError:  # Windows
    _PORT_ERRORS = (serial.SerialException, OSError)
#: How a port closed by another thread meanwhile fails (a socket's fd -1: ValueError; gone: TypeError...).
_CLOSED_PORT_ERRORS: tuple[type[Exception], ...] = (*_PORT_ERRORS, TypeError, AttributeError, ValueError)

log = logging.getLogger(__name__)

T = TypeVar("T")

MAX_COMMAND = 200
ABORT_BYTE = b"\x18"


@dataclass
class Reply:
    """A complete reply: the terminal line's fields after ``OK`` and the data lines before it."""

    fields: list[str]
    data: list[str] = field(default_factory=list)

    @overload
    def field(self, i: int, name: str = "field") -> str: ...
    @overload
    def field(self, i: int, name: str, kind: Callable[[str], T]) -> T: ...

    def field(self, i: int, name: str = "field", kind: Callable[[str], Any] = str) -> Any:
        """Field ``i`` converted by ``kind`` (``int``, ``float``...); :class:`ProtocolError` if absent or malformed."""
        try:
            text = self.fields[i]
        except IndexError:
            raise ProtocolError(f"reply OK {' '.join(self.fields)!r} lacks {name} (position {i})") from None
        try:
            return kind(text)
        except ValueError:
            raise ProtocolError(f"reply OK {' '.join(self.fields)[:60]!r}: {name} (position {i}) is {text[:20]!r}, "
                                f"not {getattr(kind, '__name__', 'a value')}; check the device's firmware "
                                "and the cable") from None


class _Hangup:
    """Queued by the reader when the port fails, so a waiting command learns at once."""

    def __init__(self, error: Exception) -> None:
        self.error = error


class LineClient:
    """Command/reply client over an open pyserial port.

    Parameters
    ----------
    port
        An open pyserial port (from :func:`~mirrorlab.core.devices.transport.open_port`); its read
        timeout should be short (~50 ms): it only bounds how fast the reader notices a stop.
    device
        Name used in error messages (``"film_scanner 'cam' on /dev/ttyUSB0"``).
    timeout
        Default seconds to wait for a command's terminal line.
    on_unsolicited
        Called from the reader thread with each ``!`` line (without the ``!``).
    """

    def __init__(self, port: SerialPort, device: str = "device", timeout: float = 2.0,
                 on_unsolicited: Callable[[str], None] | None = None) -> None:
        self.port = port
        self.device = device
        self.timeout = timeout
        self.on_unsolicited = on_unsolicited
        self.garbage_lines = 0
        #: The command waiting for its reply (``None`` when idle).
        self.pending: str | None = None
        self._abort_sent = False
        self._desynced = False
        self._lines: queue.Queue[str | _Hangup] = queue.Queue()
        self._lock = threading.Lock()  # one command at a time
        self._stop = threading.Event()
        self._reader = threading.Thread(target=self._read_loop, name=f"reader {device}", daemon=True)
        self._reader.start()

    # -- reader thread -----------------------------------------------------------------------
    def _read_loop(self) -> None:
        buf = b""
        while not self._stop.is_set():
            try:
                chunk = self.port.read(self.port.in_waiting or 1)
            except _CLOSED_PORT_ERRORS as exc:
                if not self._stop.is_set():
                    self._lines.put(_Hangup(exc))
                return
            if not chunk:
                continue
            buf += chunk
            while b"\n" in buf:
                raw, buf = buf.split(b"\n", 1)
                self._dispatch(raw.rstrip(b"\r"))
            if len(buf) > 65536:  # no newline in 64 KiB: garbage, not a line
                self._dispatch(buf)
                buf = b""

    def _dispatch(self, raw: bytes) -> None:
        try:
            line = raw.decode("ascii")
        except UnicodeDecodeError:
            self.garbage_lines += 1
            line = "\x00" + raw.decode("latin-1")  # marked: never a valid reply
        if line.startswith("!"):
            if self.on_unsolicited is not None:
                try:
                    self.on_unsolicited(line[1:])
                except Exception:  # a consumer's bug must not kill the reader
                    log.exception("%s: unsolicited-line handler failed on %r", self.device, line)
            return
        self._lines.put(line)

    # -- commands ------------------------------------------------------------------------------
    def query(self, command: str, timeout: float | None = None) -> Reply:
        """Send ``command`` and return its reply.

        Raises
        ------
        DeviceTimeout
            No terminal line within ``timeout`` seconds.
        DeviceReplyError
            The device answered ``ERR <code> <text>``.
        ProtocolError
            The device sent garbage or a line of the wrong shape.
        DeviceDisconnected
            The port failed or was closed.
        """
        if len(command) > MAX_COMMAND or "\n" in command:
            raise ValueError(f"command too long or multi-line: {command[:40]!r}...")
        timeout = self.timeout if timeout is None else timeout
        with self._lock:
            self._drain_stale()
            if self._desynced:
                self._resynchronise(timeout)
            self.pending = command
            try:
                self._write(command.encode("ascii") + b"\n")
                return self._collect(command, timeout)
            finally:
                self.pending = None

    @property
    def busy(self) -> bool:
        """Whether a command is waiting for its reply."""
        return self._lock.locked()

    def abort(self) -> None:
        """Abort the running command (its ``query`` raises ``E09 aborted``), or send ``ABORT``.

        The device answers the running command ``ERR E09 aborted`` and then ABORT's own ``OK``;
        the waiting :meth:`query` consumes both so the next command starts clean.
        """
        if self._lock.acquire(blocking=False):
            try:
                self._drain_stale()
                self._write(b"ABORT\n")
                self._collect("ABORT", self.timeout)
            finally:
                self._lock.release()
            return
        self._abort_sent = True
        self._write(ABORT_BYTE)

    def _write(self, data: bytes) -> None:
        try:
            self.port.write(data)
            self.port.flush()
        except _CLOSED_PORT_ERRORS as exc:
            raise DeviceDisconnected(f"{self.device}: write failed ({exc}); check the cable and power") from exc

    def _drain_stale(self) -> None:
        while True:
            try:
                item = self._lines.get_nowait()
            except queue.Empty:
                return
            if isinstance(item, _Hangup):
                raise DeviceDisconnected(f"{self.device}: connection lost ({item.error}); "
                                         "check the cable and power, then reconnect") from item.error
            log.warning("%s: discarding stale line %r", self.device, item)

    def _collect(self, command: str, timeout: float) -> Reply:
        deadline = time.monotonic() + timeout
        data: list[str] = []
        while True:
            remaining = deadline - time.monotonic()
            try:
                item = self._lines.get(timeout=max(0.0, remaining))
            except queue.Empty:
                self._desynced = True  # its reply may still come: the next command resynchronises first
                raise DeviceTimeout(
                    f"{self.device} did not answer {command!r} within {timeout:g} s: check that it "
                    "is powered and connected, the baud rate, and that the port is the device's"
                ) from None
            if isinstance(item, _Hangup):
                raise DeviceDisconnected(f"{self.device}: connection lost during {command!r} ({item.error}); "
                                         "check the cable and power, then reconnect") from item.error
            if item == "OK" or item.startswith("OK "):
                return Reply(item.split()[1:], data)
            if item.startswith("ERR "):
                parts = item.split(" ", 2)
                code = parts[1] if len(parts) > 1 else "E??"
                if code == "E09" and self._abort_sent:
                    self._abort_sent = False
                    self._collect("ABORT", timeout)  # ABORT's own OK follows the E09
                raise DeviceReplyError(command, code, parts[2] if len(parts) > 2 else "", self.device)
            if item[:1].isupper() and item.isprintable():
                data.append(item)
                continue
            self.garbage_lines += 1
            self._desynced = True
            raise ProtocolError(
                f"{self.device} sent garbage in reply to {command!r}: {item[:60]!r}. Check the baud "
                "rate and cable; electrical noise or a wrong device on this port give this"
            )

    def _resynchronise(self, timeout: float) -> None:
        """After a timeout or garbage: ``PING`` and drop every line before its ``OK PONG``.

        The device answers strictly in order, so a late reply to the failed command arrives before
        the PONG and is discarded instead of being taken as the next command's reply.
        """
        self._write(b"PING\n")
        deadline = time.monotonic() + timeout
        while True:
            try:
                item = self._lines.get(timeout=max(0.0, deadline - time.monotonic()))
            except queue.Empty:
                raise DeviceTimeout(f"{self.device} did not answer PING within {timeout:g} s while "
                                    "resynchronising after an error: check power and cable") from None
            if isinstance(item, _Hangup):
                raise DeviceDisconnected(f"{self.device}: connection lost ({item.error}); "
                                         "check the cable and power, then reconnect") from item.error
            if item == "OK PONG":
                self._desynced = False
                return
            log.info("%s: discarding %r while resynchronising", self.device, item)

    @property
    def alive(self) -> bool:
        return self._reader.is_alive()

    def close(self) -> None:
        """Stop the reader and close the port (idempotent)."""
        self._stop.set()
        try:
            self.port.close()
        except _PORT_ERRORS:
            pass
        if self._reader is not threading.current_thread():
            self._reader.join(timeout=1.0)
