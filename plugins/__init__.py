"""Built-in algorithm plugins: pure functions (photogrammetry, kinematics) wrapped as algorithms."""

from __future__ import annotations

from mirrorlab.core.hookspecs import hookimpl


@hookimpl
def mirrorlab_register_algorithms() -> list[type]:
    from .kinematics.plugin import Derivatives

    return [Derivatives]
