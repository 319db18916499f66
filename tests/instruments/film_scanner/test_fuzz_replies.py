"""Fuzz the film scanner driver's reading of replies: random ``OK`` fields and data lines.

A device (a TCP socket here) that answers ``PING`` properly but anything else with random,
plausible-looking replies makes every driver operation return or raise a typed
:class:`MirrorlabError`: never a ``ValueError`` from parsing its fields.
"""

from __future__ import annotations

import socket
import threading

import pytest
from hypothesis import given
from hypothesis import strategies as st
from mirrorlab.core.errors import MirrorlabError
from mirrorlab.instruments.film_scanner import FilmScanner

from tests.strategies import fuzz

WORDS = st.sampled_from(["0", "12", "-3", "1.5", "nan", "x", "", "OK", "ffff", "1e99", "A" * 130, "0" * 128])
LINES = st.one_of(
    st.lists(WORDS, max_size=4).map(lambda w: " ".join(["OK", *w])),
    st.lists(WORDS, max_size=3).map(lambda w: " ".join(["L", *w])),
    st.lists(WORDS, max_size=3).map(lambda w: " ".join(["LINE", *w])),
    st.lists(WORDS, max_size=514).map(lambda w: " ".join(["GREY", *w])),
    st.just("ERR E11 no frame"),
)
OPERATIONS = {
    "home": lambda d: d.home(), "head": lambda d: d.head(), "scan": lambda d: d.scan(2),
    "line": lambda d: d.read_line(), "grey": lambda d: d.grey_profile(), "feed": lambda d: d.feed(1.0),
    "position": lambda d: d.position(),
}


def device(server: socket.socket, replies: list[str], stop: threading.Event) -> None:
    """Answer PING with ``OK PONG``, every other command with the next reply lines (then ``OK``)."""
    conn, _ = server.accept()
    with conn, conn.makefile("rwb", buffering=0) as io:
        pending = list(replies)
        while not stop.is_set():
            line = io.readline()
            if not line:
                return
            if line.strip() == b"PING":
                io.write(b"OK PONG\n")
            else:
                answer = pending[:3] if pending else ["OK"]
                del pending[:3]
                if not answer[-1].startswith(("OK", "ERR")):
                    answer.append("OK 1 1")
                io.write("".join(f"{a}\n" for a in answer).encode())


@pytest.mark.timeout(120)
@fuzz(25)
@given(operation=st.sampled_from(sorted(OPERATIONS)), replies=st.lists(LINES, min_size=1, max_size=6))
def test_driver_operations_raise_typed_errors_on_any_reply(operation: str, replies: list[str]) -> None:
    stop = threading.Event()
    with socket.create_server(("127.0.0.1", 0)) as server:
        thread = threading.Thread(target=device, args=(server, replies, stop), daemon=True)
        thread.start()
        dev = FilmScanner("cam", port=f"socket://127.0.0.1:{server.getsockname()[1]}", timeout=1.0)
        try:
            dev.connect()
            try:
                OPERATIONS[operation](dev)
            except MirrorlabError as exc:
                assert "cam" in str(exc) or "reply" in str(exc) or "line" in str(exc), str(exc)
        finally:
            stop.set()
            dev.close()
        thread.join(timeout=10.0)
        assert not thread.is_alive()
