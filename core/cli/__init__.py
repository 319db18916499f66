"""The ``mirrorlab`` command line.

Conventions: exit code 0 ok, 1 runtime failure, 2 usage or validation error; errors are one clear
line (``--debug`` shows the traceback); commands that print information take ``--json``; long
work shows a progress bar on stderr. Plugins add commands through ``mirrorlab_add_cli_commands``.
"""

from __future__ import annotations

import argparse
import logging
import sys
import warnings
from collections.abc import Sequence
from typing import Any

from ..errors import MirrorlabError, MirrorlabWarning, ValidationError
from ..registry import get_registry
from ..session import mirrorlab_version
from . import analyze_cmd, plugins_cmd, run_cmd, session_cmd

EXIT_OK, EXIT_FAILURE, EXIT_USAGE = 0, 1, 2


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> None:  # argparse's usage errors: one line, exit 2
        self.print_usage(sys.stderr)
        print(f"mirrorlab: error: {message}", file=sys.stderr)
        sys.exit(EXIT_USAGE)


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="mirrorlab", description="Motion-measurement instruments, sessions and analysis.")
    parser.add_argument("--version", action="version", version=f"mirrorlab {mirrorlab_version()}")
    parser.add_argument("--debug", action="store_true", help="show tracebacks and debug logging")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    plugins_cmd.add(sub)
    session_cmd.add(sub)
    run_cmd.add(sub)
    analyze_cmd.add(sub)
    registry = get_registry()
    for message in registry.notify("mirrorlab_add_cli_commands", subparsers=sub):
        print(f"mirrorlab: warning: {message}", file=sys.stderr)
    return parser


_python_show_warning = warnings.showwarning


def _show_warning(message: Warning | str, category: type[Warning], filename: str, lineno: int,
                  file: Any = None, line: str | None = None) -> None:
    """mirrorlab's own warnings are one line on stderr, like its errors; others keep Python's format."""
    if issubclass(category, MirrorlabWarning):
        print(f"mirrorlab: warning: {message}", file=sys.stderr)
    else:
        _python_show_warning(message, category, filename, lineno, file, line)


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``mirrorlab`` console script."""
    argv = list(sys.argv[1:] if argv is None else argv)
    debug = "--debug" in argv
    logging.basicConfig(level=logging.DEBUG if debug else logging.WARNING,
                        format="%(levelname)s %(name)s: %(message)s")
    if not debug:
        logging.getLogger("mirrorlab").setLevel(logging.ERROR)  # the CLI prints what matters itself
        warnings.showwarning = _show_warning
    try:
        parser = build_parser()
        args = parser.parse_args(argv)
        if not getattr(args, "func", None):
            parser.print_help()
            return EXIT_USAGE
        return int(args.func(args) or EXIT_OK)
    except ValidationError as exc:
        for problem in exc.problems:
            print(f"mirrorlab: error: {problem}", file=sys.stderr)
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
        print(f"mirrorlab: error: {type(exc).__name__}: {exc} (run with --debug for the traceback)",
              file=sys.stderr)
        return EXIT_FAILURE


if __name__ == "__main__":
    sys.exit(main())
