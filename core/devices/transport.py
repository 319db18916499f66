"""Byte transports: the lowest of an instrument's three layers (transport, protocol, instrument).

The driver side opens any pyserial URL: a device path (``/dev/ttyUSB0``), a pseudo-terminal
created by a simulator, ``socket://127.0.0.1:PORT`` or ``loop://``. The simulator side serves a
byte endpoint (:class:`PtyEndpoint` or :class:`TcpEndpoint`) and injects transport faults
(:class:`TransportFaults`) into what it sends, so the real driver meets latency, dropped and
garbled bytes, stalls and disconnects through a real byte stream.
"""

from __future__ import annotations

import errno
import os
import random
import select
import socket
import termios
import threading
import time
import tty
from abc import ABC, abstractmethod
from collections import deque
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


#: The pyserial URL schemes a port may use without ``--allow-port-url``: byte streams to a device or
#: a simulator. pyserial has others (``spy://`` logs to any file it is given, ``alt://`` loads
#: another back end, ``hwgrep://`` opens whatever device matches), which a recipe from elsewhere
#: could use to write files or reach devices it does not name.
PORT_SCHEMES = ("socket", "loop", "rfc2217")


def port_problem(port: str) -> str | None:
    """Why ``port`` is refused without ``--allow-port-url`` (``None``: a device path or a plain URL).

    pyserial reads anything holding ``://`` as a URL, whatever its case, and anything else as a path.

    >>> port_problem("/dev/ttyUSB0") is None, port_problem("socket://127.0.0.1:5000") is None
    (True, True)
    >>> port_problem("spy://loop://?file=/tmp/x")
    "'spy://loop://?file=/tmp/x' is a pyserial URL of kind spy://: a port is a device path, socket://, \
loop:// or rfc2217://; add --allow-port-url to use another pyserial URL"
    """
    scheme, sep, _ = port.partition("://")
    if not sep or scheme.lower() in PORT_SCHEMES:
        return None
    return (f"{port!r} is a pyserial URL of kind {scheme}://: a port is a device path, "
            f"{', '.join(s + '://' for s in PORT_SCHEMES[:-1])} or {PORT_SCHEMES[-1]}://; "
            "add --allow-port-url to use another pyserial URL")


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
        if getattr(exc, "errno", None) in (errno.EMFILE, errno.ENFILE):  # not the device: this process or machine
            raise DeviceDisconnected(
                f"cannot open port {url!r}: too many files are open ({exc}); the device is not at fault: "
                "close other sessions or programs, or raise the limit of open files (`ulimit -n`)") from exc
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


#: The line a second client gets before it is closed: the simulator serves one client at a time.
BUSY_LINE = b"ERR E10 busy: another client is connected; try again when it has disconnected\n"
#: How often, s, a pty endpoint with no program on it looks for one (a hung-up pty cannot be waited on).
PTY_LOOK_S = 0.01
TCP_ESTABLISHED = 1   # tcpi_state of a connection neither end has closed (linux/tcp_states.h)


class Endpoint(ABC):
    """A simulator's byte endpoint: one client at a time, output sent by a writer thread.

    ``url`` is what a client opens. The serving thread calls :meth:`recv`, which also notices a
    client arriving or hanging up; :attr:`generation` counts those changes (and :meth:`disconnect`,
    the simulated unplug), so bytes read for one client are never taken as the next one's, and
    what was queued for a client that left is dropped. :meth:`send` only queues: the writer thread
    sends (through :attr:`faults`, and paced to :attr:`baud` bits/s of 8N1 if set), so a client that
    reads slowly never holds up the device; :attr:`backlog` is what waits.
    """

    url: str

    def __init__(self, seed: int = 0, baud: int | None = None) -> None:
        self.faults = TransportFaults()
        self.baud = baud
        self.generation = 0
        self._rng = random.Random(seed)
        self._closed = False
        self._queue: deque[tuple[int, bytes]] = deque()
        self._queued = 0
        self._wake = threading.Condition()    # the queue, its byte count, the generation
        self._io = threading.Lock()           # one write, or one change of client, at a time
        self._fd_lock = threading.Lock()      # held while the serving thread waits on a descriptor
        self._interrupt_r, self._interrupt_w = os.pipe()   # wakes that wait, so disconnect() is prompt
        os.set_blocking(self._interrupt_r, False)
        self._line_free = 0.0                 # monotonic time the paced line is free again
        self._writer = threading.Thread(target=self._write_loop, name="simulator output", daemon=True)
        self._writer.start()

    @property
    @abstractmethod
    def connected(self) -> bool:
        """Whether a client is connected (output to nobody is dropped)."""

    @property
    def backlog(self) -> int:
        """Bytes queued for the client and not sent yet."""
        return self._queued

    @abstractmethod
    def recv(self, timeout: float) -> tuple[int, bytes]:
        """Wait up to ``timeout`` s for the client's bytes: ``(generation they belong to, bytes)``, ``b""``
        when none came or no client is connected. Takes a client that arrives, refuses a second one
        (``ERR E10 busy``) and notices one that hangs up."""

    @abstractmethod
    def _write_some(self, data: memoryview) -> int | None:
        """Write what the client takes now without blocking: bytes written (0: try later), ``None`` if it is gone."""

    @abstractmethod
    def _wait_writable(self, timeout: float) -> None:
        """Wait up to ``timeout`` s until the client can take more bytes."""

    @abstractmethod
    def disconnect(self) -> None:
        """Drop the current client, as if the device were unplugged and plugged in again."""

    def send(self, data: bytes) -> None:
        """Queue ``data`` for the connected client; with none connected it is dropped (nobody listens)."""
        with self._wake:
            if self._closed or not self.connected:
                return
            self._queue.append((self.generation, data))
            self._queued += len(data)
            self._wake.notify()

    def close(self) -> None:
        """Stop serving: the client is hung up, the descriptors and the writer thread end (idempotent)."""
        with self._wake:
            self._closed = True
            self._wake.notify()
        self._interrupt()
        with self._fd_lock, self._io:
            self._release()
            for fd in (self._interrupt_r, self._interrupt_w):
                if fd >= 0:
                    os.close(fd)
            self._interrupt_r = self._interrupt_w = -1

    @abstractmethod
    def _release(self) -> None:
        """Close the endpoint's descriptors (both locks held)."""

    def _new_generation(self) -> None:
        """A client came or went (``_io`` held): what was queued for the previous one is dropped."""
        with self._wake:
            self.generation += 1
            self._queue.clear()
            self._queued = 0

    def _interrupt(self) -> None:
        try:
            os.write(self._interrupt_w, b"\0")
        except OSError:
            pass  # closed, or already full of wake-ups

    def _drain_interrupts(self) -> None:
        try:
            while os.read(self._interrupt_r, 64):
                pass
        except OSError:
            pass  # empty (or closed)

    def _write_loop(self) -> None:
        while True:
            with self._wake:
                while not self._queue and not self._closed:
                    self._wake.wait()
                if self._closed:
                    return
                generation, data = self._queue.popleft()    # counted in the backlog until written
            self._deliver(generation, data)
            with self._wake:
                if generation == self.generation:
                    self._queued -= len(data)

    def _deliver(self, generation: int, data: bytes) -> None:
        f = self.faults
        while f.stall and not self._closed and generation == self.generation:
            time.sleep(0.01)
        if f.latency:
            time.sleep(f.latency)
        view = memoryview(f.apply(data, self._rng))
        # Paced, the line carries 10 bits a byte (8N1): chunks of 10 ms of the line, each sent when it is free.
        chunk = max(1, self.baud // 1000) if self.baud else len(view)
        while view:
            if self.baud and (wait := self._line_free - time.monotonic()) > 0:
                time.sleep(wait)
            with self._io:
                if generation != self.generation or self._closed:
                    return   # the client left: the rest was for it alone
                n = self._write_some(view[:chunk])
            if n is None:
                return       # it hung up: recv() notices
            if not n:
                self._wait_writable(0.02)
                continue
            view = view[n:]
            if self.baud:
                self._line_free = max(self._line_free, time.monotonic()) + n * 10.0 / self.baud


class PtyEndpoint(Endpoint):
    """A pseudo-terminal pair; the client opens :attr:`url`, a stable symlink to the pty slave.

    A real device re-enumerates with a new ``/dev/pts`` number after an unplug; the symlink (like a
    udev ``/dev/serial/by-id`` link) keeps the path the recipe names valid across reconnects.

    A client is whatever program has the slave open: the first open after every program closed it
    starts a new one (the simulator holds no descriptor of the slave, so it sees the hang-up). As on
    a serial port, two programs that hold it open at once cannot be told apart.
    """

    def __init__(self, link: Path, seed: int = 0, baud: int | None = None) -> None:
        super().__init__(seed, baud)
        self.link = Path(link)
        self.url = str(self.link)
        self._master = -1
        self._slave_path = ""
        self._client = False
        self._open_pty()

    def _open_pty(self) -> None:
        master, slave = os.openpty()
        tty.setraw(slave)   # no echo, no line discipline: bytes pass unchanged (the pty keeps the setting)
        self._slave_path = os.ttyname(slave)
        os.close(slave)
        os.set_blocking(master, False)
        self._master = master
        tmp = self.link.with_name(self.link.name + ".new")
        tmp.unlink(missing_ok=True)
        tmp.symlink_to(self._slave_path)
        os.replace(tmp, self.link)

    @property
    def connected(self) -> bool:
        return self._client

    def recv(self, timeout: float) -> tuple[int, bytes]:
        data = b""
        with self._fd_lock:
            generation, master = self.generation, self._master
            if master >= 0:
                poll = select.poll()
                poll.register(master, select.POLLIN)
                poll.register(self._interrupt_r, select.POLLIN)
                # With no program on the slave the master reports a hang-up at once: look, do not wait.
                events = dict(poll.poll(1000.0 * timeout if self._client else 0))
                self._drain_interrupts()
                event = events.get(master, 0)
                hung_up = bool(event & (select.POLLHUP | select.POLLERR))
                if event & select.POLLIN:
                    try:
                        data = os.read(master, 4096)
                    except OSError:
                        data = b""   # EIO: nobody has the slave open
                if (data or not hung_up) and not self._client:
                    self._connect()   # (a program that wrote and closed between two looks was a client too)
                    generation = self.generation
                elif hung_up and not data and self._client:
                    self._hang_up()
        if not self._client:
            time.sleep(min(timeout, PTY_LOOK_S))
        return generation, data

    def _connect(self) -> None:
        with self._io:
            self._client = True
            self._new_generation()

    def _hang_up(self) -> None:
        """Every program closed the slave: forget the client, and what it left unread in the pty."""
        with self._io:
            self._client = False
            self._new_generation()
            try:
                fd = os.open(self._slave_path, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
            except OSError:
                return
            try:
                termios.tcflush(fd, termios.TCIOFLUSH)
            finally:
                os.close(fd)

    def _write_some(self, data: memoryview) -> int | None:
        if self._master < 0:
            return None
        try:
            return os.write(self._master, data)
        except BlockingIOError:
            return 0
        except OSError:
            return None

    def _wait_writable(self, timeout: float) -> None:
        try:
            select.select([], [self._master], [], timeout)
        except (OSError, ValueError):
            time.sleep(timeout)

    def disconnect(self) -> None:
        # Closing the master hangs up the client; a fresh pty replaces it behind the same link, and
        # first: a driver that reopens the link the moment it is hung up must find the new pty, not
        # the old one's slave path (which no longer opens).
        self._interrupt()
        with self._fd_lock, self._io:
            old, self._master = self._master, -1
            if not self._closed:
                self._open_pty()
            if old >= 0:
                os.close(old)
            self._client = False
            self._new_generation()

    def close(self) -> None:
        super().close()
        self.link.unlink(missing_ok=True)

    def _release(self) -> None:
        self._close_master()

    def _close_master(self) -> None:
        if self._master >= 0:
            os.close(self._master)
        self._master = -1


class TcpEndpoint(Endpoint):
    """A TCP server; the client opens ``socket://HOST:PORT``. One client at a time: another that
    connects meanwhile gets :data:`BUSY_LINE` and is closed.

    ``host`` is the interface listened on: the loopback interface unless another is asked for
    (``0.0.0.0`` is every IPv4 interface; the protocol has no authentication).
    """

    def __init__(self, host: str = "127.0.0.1", port: int = 0, seed: int = 0, baud: int | None = None) -> None:
        family = socket.AF_INET6 if ":" in host else socket.AF_INET
        self._server = socket.create_server((host, port), family=family)
        self._server.setblocking(False)
        super().__init__(seed, baud)
        self.port = self._server.getsockname()[1]
        self.url = f"socket://{f'[{host}]' if family == socket.AF_INET6 else host}:{self.port}"
        self._conn: socket.socket | None = None

    @property
    def connected(self) -> bool:
        return self._conn is not None

    def recv(self, timeout: float) -> tuple[int, bytes]:
        data = b""
        with self._fd_lock:
            generation, conn = self.generation, self._conn
            watched: list[socket.socket | int] = [self._server, self._interrupt_r, *([conn] if conn is not None else [])]
            try:
                ready, _, _ = select.select(watched, [], [], timeout)
            except (OSError, ValueError):   # closed meanwhile
                return generation, b""
            self._drain_interrupts()
            if conn is not None and conn in ready:
                try:
                    data = conn.recv(4096)
                except (OSError, ValueError):
                    data = b""
                if not data:
                    self._hang_up(conn)
            if self._server in ready:
                self._accept()
        return generation, data

    def _accept(self) -> None:
        try:
            new, _ = self._server.accept()
        except (OSError, ValueError):
            return
        current = self._conn
        if current is not None and not _alive(current):
            self._hang_up(current)   # gone without a word yet: the newcomer is not a second client
            current = None
        if current is not None:
            _refuse(new)
            return
        new.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        with self._io:
            self._conn = new
            self._new_generation()

    def _hang_up(self, conn: socket.socket) -> None:
        with self._io:
            if self._conn is conn:
                self._conn = None
                self._new_generation()
        conn.close()

    def _write_some(self, data: memoryview) -> int | None:
        conn = self._conn
        if conn is None:
            return None
        try:
            return conn.send(data, socket.MSG_DONTWAIT)
        except BlockingIOError:
            return 0
        except (OSError, ValueError):
            return None

    def _wait_writable(self, timeout: float) -> None:
        conn = self._conn
        try:
            select.select([], [conn] if conn is not None else [], [], timeout)
        except (OSError, ValueError):
            time.sleep(timeout)

    def disconnect(self) -> None:
        self._interrupt()
        with self._fd_lock, self._io:
            conn, self._conn = self._conn, None
            if conn is None:
                return
            self._new_generation()
        try:
            conn.shutdown(socket.SHUT_RDWR)
        except OSError:
            pass
        conn.close()

    def _release(self) -> None:
        conn, self._conn = self._conn, None
        for sock in (conn, self._server):
            if sock is not None:
                sock.close()


def _alive(conn: socket.socket) -> bool:
    """Whether the peer of ``conn`` is still there: it has not closed its end, even with bytes of it unread."""
    try:
        if hasattr(socket, "TCP_INFO"):   # Linux: the connection's state, whatever waits in it
            return conn.getsockopt(socket.IPPROTO_TCP, socket.TCP_INFO, 1)[0] == TCP_ESTABLISHED
        return conn.recv(1, socket.MSG_PEEK | socket.MSG_DONTWAIT) != b""
    except BlockingIOError:
        return True
    except (OSError, ValueError):
        return False


def _refuse(conn: socket.socket) -> None:
    """Tell a second client the simulator is busy, and close it."""
    try:
        conn.setblocking(False)
        conn.sendall(BUSY_LINE)
        conn.shutdown(socket.SHUT_WR)
        conn.recv(65536)   # what it sent already: closing with unread input would reset the connection first
    except OSError:
        pass
    conn.close()
