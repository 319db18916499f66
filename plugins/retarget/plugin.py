"""Registration of the retarget adapters: the ``retarget`` algorithm (:mod:`.algorithms`), step
(:mod:`.steps`), controller (:mod:`.controllers`) and command (:mod:`.cli`), the console's
virtual input chain (:mod:`.screen`), and the reader of motion recordings that a simulated
``chain_source`` plays (``mirrorlab_read_motion``).

Nothing else lives here.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

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
def mirrorlab_read_motion(path: str, joints: list[str], scale: float, skip: int) -> tuple[Any, list[str], float]:
    from .algorithms import read_motion

    m = read_motion(Path(path), list(joints), scale, skip)
    return m.joints, [n.replace(" ", "_") for n in m.names], m.rate


@hookimpl
def mirrorlab_register_screens() -> list[ScreenEntry]:
    return [ScreenEntry("chain", "v", "Virtual chain", "turn a virtual input chain's joints, see it retargeted",
                        f"{__package__}.screen:ChainScreen")]


@hookimpl
def mirrorlab_add_cli_commands(subparsers: Subcommands) -> None:
    from .cli import add  # the CLI adapter only when a command line needs it

    add(subparsers)
