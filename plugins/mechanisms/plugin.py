"""Registration of the mechanism adapters: algorithms
(:mod:`.algorithms`), the ``four_bar_report`` / ``wall_report`` steps (:mod:`.steps`), the
``mirrorlab mechanisms`` command (:mod:`.cli`) and the console's dexterity task (:mod:`.screen`).

Nothing else lives here.
"""

from __future__ import annotations

from mirrorlab.core import ScreenEntry, Subcommands, hookimpl

from .algorithms import ALGORITHMS
from .steps import STEPS


@hookimpl
def mirrorlab_register_algorithms() -> list[type]:
    return list(ALGORITHMS)


@hookimpl
def mirrorlab_register_steps() -> list[type]:
    return list(STEPS)


@hookimpl
def mirrorlab_register_screens() -> list[ScreenEntry]:
    return [ScreenEntry("dexterity", "m", "Dexterity task", "sweep the least area moving a segment, B on the x axis",
                        f"{__package__}.screen:DexterityScreen")]


@hookimpl
def mirrorlab_add_cli_commands(subparsers: Subcommands) -> None:
    from .cli import add  # the CLI adapter only when a command line needs it

    add(subparsers)
