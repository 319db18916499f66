"""The ``mirrorlab`` command line.

Conventions: exit code 0 ok, 1 runtime failure, 2 usage or validation error (:data:`EXIT_CODES`);
an error is printed once, as one line on stderr (``--debug``, anywhere on the line, shows the
traceback); commands that print information take ``--json``; long work shows a progress bar on
stderr. Start-up is lazy: the core's command table and the plugins' declarations
(:mod:`.commands`) list the commands without importing them, and only the command being run is
imported. Plugins add commands through ``mirrorlab_add_cli_commands``.
"""

from __future__ import annotations

import argparse
import logging
import os
import sys
import warnings
from collections.abc import Sequence
from typing import Any, NoReturn

from ..errors import MirrorlabError, MirrorlabWarning, ValidationError
from ..version import mirrorlab_version
from . import commands
from .outputs import printable

EXIT_OK, EXIT_FAILURE, EXIT_USAGE = 0, 1, 2

#: The exit codes of every command (shown by ``mirrorlab --help``).
EXIT_CODES = """\
exit codes (every command):
  0  ok
  1  runtime failure: a failed algorithm run or step, a device, file or plugin error,
     a recording in which an instrument delivered no sample (unless --allow-empty),
     an incomplete session (session check), a broken plugin (plugins doctor)
  2  usage or validation error: unknown option or input name, bad value, invalid recipe,
     missing input file, folder, dataset or stream

Add --debug anywhere for tracebacks and debug logging."""


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> NoReturn:  # argparse's usage errors: one line, exit 2
        self.print_usage(sys.stderr)
        print(f"mirrorlab: error: {message}", file=sys.stderr)
        sys.exit(EXIT_USAGE)


def _command_name(argv: Sequence[str]) -> str | None:
    """The sub-command named in ``argv`` (top-level options take no values), or None."""
    return next((a for a in argv if not a.startswith("-")), None)


def build_parser(argv: Sequence[str] | None = None) -> argparse.ArgumentParser:
    """The ``mirrorlab`` parser: everything (``argv=None``) or only what parsing ``argv`` needs.

    With ``argv`` the commands other than the one named in it are help-only stubs (never parsed):
    a core command imports no plugin, a plugin's command only the plugin that declares it, and
    plugins that declare no commands are imported only for the top-level help or a command that no
    one declares (:func:`.commands.add_plugin_commands`).
    """
    parser = _Parser(prog="mirrorlab", description="Motion-measurement instruments, sessions and analysis.",
                     epilog=EXIT_CODES, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--version", action="version", version=f"mirrorlab {mirrorlab_version()}")
    parser.add_argument("--debug", action="store_true", help="show tracebacks and debug logging")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    wanted = None if argv is None else _command_name(argv)
    load = {c.target for c in commands.CORE_COMMANDS if argv is None or c.name == wanted}
    for command in commands.CORE_COMMANDS:
        if command.name in sub.choices:  # added with a sibling from the same module
            continue
        if command.target in load:
            command.add(sub, argv)
        else:
            sub.add_parser(command.name, help=command.help, add_help=False)
    if argv is None or (wanted is None and "--version" not in argv) or (wanted is not None and wanted not in sub.choices):
        from ..registry import Registry

        for message in commands.add_plugin_commands(sub, Registry(), argv, wanted):
            print(f"mirrorlab: warning: {message}", file=sys.stderr)
    return parser


def _split_debug(argv: list[str]) -> tuple[list[str], bool]:
    """Remove ``--debug`` wherever it is (before a ``--``): it is accepted after the sub-command too."""
    end = argv.index("--") if "--" in argv else len(argv)
    kept = [a for a in argv[:end] if a != "--debug"] + argv[end:]
    return kept, len(kept) != len(argv)


_python_show_warning = warnings.showwarning


def _show_warning(message: Warning | str, category: type[Warning], filename: str, lineno: int,
                  file: Any = None, line: str | None = None) -> None:
    """mirrorlab's own warnings are one line on stderr, like its errors; others keep Python's format."""
    if issubclass(category, MirrorlabWarning):
        print(f"mirrorlab: warning: {message}", file=sys.stderr)
    else:
        _python_show_warning(message, category, filename, lineno, file, line)


def _configure_logging(debug: bool) -> None:
    logging.basicConfig(level=logging.WARNING, format="%(levelname)s %(name)s: %(message)s")
    logging.getLogger("mirrorlab").setLevel(logging.DEBUG if debug else logging.ERROR)
    if not debug:  # session events reach the terminal through the command (progress bar, raised errors)
        logging.getLogger("mirrorlab.events").setLevel(logging.CRITICAL)
        warnings.showwarning = _show_warning


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``mirrorlab`` console script; returns the exit code."""
    argv, debug = _split_debug(list(sys.argv[1:] if argv is None else argv))
    _configure_logging(debug)
    try:
        parser = build_parser(argv)
        args = parser.parse_args(argv)
        args.debug = debug
        if not getattr(args, "func", None):
            parser.print_help()
            return EXIT_USAGE
        from ..store import lock  # a session file this command writes names it as its writer

        lock.command = f"mirrorlab {args.command}"
        code = int(args.func(args) or EXIT_OK)
        sys.stdout.flush()  # a closed pipe shows here, not at interpreter exit
        return code
    except BrokenPipeError:  # the reader went away (`mirrorlab ... | head`): stop quietly
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return EXIT_FAILURE
    except ValidationError as exc:
        for problem in exc.problems:  # a key or value from the input may hold terminal escapes: shown escaped
            print(f"mirrorlab: error: {printable(str(problem))}", file=sys.stderr)
        if debug:
            raise
        return EXIT_USAGE
    except MirrorlabError as exc:
        if debug:
            raise
        print(f"mirrorlab: error: {exc}", file=sys.stderr)
        return EXIT_FAILURE
    except KeyboardInterrupt:
        print("mirrorlab: interrupted", file=sys.stderr)
        return EXIT_FAILURE
    except Exception as exc:  # an unexpected failure is still one line unless --debug
        if debug:
            raise
        print(f"mirrorlab: error: {type(exc).__name__}: {exc} (add --debug for the traceback)", file=sys.stderr)
        return EXIT_FAILURE


if __name__ == "__main__":
    sys.exit(main())
