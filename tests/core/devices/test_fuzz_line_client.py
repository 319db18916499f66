"""Fuzz :class:`LineClient` with random device replies over a real TCP socket.

A query returns a well-formed reply or raises a typed :class:`MirrorlabError` within its timeout
(plus generous slack for a loaded machine), whatever bytes come back; the reader thread survives
them and stops when the client closes.
"""

from __future__ import annotations

import socket
import threading
import time

import pytest
from hypothesis import given
from hypothesis import strategies as st
from mirrorlab.core.devices import LineClient, open_port
from mirrorlab.core.errors import MirrorlabError

from tests.strategies import fuzz

TIMEOUT = 0.1
#: Lines a device might send, well-formed or not; joined with random separators and random bytes.
PIECES = st.sampled_from([b"OK", b"OK PONG", b"OK 1 2 3", b"ERR E01 unknown command", b"ERR", b"ERR E09 aborted",
                          b"DATA 1 2", b"L 0 ffff", b"!ERR E20 overheat", b"!EVT x", b"lower case", b"ok",
                          b"\x00\xff\xfe", b" OK", b"OK\r", b"", b"\x18", b"A" * 300])
REPLY = st.lists(st.one_of(PIECES, st.binary(max_size=40)), max_size=8).flatmap(
    lambda parts: st.tuples(st.just(parts), st.lists(st.sampled_from([b"\n", b"\r\n", b"", b"\r"]),
                                                     min_size=len(parts), max_size=len(parts))))


def serve_once(server: socket.socket, reply: bytes, hang_up: bool) -> None:
    """Accept one driver, answer its first command with ``reply``, then hang up or wait for it to leave."""
    conn, _ = server.accept()
    with conn:
        conn.settimeout(10.0)
        buf = b""
        while b"\n" not in buf:
            chunk = conn.recv(256)
            if not chunk:
                return
            buf += chunk
        conn.sendall(reply)
        if hang_up:
            return
        while conn.recv(256):  # until the driver closes
            pass


@pytest.mark.slow
@pytest.mark.timeout(120)
@fuzz(40)
@given(reply=REPLY, hang_up=st.booleans())
def test_any_reply_gives_a_reply_or_a_typed_error_in_time(reply: tuple[list[bytes], list[bytes]],
                                                          hang_up: bool) -> None:
    payload = b"".join(part + sep for part, sep in zip(*reply))
    with socket.create_server(("127.0.0.1", 0)) as server:
        device = threading.Thread(target=serve_once, args=(server, payload, hang_up), daemon=True)
        device.start()
        client = LineClient(open_port(f"socket://127.0.0.1:{server.getsockname()[1]}"), "fuzz device", TIMEOUT)
        try:
            start = time.monotonic()
            try:
                answer = client.query("*IDN?")
            except MirrorlabError as exc:
                assert "fuzz device" in str(exc)
            else:
                assert all(line[:1].isupper() and line.isprintable() for line in answer.data)
            assert time.monotonic() - start < TIMEOUT + 10.0, "query overran its timeout"
            assert client.alive or hang_up, "the reader thread died on the reply"
        finally:
            client.close()
        assert not client.alive
        device.join(timeout=10.0)
        assert not device.is_alive()
