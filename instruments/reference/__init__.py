"""Reference instruments: a streaming angle source and an actuator with a live target.

Minimal, complete serial instruments (driver + simulator speaking the line protocol of
``instruments.md`` §0.2) for closing a control loop without special hardware: the runtime's tests
and benchmark use them, a lab can point them at a bench rig with the same firmware, and plugin
authors can read them as the shortest example of a streaming sensor and of a set-point actuator.
Protocols: ``docs/instruments/reference.md``.
"""

from .drivers import Actuator, AngleSource

__all__ = ["Actuator", "AngleSource"]
