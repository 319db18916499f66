"""Registration of the retarget adapters: the ``retarget`` algorithm (:mod:`.algorithms`), step
(:mod:`.steps`) and controller (:mod:`.controllers`).

Nothing else lives here.
"""

from __future__ import annotations

from mirrorlab.core import hookimpl

from .algorithms import Retarget
from .controllers import RetargetController
from .steps import RetargetStep


@hookimpl
def mirrorlab_register_algorithms() -> list[type]:
    return [Retarget]


@hookimpl
def mirrorlab_register_steps() -> list[type]:
    return [RetargetStep]


@hookimpl
def mirrorlab_register_controllers() -> list[type]:
    return [RetargetController]
