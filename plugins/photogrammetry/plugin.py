"""Registration of the photogrammetry adapters: algorithms
(:mod:`.algorithms`), the ``calibrate`` / ``reconstruct`` steps (:mod:`.steps`) and the
``mirrorlab calibrate`` / ``reconstruct`` commands (:mod:`.cli`).

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
