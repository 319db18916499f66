"""The session clock: one time base for every instrument, the log and the controllers of a session.

*Session time* is seconds since the session's clock origin, a UTC instant stored in the file
(root attribute ``clock_origin_utc``, schema 2). Within one opening of the file, time advances
with :func:`time.monotonic`, so instruments running at different rates share one time axis and a
wall-clock change (NTP step, daylight saving) never bends a recording. When a file is opened
again, the clock continues on the same axis: the offset since the origin is taken from the wall
clock once, at opening.
"""

from __future__ import annotations

import time
from datetime import UTC, datetime

ISO_FORMAT = "%Y-%m-%dT%H:%M:%S.%fZ"


def utc_now_iso() -> str:
    """Current UTC time as ISO 8601 with a ``Z`` suffix (microsecond resolution)."""
    return datetime.now(UTC).strftime(ISO_FORMAT)


def parse_utc(text: str) -> datetime:
    """The UTC instant of an ISO 8601 text as :func:`utc_now_iso` writes it.

    >>> parse_utc("2026-11-23T21:42:24.500000Z").isoformat()
    '2026-11-23T21:42:24.500000+00:00'
    """
    return datetime.strptime(text, ISO_FORMAT).replace(tzinfo=UTC)


class SessionClock:
    """Seconds since ``origin`` (a UTC instant), advancing with :func:`time.monotonic`.

    Parameters
    ----------
    origin
        Session time 0 as an aware UTC :class:`~datetime.datetime`; ``None`` starts the clock now.
        An origin in the past continues that time axis: ``now()`` starts at the wall-clock seconds
        elapsed since it (a reopened session).

    Examples
    --------
    >>> from datetime import timedelta
    >>> clock = SessionClock(datetime.now(UTC) - timedelta(seconds=100))
    >>> 100.0 <= clock.now() < 110.0
    True
    """

    def __init__(self, origin: datetime | None = None) -> None:
        now = datetime.now(UTC)
        #: Session time 0 (UTC), stored in the file as ``clock_origin_utc``.
        self.origin = origin or now
        #: The :func:`time.monotonic` reading at session time 0 (system-wide on Linux).
        self.t0_monotonic = time.monotonic() - (now - self.origin).total_seconds()

    def now(self) -> float:
        """Session time in seconds."""
        return time.monotonic() - self.t0_monotonic

    def from_monotonic(self, t: float) -> float:
        """Convert a :func:`time.monotonic` reading to session time in seconds."""
        return t - self.t0_monotonic
