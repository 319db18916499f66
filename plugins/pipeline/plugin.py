"""Registration of the demo pipeline adapters: the glue algorithms
(:mod:`.algorithms`) and the ``report`` step (:mod:`.steps`).

Nothing else lives here.
"""

from __future__ import annotations

from mirrorlab.core import hookimpl

from .algorithms import ALGORITHMS
from .steps import STEPS


@hookimpl
def mirrorlab_register_algorithms() -> list[type]:
    return list(ALGORITHMS)


@hookimpl
def mirrorlab_register_steps() -> list[type]:
    return list(STEPS)
