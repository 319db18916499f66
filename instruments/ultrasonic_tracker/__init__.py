"""The ultrasonic direction tracker of ``instruments.md`` §2 (``USDF``).

``UltrasonicTracker`` is the plugin (driver), ``UltrasonicTrackerModel`` its simulator;
:mod:`.acoustics` (directivity, steering, timing), :mod:`.echoes` (echo pressures, identification)
and :mod:`.search` (the gradient search 4.4-4.8) are pure functions.
"""

from .driver import UltrasonicTracker
from .model import UltrasonicTrackerModel

__all__ = ["UltrasonicTracker", "UltrasonicTrackerModel"]
