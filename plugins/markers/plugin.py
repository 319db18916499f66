"""Registration of the marker detection algorithm (:mod:`.algorithms`); nothing else lives here."""

from __future__ import annotations

from mirrorlab.core import hookimpl

from .algorithms import ALGORITHMS


@hookimpl
def mirrorlab_register_algorithms() -> list[type]:
    return list(ALGORITHMS)
