"""Controllers: live logic that commands instruments from streams (closed loops, set-point schedules).

``follow``: drive one live parameter of an instrument from a scalar stream,
``value = gain · input + offset``. ``follow_target``: an active mirror (``mirror_gimbal``) follows
a direction tracker (``ultrasonic_tracker``) by θt = θv / 2 on both axes (thesis §4.4). See
``docs/writing-plugins.md`` for writing a controller.
"""

from .controllers import Follow, FollowTarget

__all__ = ["Follow", "FollowTarget"]
