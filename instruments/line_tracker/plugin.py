"""Registration of the line sensor direction detector (OLDT): the ``line_tracker``
instrument and its report step (:mod:`.steps`).

Nothing else lives here.
"""

from __future__ import annotations

from mirrorlab.core import hookimpl

from .driver import LineTracker
from .steps import STEPS


@hookimpl
def mirrorlab_register_instruments() -> list[type]:
    return [LineTracker]


@hookimpl
def mirrorlab_register_steps() -> list[type]:
    return list(STEPS)
