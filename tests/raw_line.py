"""A client that talks to a served simulator in raw bytes, as a lab's own program would: a plain TCP socket
or the pty opened as a file, no mirrorlab driver in between (so nothing is parsed, escaped or retried)."""

from __future__ import annotations

import os
import select
import socket
import time

WAIT = 10.0  # s: only turns a hang into a failure


class RawClient:
    """One connection to ``url`` (``socket://HOST:PORT`` or a pty path): bytes out, lines in."""

    def __init__(self, url: str) -> None:
        if url.startswith("socket://"):
            host, _, port = url[len("socket://"):].rpartition(":")
            self.sock: socket.socket | None = socket.create_connection((host.strip("[]"), int(port)), timeout=WAIT)
            self.fd = self.sock.fileno()
        else:
            self.sock = None
            self.fd = os.open(url, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
        self.buffer = b""

    def send(self, data: bytes) -> None:
        if self.sock is not None:
            self.sock.sendall(data)
            return
        view = memoryview(data)
        while view:
            select.select([], [self.fd], [], WAIT)
            view = view[os.write(self.fd, view):]

    def read_some(self, timeout: float) -> bytes:
        """What arrives within ``timeout`` s (``b""`` if nothing); raises EOFError once the other end closed."""
        ready, _, _ = select.select([self.fd], [], [], timeout)
        if not ready:
            return b""
        try:
            data = self.sock.recv(65536) if self.sock is not None else os.read(self.fd, 65536)
        except (BlockingIOError, InterruptedError):
            return b""
        except OSError:   # a pty whose simulator hung up: EIO
            data = b""
        if not data:
            raise EOFError("the simulator closed the connection")
        return data

    def line(self, timeout: float = WAIT) -> str:
        """The next line (without its LF), decoded as ASCII (a non-ASCII byte fails the test)."""
        deadline = time.monotonic() + timeout
        while b"\n" not in self.buffer:
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                raise TimeoutError(f"no line within {timeout:g} s; received so far {self.buffer[:200]!r}")
            self.buffer += self.read_some(remaining)
        raw, _, self.buffer = self.buffer.partition(b"\n")
        return raw.decode("ascii")

    def reply(self, timeout: float = WAIT) -> list[str]:
        """The lines up to the next terminal line (``OK…`` / ``ERR…``), unsolicited ``!`` lines left out."""
        lines: list[str] = []
        while True:
            line = self.line(timeout)
            if line.startswith("!"):
                continue
            lines.append(line)
            if line == "OK" or line.startswith(("OK ", "ERR ")):
                return lines

    def ask(self, command: bytes | str, timeout: float = WAIT) -> list[str]:
        """Send one command line and return its reply lines."""
        self.send((command.encode("ascii") if isinstance(command, str) else command) + b"\n")
        return self.reply(timeout)

    def close(self) -> None:
        if self.sock is not None:
            self.sock.close()
        else:
            os.close(self.fd)

    def __enter__(self) -> RawClient:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
