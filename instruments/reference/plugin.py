"""Registration of the reference instruments ``angle_source``, ``actuator`` and ``chain_source``.

Nothing else lives here.
"""

from __future__ import annotations

from mirrorlab.core import hookimpl

from .drivers import Actuator, AngleSource, ChainSource


@hookimpl
def mirrorlab_register_instruments() -> list[type]:
    return [AngleSource, Actuator, ChainSource]
