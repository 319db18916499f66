"""Built-in algorithm plugins: pure functions wrapped as algorithms, recipe steps and CLI commands.

Each sub-package keeps its mathematics in plain modules and its framework adapters in
``plugin.py``, which may define ``ALGORITHMS`` (algorithm classes), ``STEPS`` (recipe step
classes) and ``add_cli_commands(subparsers)``. Each adapter is registered as its own plugin
(``mirrorlab.plugins.<name>``), so one that fails to import is reported as broken without taking
the others down. Their CLI commands are declared in :data:`CLI_COMMANDS`, so that the ``mirrorlab``
command lists them without importing any sub-package.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from types import ModuleType

from mirrorlab.core.hookspecs import hookimpl

#: Sub-packages with a ``plugin`` module, in registration order.
SUBPACKAGES = ("kinematics", "photogrammetry", "markers", "pairing", "tracking", "pipeline", "retarget", "mechanisms",
               "control")

#: CLI sub-commands of the sub-packages: name -> (one-line help, ``"module:function"`` adding the parser).
#: ``mirrorlab --help`` lists them from here; the module is imported only when the command runs.
CLI_COMMANDS = {
    "calibrate": ("calibrate a camera from chessboard photos or from calibration points (CSV)",
                  f"{__name__}.photogrammetry.plugin:add_cli_commands"),
    "reconstruct": ("3-D markers from 2-D marker data: --method parallel|central|mirror",
                    f"{__name__}.photogrammetry.plugin:add_cli_commands"),
    "kinematics": ("marker import/export, derivatives, joint angles, rigid bodies",
                   f"{__name__}.kinematics.plugin:add_cli_commands"),
    "retarget": ("chain shape approximation (retargeting) of recorded motion",
                 f"{__name__}.retarget.plugin:add_cli_commands"),
    "mechanisms": ("linkage reconstruction, swept areas, optimal wall",
                   f"{__name__}.mechanisms.plugin:add_cli_commands"),
}


class Adapter:
    """The hook implementations of one sub-package's ``plugin`` module."""

    def __init__(self, module: ModuleType) -> None:
        self.module = module

    @hookimpl
    def mirrorlab_register_algorithms(self) -> list[type]:
        return list(getattr(self.module, "ALGORITHMS", ()))

    @hookimpl
    def mirrorlab_register_controllers(self) -> list[type]:
        return list(getattr(self.module, "CONTROLLERS", ()))

    @hookimpl
    def mirrorlab_register_steps(self) -> list[type]:
        return list(getattr(self.module, "STEPS", ()))


def builtin_plugins() -> list[tuple[str, Callable[[], Adapter]]]:
    """``(plugin name, loader)`` for each sub-package adapter; the registry loads them one by one."""
    return [(f"{__name__}.{name}", lambda name=name: Adapter(importlib.import_module(f"{__name__}.{name}.plugin")))
            for name in SUBPACKAGES]
