"""Byte transports: the lowest of an instrument's three layers (transport, protocol, instrument).

The driver side opens any pyserial URL: a device path (``/dev/ttyUSB0``), a pseudo-terminal
created by a simulator, ``socket://127.0.0.1:PORT`` or ``loop://``. The simulator side serves a
byte endpoint (:class:`PtyEndpoint` or :class:`TcpEndpoint`) and injects transport faults
(:class:`TransportFaults`) into what it sends, so the real driver meets latency, dropped and
garbled bytes, stalls and disconnects through a real byte stream.
"""

from __future__ import annotations

import os
import random
import select
import socket
import threading
import time
import tty
from abc import ABC, abstractmethod
from dataclasses import dataclass
from pathlib import Path
from typing import Protocol, cast

import serial

from ..errors import DeviceDisconnected


class SerialPort(Protocol):
    """What a driver uses of an open port (:func:`open_port`), in bytes. Every pyserial back end has
    it (a tty, ``socket://``, ``loop://``), though pyserial's base class declares no ``in_waiting``."""

    @property
    def in_waiting(self) -> int:
        """Bytes received and not read yet."""
        ...

    def read(self, size: int = 1, /) -> bytes:
        """Up to ``size`` bytes; fewer (or none) when the port's read timeout passes first."""
        ...

    def write(self, data: bytes, /) -> int | None:
        """Queue ``data`` for sending."""
        ...

    def flush(self) -> None:
        """Wait until everything written has been sent."""
        ...

    def close(self) -> None:
        """Close the port (idempotent)."""
        ...


def open_port(url: str, baudrate: int = 115200, timeout: float = 0.05) -> SerialPort:
    """Open a pyserial URL or device path for a driver.

    Raises
    ------
    DeviceDisconnected
        The port does not exist or cannot be opened; the message says what to check.
    """
    try:
        return cast(SerialPort, serial.serial_for_url(url, baudrate=baudrate, timeout=timeout, write_timeout=2.0))
    except (serial.SerialException, OSError, ValueError) as exc:
        raise DeviceDisconnected(
            f"cannot open port {url!r}: {exc}. Check that the device is plugged in and powered, "
            "that the path or URL is right (`python -m serial.tools.list_ports` lists ports) "
            "and that no other program holds it."
        ) from exc


@dataclass
class TransportFaults:
    """Faults applied by a simulator endpoint to the bytes it sends.

    Attributes
    ----------
    latency
        Delay in seconds before each write.
    drop
        Probability that a byte is dropped.
    garble
        Probability that a byte is replaced by a random non-ASCII byte.
    stall
        While ``True`` nothing is sent or answered (the device hangs).
    """

    latency: float = 0.0
    drop: float = 0.0
    garble: float = 0.0
    stall: bool = False

    def apply(self, data: bytes, rng: random.Random) -> bytes:
        if not (self.drop or self.garble):
            return data
        out = bytearray()
        for b in data:
            r = rng.random()
            if r < self.drop:
                continue
            if r < self.drop + self.garble:
                out.append(rng.randrange(0x80, 0x100))
            else:
                out.append(b)
        return bytes(out)


class Endpoint(ABC):
    """A simulator's byte endpoint; subclasses provide :meth:`_accept`, :meth:`_recv`, :meth:`_send`.

    ``url`` is what a driver opens. :meth:`disconnect` drops the current connection (the driver sees
    a hang-up); the endpoint then accepts a new one, as a device that is unplugged and plugged in
    again.
    """

    url: str

    def __init__(self, seed: int = 0) -> None:
        self.faults = TransportFaults()
        self._rng = random.Random(seed)
        self._closed = False

    @abstractmethod
    def wait_connection(self, stop: threading.Event) -> bool:
        """Block until a driver is connected (or ``stop`` is set); True when connected."""
        ...

    @abstractmethod
    def recv(self, timeout: float) -> bytes | None:
        """Bytes from the driver (possibly ``b""`` on timeout); ``None`` once the driver hung up."""
        ...

    @abstractmethod
    def _send_raw(self, data: bytes) -> None:
        ...

    def send(self, data: bytes) -> None:
        f = self.faults
        while f.stall and not self._closed:
            time.sleep(0.01)
        if f.latency:
            time.sleep(f.latency)
        self._send_raw(f.apply(data, self._rng))

    @abstractmethod
    def disconnect(self) -> None:
        ...

    def close(self) -> None:
        self._closed = True


class PtyEndpoint(Endpoint):
    """A pseudo-terminal pair; the driver opens :attr:`url`, a stable symlink to the pty slave.

    A real device re-enumerates with a new ``/dev/pts`` number after an unplug; the symlink (like a
    udev ``/dev/serial/by-id`` link) keeps the path the recipe names valid across reconnects.
    """

    def __init__(self, link: Path, seed: int = 0) -> None:
        super().__init__(seed)
        self.link = Path(link)
        self.url = str(self.link)
        self._master = -1
        self._slave = -1
        # recv() runs in the serving thread outside the server's lock; disconnect() swaps the pty from
        # another thread. Without this lock recv() could select on a closed descriptor (the serving
        # thread died with EBADF) or on its number reused by the driver's reopened slave.
        self._fd_lock = threading.Lock()
        self._open_pty()

    def _open_pty(self) -> None:
        self._master, self._slave = os.openpty()
        tty.setraw(self._slave)  # no echo, no line discipline: bytes pass unchanged
        tmp = self.link.with_name(self.link.name + ".new")
        tmp.unlink(missing_ok=True)
        tmp.symlink_to(os.ttyname(self._slave))
        os.replace(tmp, self.link)

    def wait_connection(self, stop: threading.Event) -> bool:
        return not stop.is_set()

    def recv(self, timeout: float) -> bytes | None:
        with self._fd_lock:
            if self._master < 0:
                return None
            ready, _, _ = select.select([self._master], [], [], timeout)
            if not ready:
                return b""
            try:
                return os.read(self._master, 4096)
            except OSError:
                return b""  # no driver has the slave open right now: nothing to read

    def _send_raw(self, data: bytes) -> None:
        view = memoryview(data)
        while view and self._master >= 0:
            try:
                n = os.write(self._master, view)
            except BlockingIOError:
                time.sleep(0.001)
                continue
            except OSError:
                return
            view = view[n:]

    def disconnect(self) -> None:
        # Closing both ends hangs up the driver; a fresh pty replaces it behind the same link.
        with self._fd_lock:
            self._close_fds()
            if not self._closed:
                self._open_pty()

    def close(self) -> None:
        super().close()
        with self._fd_lock:
            self._close_fds()
        self.link.unlink(missing_ok=True)

    def _close_fds(self) -> None:
        for fd in (self._master, self._slave):
            if fd >= 0:
                os.close(fd)
        self._master = self._slave = -1


class TcpEndpoint(Endpoint):
    """A TCP server on the loopback interface; the driver opens ``socket://127.0.0.1:PORT``."""

    def __init__(self, host: str = "127.0.0.1", port: int = 0, seed: int = 0) -> None:
        super().__init__(seed)
        self._server = socket.create_server((host, port))
        self._server.settimeout(0.05)
        self.port = self._server.getsockname()[1]
        self.url = f"socket://{host}:{self.port}"
        self._conn: socket.socket | None = None

    def wait_connection(self, stop: threading.Event) -> bool:
        while not stop.is_set():
            try:
                conn, _ = self._server.accept()
            except TimeoutError:
                continue
            except OSError:
                return False
            conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            self._conn = conn
            return True
        return False

    def recv(self, timeout: float) -> bytes | None:
        conn = self._conn
        if conn is None:
            return None
        try:  # disconnect() may close the socket meanwhile (fileno -1: ValueError): a hang-up
            ready, _, _ = select.select([conn], [], [], timeout)
            if not ready:
                return b""
            data = conn.recv(4096)
        except (OSError, ValueError):
            return None
        return data if data else None

    def _send_raw(self, data: bytes) -> None:
        if self._conn is not None:
            try:
                self._conn.sendall(data)
            except OSError:
                pass  # the driver hung up; recv() reports it

    def disconnect(self) -> None:
        conn, self._conn = self._conn, None  # the serving thread may hang up at the same time
        if conn is not None:
            try:
                conn.shutdown(socket.SHUT_RDWR)
            except OSError:
                pass
            conn.close()

    def close(self) -> None:
        super().close()
        self.disconnect()
        self._server.close()
