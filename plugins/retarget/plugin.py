"""Registration of the retarget adapters: the ``retarget`` algorithm (:mod:`.algorithms`), step
(:mod:`.steps`), controller (:mod:`.controllers`) and command (:mod:`.cli`), and the console's
virtual input chain (:mod:`.screen`).

Nothing else lives here.
"""

from __future__ import annotations

from mirrorlab.core import ScreenEntry, Subcommands, hookimpl

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


@hookimpl
def mirrorlab_register_screens() -> list[ScreenEntry]:
    return [ScreenEntry("chain", "v", "Virtual chain", "turn a virtual input chain's joints, see it retargeted",
                        f"{__package__}.screen:ChainScreen")]


@hookimpl
def mirrorlab_add_cli_commands(subparsers: Subcommands) -> None:
    from .cli import add  # the CLI adapter only when a command line needs it

    add(subparsers)
