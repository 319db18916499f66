"""The mirror gimbal instrument: the active mirror of ``instruments.md`` §4 (``MGIM``).

``MirrorGimbal`` is the plugin (driver), ``MirrorGimbalModel`` its simulator; :mod:`.dynamics`
holds the axis physics and control law as pure functions.
"""

from .driver import MirrorGimbal
from .model import MirrorGimbalModel

__all__ = ["MirrorGimbal", "MirrorGimbalModel"]
