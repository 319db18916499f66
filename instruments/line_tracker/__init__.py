"""The optical line-sensor direction detector of ``instruments.md`` §3 (``OLDT``).

``LineTracker`` is the plugin (driver), ``LineTrackerModel`` its simulator. The sensor, the OLDT
command set of one detector and what it sees of a tracking world are shared with the mirror gimbal
(one detector per axis): :mod:`mirrorlab.instruments.virtual_lab.line_sensor`.
"""

from .driver import LineTracker
from .model import LineTrackerModel

__all__ = ["LineTracker", "LineTrackerModel"]
