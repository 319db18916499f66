"""Damage to real files, as hypothesis strategies: cut at a random offset, or a few bits flipped."""

from __future__ import annotations

from hypothesis import HealthCheck, settings
from hypothesis import strategies as st


def fuzz(examples: int) -> settings:
    """Settings of a fuzz test: ``examples`` chosen so that the whole fuzz suite stays well under a
    minute on a loaded 2-core machine; no deadline (a loaded machine is slow, hangs are caught by
    pytest-timeout)."""
    return settings(max_examples=examples, deadline=None,
                    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])


@st.composite
def damaged(draw: st.DrawFn, data: bytes, hot: int = 0) -> bytes:
    """``data`` cut at a random offset, or with 1-8 bits flipped (half of them in the first ``hot`` bytes)."""
    if draw(st.booleans()):
        return data[: draw(st.integers(0, len(data) - 1))]
    out = bytearray(data)
    for _ in range(draw(st.integers(1, 8))):
        limit = hot if hot and draw(st.booleans()) else len(out)
        i = draw(st.integers(0, limit - 1))
        out[i] ^= 1 << draw(st.integers(0, 7))
    return bytes(out)
