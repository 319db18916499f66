"""The table of built-in sub-commands: name, one-line help and where the parser is built.

``mirrorlab --version`` and ``mirrorlab --help`` read only this table, so they import no plugin,
no numpy and no h5py. A command's module (and its plugin) is imported only when that command is
parsed. The core declares its own commands here; the built-in algorithm plugins declare theirs in
``mirrorlab.plugins.CLI_COMMANDS``. Third-party plugins add commands through the hook
``mirrorlab_add_cli_commands``; their modules are imported only for the top-level help and for a
command name that is not built in (see :func:`mirrorlab.core.cli.build_parser`).
"""

from __future__ import annotations

import argparse
import importlib
import inspect
from collections.abc import Sequence
from dataclasses import dataclass


@dataclass(frozen=True)
class Command:
    """One sub-command: its name and help as listed by ``mirrorlab --help``, and its parser builder.

    ``target`` is ``"module:function"``; the function takes the sub-parsers action and adds this
    command's parser (it may add sibling commands of the same module too). A function that also
    takes ``argv`` (the command line being parsed, or None for the full help) may build only what
    parsing it needs: ``analyze`` and ``record`` build one algorithm's or instrument's options, so
    only its plugin is imported.
    """

    name: str
    help: str
    target: str

    def add(self, subparsers: argparse._SubParsersAction, argv: Sequence[str] | None = None) -> None:
        module, _, function = self.target.partition(":")
        builder = getattr(importlib.import_module(module), function)
        if "argv" in inspect.signature(builder).parameters:
            builder(subparsers, argv=argv)
        else:
            builder(subparsers)


def named_after(argv: Sequence[str] | None, command: str) -> str | None:
    """The first positional argument after ``command`` in ``argv`` (e.g. the algorithm of ``analyze``)."""
    if argv is None or command not in argv:
        return None
    return next((a for a in list(argv)[list(argv).index(command) + 1:] if not a.startswith("-")), None)


CORE_COMMANDS = (
    Command("plugins", "list installed plugins, instruments, algorithms and steps", f"{__package__}.plugins_cmd:add"),
    Command("session", "create, inspect, check, close and export session files", f"{__package__}.session_cmd:add"),
    Command("run", "validate and run a recipe (TOML) into a new session file", f"{__package__}.run_cmd:add"),
    Command("demo", "run the bundled demonstration recipe on simulated instruments", f"{__package__}.run_cmd:add"),
    Command("analyze", "run a registered algorithm on datasets of a session", f"{__package__}.analyze_cmd:add"),
    Command("record", "record one instrument (real or simulated) into a new session", f"{__package__}.analyze_cmd:add"),
    Command("simulate", "serve an instrument's simulator on a pty or TCP port", f"{__package__}.simulate_cmd:add"),
    Command("batch", "run an analysis recipe on many session files on Dask workers", "mirrorlab.core.batch.cli:add"),
    Command("tui", "the operator console: live dashboard, recording, set-points, in the terminal",
            f"{__package__}.tui_cmd:add"),
)


def builtin_commands() -> list[Command]:
    """The core's commands, then those the built-in algorithm plugins declare (nothing imported)."""
    declared = importlib.import_module("mirrorlab.plugins").CLI_COMMANDS
    return [*CORE_COMMANDS, *(Command(name, help_, target) for name, (help_, target) in declared.items())]
