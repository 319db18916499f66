"""Wire encoding shared by the FSCAN model and driver (``instruments.md`` §1.5).

A binary line is 512 pixels packed into 64 bytes, most significant bit = lowest pixel index,
written as 128 upper-case hex digits (the order in which the 6502 ``CCDIN`` routine shifts the
comparator bits into memory).
"""

from __future__ import annotations

import numpy as np
from mirrorlab.core import ProtocolError

PIXELS = 512
HEX_DIGITS = PIXELS // 4


def encode_bits(bits: np.ndarray) -> str:
    """Pack 512 booleans (pixel 0 first) into 128 upper-case hex digits."""
    return np.packbits(np.asarray(bits, dtype=bool)).tobytes().hex().upper()


def decode_bits(text: str) -> np.ndarray:
    """Unpack 128 hex digits into a ``(512,)`` uint8 array of 0/1.

    Raises
    ------
    ProtocolError
        The text is not 128 hex digits (a garbled line).
    """
    if len(text) != HEX_DIGITS:
        raise ProtocolError(f"binary line has {len(text)} hex digits, expected {HEX_DIGITS}")
    try:
        raw = bytes.fromhex(text)
    except ValueError:
        raise ProtocolError(f"binary line is not hex: {text[:20]!r}...") from None
    return np.unpackbits(np.frombuffer(raw, dtype=np.uint8))


def parse_data_line(line: str, tag: str) -> tuple[int, np.ndarray]:
    """Parse ``<tag> <index> <128 hex>`` (``L`` from ``SCAN``, ``LINE`` from ``LINE?``)."""
    parts = line.split(" ")
    if len(parts) != 3 or parts[0] != tag:
        raise ProtocolError(f"expected '{tag} <n> <hex>', got {line[:40]!r}")
    try:
        index = int(parts[1])
    except ValueError:
        raise ProtocolError(f"bad line index in {line[:40]!r}") from None
    return index, decode_bits(parts[2])
