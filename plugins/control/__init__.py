"""Controllers: live logic that commands instruments from streams (closed loops, set-point schedules).

``follow``: drive one live parameter of an instrument from a scalar stream,
``value = gain · input + offset`` — a proportional feed-forward such as the active mirror's
θt = θv / 2 (gain 0.5). See ``docs/writing-plugins.md`` for writing a controller.
"""

from .controllers import Follow

__all__ = ["Follow"]
