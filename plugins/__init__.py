"""Built-in algorithm plugins: pure functions wrapped as algorithms, recipe steps and CLI commands.

Each sub-package keeps its mathematics in plain modules and its framework adapters in
``plugin.py``, which may define ``ALGORITHMS`` (algorithm classes), ``STEPS`` (recipe step
classes) and ``add_cli_commands(subparsers)``. Each adapter is registered as its own plugin
(``mirrorlab.plugins.<name>``), so one that fails to import is reported as broken without taking
the others down.
"""

from __future__ import annotations

import argparse
import importlib
from collections.abc import Callable
from types import ModuleType

from mirrorlab.core.hookspecs import hookimpl

#: Sub-packages with a ``plugin`` module, in registration order.
SUBPACKAGES = ("kinematics", "photogrammetry", "markers", "pairing", "tracking", "pipeline", "mechanisms")


class Adapter:
    """The hook implementations of one sub-package's ``plugin`` module."""

    def __init__(self, module: ModuleType) -> None:
        self.module = module

    @hookimpl
    def mirrorlab_register_algorithms(self) -> list[type]:
        return list(getattr(self.module, "ALGORITHMS", ()))

    @hookimpl
    def mirrorlab_register_steps(self) -> list[type]:
        return list(getattr(self.module, "STEPS", ()))

    @hookimpl
    def mirrorlab_add_cli_commands(self, subparsers: argparse._SubParsersAction) -> None:
        add = getattr(self.module, "add_cli_commands", None)
        if add is not None:
            add(subparsers)


def builtin_plugins() -> list[tuple[str, Callable[[], Adapter]]]:
    """``(plugin name, loader)`` for each sub-package adapter; the registry loads them one by one."""
    return [(f"{__name__}.{name}", lambda name=name: Adapter(importlib.import_module(f"{__name__}.{name}.plugin")))
            for name in SUBPACKAGES]
