"""Binary lines on the wire: a line of bits packed into bytes and written as upper-case hex digits.

The bit of pixel 0 is the most significant bit of the first byte (the order in which the FSCAN's
6502 ``CCDIN`` routine shifts the comparator bits into memory, ``instruments.md`` §1.5); a data
line reads ``<tag> <index> <hex>``. Used by the film scanner (``LINE``, ``L``) and the line-sensor
detectors (``F`` of ``FRAME?``), with the number of bits of their sensor.
"""

from __future__ import annotations

import numpy as np

from ..errors import ProtocolError

__all__ = ["decode_bits", "encode_bits", "parse_data_line"]


def encode_bits(bits: np.ndarray) -> str:
    """Pack booleans (pixel 0 first; a multiple of 8) into upper-case hex digits, 4 bits per digit.

    Examples
    --------
    >>> encode_bits(np.array([1, 0, 0, 0, 0, 0, 0, 1] + [0] * 8, bool))
    '8100'
    """
    return np.packbits(np.asarray(bits, dtype=bool)).tobytes().hex().upper()


def decode_bits(text: str, n_bits: int) -> np.ndarray:
    """Unpack the hex digits of a line of ``n_bits`` bits into a ``(n_bits,)`` uint8 array of 0/1.

    Raises
    ------
    ProtocolError
        The text is not ``n_bits / 4`` hex digits (a garbled line).

    Examples
    --------
    >>> decode_bits("8100", 16).tolist()
    [1, 0, 0, 0, 0, 0, 0, 1, 0, 0, 0, 0, 0, 0, 0, 0]
    """
    digits = n_bits // 4
    if len(text) != digits:
        raise ProtocolError(f"binary line has {len(text)} hex digits, expected {digits}")
    try:
        raw = bytes.fromhex(text)
    except ValueError:
        raise ProtocolError(f"binary line is not hex: {text[:20]!r}...") from None
    return np.unpackbits(np.frombuffer(raw, dtype=np.uint8))


def parse_data_line(line: str, tag: str, n_bits: int) -> tuple[int, np.ndarray]:
    """Parse ``<tag> <index> <hex>`` of a line of ``n_bits`` bits (e.g. ``L`` from ``SCAN``).

    Raises
    ------
    ProtocolError
        Another tag, a bad index or a garbled line of bits.
    """
    parts = line.split(" ")
    if len(parts) != 3 or parts[0] != tag:
        raise ProtocolError(f"expected '{tag} <n> <hex>', got {line[:40]!r}")
    try:
        index = int(parts[1])
    except ValueError:
        raise ProtocolError(f"bad line index in {line[:40]!r}") from None
    return index, decode_bits(parts[2], n_bits)
