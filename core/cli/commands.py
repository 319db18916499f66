"""The sub-commands of ``mirrorlab``: the core's own table, and the plugins' through their hook.

``mirrorlab --version`` and ``mirrorlab --help`` import no plugin, no numpy and no h5py: the core's
commands are listed from :data:`CORE_COMMANDS` (name, one-line help and where the parser is built),
the plugins' from their declarations (``command.<name>`` in the entry-point group
``mirrorlab.provides``, its help in the group ``mirrorlab.commands``; see
:mod:`mirrorlab.core.registry`). A command's parser, and its plugin, is built only when that
command is parsed. Every plugin, built-in or third-party, adds its commands one way: the hook
``mirrorlab_add_cli_commands``, which receives a :class:`Subcommands`. A plugin that declares no
commands is imported for the top-level help and for a command name no plugin declares (see
:func:`add_plugin_commands`).
"""

from __future__ import annotations

import argparse
import importlib
import inspect
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from ..errors import PluginError

if TYPE_CHECKING:
    from ..registry import Registry


class Subcommands:
    """The ``mirrorlab`` sub-commands, as a plugin's ``mirrorlab_add_cli_commands`` receives them.

    Parameters
    ----------
    action
        The top-level parser's sub-parsers (argparse's own type stays inside the core).
    argv
        The command line being parsed, or None when every parser is built (the full help).
    """

    def __init__(self, action: argparse._SubParsersAction, argv: Sequence[str] | None) -> None:
        self._action = action
        #: The command line being parsed (without the program name), or None when every parser is
        #: built: a command that builds many options (one per algorithm) may build only what it needs.
        self.argv = argv

    def __contains__(self, name: object) -> bool:
        return name in self._action.choices

    def add_parser(self, name: str, *, help: str, **kwargs: Any) -> argparse.ArgumentParser:
        """Add the command ``name`` and return its parser: add its arguments (sub-commands too) and
        ``set_defaults(func=...)``, a callable taking the parsed ``argparse.Namespace`` and returning the
        exit code (0 ok, 1 runtime failure, 2 usage or validation error).

        ``help`` is the command's line in ``mirrorlab --help``; ``kwargs`` are those of
        ``argparse.ArgumentParser`` (``description``, ``epilog``, ``formatter_class``...). Raises
        ``ValueError`` if another command (the core's or another plugin's) already has the name.
        """
        if name in self._action.choices:
            raise ValueError(f"a command named {name!r} already exists")
        return self._action.add_parser(name, help=help, **kwargs)


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


def command_table(registry: Registry) -> dict[str, str]:
    """Every command ``mirrorlab --help`` lists without importing a plugin: name -> one-line help,
    the core's first, then those the plugins declare (in declaration order)."""
    table = {c.name: c.help for c in CORE_COMMANDS}
    for name in registry.commands():
        table.setdefault(name, registry.command_help(name))
    return table


def add_plugin_commands(action: argparse._SubParsersAction, registry: Registry, argv: Sequence[str] | None,
                        wanted: str | None) -> list[str]:
    """Add the plugins' commands: real parsers for what parsing ``argv`` needs, help-only stubs for the
    rest. Returns the failures of plugins' hooks (one line each), to be shown as warnings.

    ``argv=None`` builds every plugin's parsers. With ``argv``: a command a plugin declares
    (``wanted``) calls only that plugin's hook; any other line (the top-level help, a command no
    plugin declares) calls the hook of the plugins that declare no commands, which the registry
    imported when it was built. Raises :class:`PluginError` if the plugin declaring ``wanted``
    could not add it (broken, or its hook failed).
    """
    declared = registry.commands()
    if argv is None:
        registry.load_all()
        calling: set[str] | None = set(registry.installed())
    else:
        calling = set(declared[wanted]) if wanted in declared else None
    stubs = set()  # help-only parsers, listed in order but never parsed
    for name in declared:
        if name not in action.choices and not (calling and calling & set(declared[name])):
            action.add_parser(name, help=registry.command_help(name), add_help=False)
            stubs.add(name)
    failures = registry.notify("mirrorlab_add_cli_commands", plugins=calling, subparsers=Subcommands(action, argv))
    for name in declared:  # a declared command whose plugin is broken is still listed
        if name not in action.choices:
            action.add_parser(name, help=registry.command_help(name), add_help=False)
            stubs.add(name)
    if wanted in declared and wanted in stubs:
        reasons = [f"plugin {p!r} is broken: {info.error}" if info.error else f"plugin {p!r} did not add it"
                   for p, info in ((p, registry.installed()[p]) for p in declared[wanted])]
        raise PluginError(f"the command {wanted!r} is not available: {'; '.join(failures + reasons)} "
                          "(see `mirrorlab plugins doctor`)")
    return failures
