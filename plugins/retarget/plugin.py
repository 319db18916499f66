"""Registration of the retarget adapters: the ``retarget`` algorithm and step (:mod:`.algorithms`); nothing else lives here."""

from __future__ import annotations

from mirrorlab.core import hookimpl

from .algorithms import Retarget, RetargetStep


@hookimpl
def mirrorlab_register_algorithms() -> list[type]:
    return [Retarget]


@hookimpl
def mirrorlab_register_steps() -> list[type]:
    return [RetargetStep]
