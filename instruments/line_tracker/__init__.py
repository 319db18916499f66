"""The optical line-sensor direction detector of ``instruments.md`` §3 (``OLDT``).

``LineTracker`` is the plugin (driver), ``LineTrackerModel`` its simulator. Pure functions:
:mod:`.sensor` (pixel geometry, summing projection, video signal, runs, adaptive threshold) and
:mod:`.view` (what a detector sees of a tracking world, the optical faults); :mod:`.detector` is the
OLDT command set of one detector, used here and once per axis by the mirror gimbal.
"""

from .driver import LineTracker
from .model import LineTrackerModel

__all__ = ["LineTracker", "LineTrackerModel"]
