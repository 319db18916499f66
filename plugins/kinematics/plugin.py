"""Registration of the kinematics adapters: algorithms
(:mod:`.algorithms`), the ``import_markers`` step (:mod:`.steps`) and the ``mirrorlab kinematics``
command (:mod:`.cli`).

Nothing else lives here.
"""

from __future__ import annotations

from mirrorlab.core import Subcommands, hookimpl

from .algorithms import ALGORITHMS
from .steps import STEPS


@hookimpl
def mirrorlab_register_algorithms() -> list[type]:
    return list(ALGORITHMS)


@hookimpl
def mirrorlab_register_steps() -> list[type]:
    return list(STEPS)


@hookimpl
def mirrorlab_add_cli_commands(subparsers: Subcommands) -> None:
    from .cli import add  # the CLI adapter only when a command line needs it

    add(subparsers)
