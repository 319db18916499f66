"""Frame-to-frame marker tracking (spec analysis.md §2): thesis nearest neighbour and predictive assignment."""

from .errors import InvalidDetections, TrackingError
from .track import Tracks, track

__all__ = ["InvalidDetections", "Tracks", "TrackingError", "track"]
