"""Registration of the ultrasonic direction tracker (USDF): the ``ultrasonic_tracker``
instrument and its report step (:mod:`.steps`).

Nothing else lives here.
"""

from __future__ import annotations

from mirrorlab.core import hookimpl

from .driver import UltrasonicTracker
from .steps import STEPS


@hookimpl
def mirrorlab_register_instruments() -> list[type]:
    return [UltrasonicTracker]


@hookimpl
def mirrorlab_register_steps() -> list[type]:
    return list(STEPS)
