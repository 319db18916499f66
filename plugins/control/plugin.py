"""Registration of the built-in controllers (:mod:`.controllers`). Nothing else lives here."""

from __future__ import annotations

from mirrorlab.core import hookimpl

from .controllers import CONTROLLERS


@hookimpl
def mirrorlab_register_controllers() -> list[type]:
    return list(CONTROLLERS)
