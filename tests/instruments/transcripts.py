"""Transcripts in the instrument docs, and a scripted device that serves one on a real pty.

A transcript is a plain fenced block of lines ``> command`` (host to device), ``< reply`` (device
to host) and ``… N ms`` (time passing). :func:`replay_on_model` checks a simulator against it in
process, :func:`replay_on_server` over a real connection in raw bytes; :class:`ScriptedDevice`
plays the device side byte for byte to a real driver, so the driver's wire format is pinned
independently of the simulator (:func:`scripted_driver` connects one to it and checks the whole
script was played).
"""

from __future__ import annotations

import os
import re
import select
import threading
import tty
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from pathlib import Path
from typing import Any, TypeVar

from mirrorlab.core.devices import Instrument
from mirrorlab.core.devices.simulator import LineSimulator

from tests.raw_line import RawClient
from tests.support import REPO
from tests.test_docs import blocks

WAIT = re.compile(r"^… (\d+) ms$")
I = TypeVar("I", bound=Instrument)


def transcripts(doc: str) -> list[list[str]]:
    """The transcript blocks (plain fenced blocks starting with ``> ``) of ``docs/instruments/<doc>``."""
    found = blocks(REPO / "docs" / "instruments" / doc)
    return [b.text.splitlines() for b in found if b.lang == "" and b.text.startswith("> ")]


def replay_on_model(model: LineSimulator, lines: list[str]) -> None:
    """Run every ``>`` command on ``model`` and assert its reply lines are exactly the ``<`` lines.

    After ``… N ms`` the model advances and the ``<`` lines that follow are the stream lines it sent
    meanwhile (none if none follow).
    """
    expected: list[str] = []
    command = None                                # None: the lines after a wait are stream lines

    def check() -> None:
        got = model.execute(command) if command is not None else model.stream_lines()
        assert got == expected, f"{command or 'stream'!r}: got {got}, transcript says {expected}"

    for n, line in enumerate(lines):
        if line.startswith("> "):
            if n:
                check()
            command, expected = line[2:], []
        elif line.startswith("< "):
            expected.append(line[2:])
        elif m := WAIT.match(line):
            check()
            command, expected = None, []
            model.advance(int(m[1]) / 1000.0)
        else:
            raise AssertionError(f"not a transcript line: {line!r}")
    check()


class ScriptedDevice:
    """Serve the device side of a transcript on a pty; records any deviation of the host's bytes."""

    def __init__(self, lines: list[str]) -> None:
        self.steps: list[tuple[bytes, bytes]] = []
        for line in lines:
            if line.startswith("> "):
                self.steps.append(((line[2:] + "\n").encode("ascii"), b""))
            elif line.startswith("< "):
                sent, reply = self.steps[-1]
                self.steps[-1] = (sent, reply + (line[2:] + "\n").encode("ascii"))
        self.master, slave = os.openpty()
        tty.setraw(slave)
        self.path = Path(os.ttyname(slave))
        self._slave = slave
        self.error: str | None = None
        self.done = threading.Event()
        self._thread = threading.Thread(target=self._serve, daemon=True)
        self._thread.start()

    def _serve(self) -> None:
        buffer = b""
        for n, (expected, reply) in enumerate(self.steps):
            while b"\n" not in buffer:
                ready, _, _ = select.select([self.master], [], [], 10.0)
                if not ready:
                    self.error = f"step {n}: host sent nothing, expected {expected!r}"
                    return
                buffer += os.read(self.master, 4096)
            line, _, buffer = buffer.partition(b"\n")
            sent = line + b"\n"
            if sent != expected:
                self.error = f"step {n}: host sent {sent!r}, transcript says {expected!r}"
                os.write(self.master, b"ERR E01 not in the transcript\n")
                return
            os.write(self.master, reply)
        self.done.set()

    def close(self) -> None:
        os.close(self.master)
        os.close(self._slave)


@contextmanager
def scripted_driver(script: list[str], cls: type[I], label: str,
                    settings: Mapping[str, Any] | None = None) -> Iterator[I]:
    """The driver ``cls`` connected, identified and configured to a :class:`ScriptedDevice` playing ``script``.

    On leaving the block the driver and the device are closed, and the device must have seen exactly
    the script's bytes, all of them.
    """
    device = ScriptedDevice(script)
    try:
        inst = cls(label, port=str(device.path), settings=settings, timeout=2.0)
        inst.connect()
        inst.identify()
        inst.configure()
        yield inst
        inst.close()
    finally:
        device.close()
    assert device.error is None, device.error
    assert device.done.is_set()


def _sent_bytes(line: str) -> bytes:
    r"""The bytes of a ``>`` line: ``>`` alone is an empty line, ``\xNN`` one byte."""
    text = line[2:] if line.startswith("> ") else ""
    return re.sub(rb"\\x([0-9a-f]{2})", lambda m: bytes([int(m[1], 16)]), text.encode("ascii")) + b"\n"


def replay_on_server(url: str, lines: list[str]) -> None:
    r"""Send every ``>`` line's bytes to a served simulator (``>`` alone: an empty line; ``\xNN``: one byte) and
    assert it answers exactly the ``<`` lines after it, byte for byte, and nothing else (a ``PING`` after the
    last must be answered next)."""
    steps: list[tuple[bytes, list[str]]] = []
    for line in lines:
        if line == ">" or line.startswith("> "):
            steps.append((_sent_bytes(line), []))
        elif line.startswith("< "):
            steps[-1][1].append(line[2:])
        else:
            raise AssertionError(f"not a transcript line: {line!r}")
    with RawClient(url) as client:
        for sent, expected in steps:
            client.send(sent)
            got = [client.line() for _ in expected]
            assert got == expected, f"{sent!r}: got {got}, transcript says {expected}"
        assert client.ask("PING") == ["OK PONG"]
