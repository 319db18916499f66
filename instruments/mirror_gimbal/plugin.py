"""Registration of the active mirror (MGIM): the ``mirror_gimbal``
instrument and its report step (:mod:`.steps`).

Nothing else lives here.
"""

from __future__ import annotations

from mirrorlab.core import hookimpl

from .driver import MirrorGimbal
from .steps import STEPS


@hookimpl
def mirrorlab_register_instruments() -> list[type]:
    return [MirrorGimbal]


@hookimpl
def mirrorlab_register_steps() -> list[type]:
    return list(STEPS)
