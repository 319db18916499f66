"""The session clock: one time base for every instrument of a session.

Device threads stamp samples with :func:`time.monotonic` converted to *session time* (seconds since
the session clock started), so instruments running at different rates share one time axis and a
wall-clock change (NTP step, daylight saving) never bends a recording.
"""

from __future__ import annotations

import time
from datetime import UTC, datetime


def utc_now_iso() -> str:
    """Current UTC time as ISO 8601 with a ``Z`` suffix (microsecond resolution)."""
    return datetime.now(UTC).strftime("%Y-%m-%dT%H:%M:%S.%fZ")


class SessionClock:
    """Monotonic seconds since :meth:`start`; ``utc_start`` records the matching wall time."""

    def __init__(self) -> None:
        self.start()

    def start(self) -> None:
        #: The :func:`time.monotonic` reading at session time 0 (system-wide on Linux).
        self.t0_monotonic = time.monotonic()
        self.utc_start = utc_now_iso()

    def now(self) -> float:
        """Session time in seconds."""
        return time.monotonic() - self.t0_monotonic

    def from_monotonic(self, t: float) -> float:
        """Convert a :func:`time.monotonic` reading to session time in seconds."""
        return t - self.t0_monotonic
