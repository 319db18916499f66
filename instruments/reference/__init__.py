"""Reference instruments: a streaming angle source, an actuator with a live target and a chain source.

Minimal, complete serial instruments (driver + simulator speaking the line protocol of
``instruments.md`` §0.2) for closing a control loop without special hardware: the runtime's tests
and benchmark use them, a lab can point them at a bench rig with the same firmware, and plugin
authors can read them as the shortest example of a streaming sensor and of a set-point actuator.
The chain source streams joint positions (a motion-capture skeleton) to drive the ``retarget``
controller.
Protocols: ``docs/instruments/reference.md``.
"""

from .drivers import Actuator, AngleSource, ChainSource

__all__ = ["Actuator", "AngleSource", "ChainSource"]
