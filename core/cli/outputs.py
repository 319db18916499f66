"""``--overwrite`` for commands that create a session file, and the CLI's wording of its refusal."""

from __future__ import annotations

import argparse
import contextlib
from collections.abc import Iterator

from ..errors import SessionExistsError


def add_overwrite_option(parser: argparse.ArgumentParser, option: str = "--out") -> None:
    """Add ``--overwrite``: a new session replaces the file named by ``option`` if it exists."""
    parser.add_argument("--overwrite", action="store_true",
                        help=f"replace an existing {option} file with a new session (the old file stays "
                             "until the new session holds data)")


@contextlib.contextmanager
def cli_advice(option: str = "--out") -> Iterator[None]:
    """Reword :class:`SessionExistsError` for the command line: ``--overwrite``, not ``overwrite=True``."""
    try:
        yield
    except SessionExistsError as exc:
        raise SessionExistsError(exc.path, f"add --overwrite to replace it, or choose another {option}") from None
