"""``--overwrite`` for commands that create a session file, the CLI's wording of its refusal, and
wording shared by the commands' summaries."""

from __future__ import annotations

import argparse
import contextlib
from collections.abc import Iterator
from typing import Any

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


def add_allow_empty_option(parser: argparse.ArgumentParser) -> None:
    """Add ``--allow-empty``: an instrument that recorded no sample is a warning, not a failure (exit 1)."""
    parser.add_argument("--allow-empty", action="store_true",
                        help="accept a recording in which an instrument delivered no sample (a warning; "
                             "without it: exit 1)")


def group_contents(g: dict[str, Any]) -> str:
    """``12 datasets``, ``1 dataset, 2 groups`` or ``empty``: a group of :meth:`Session.describe`,
    with its description."""
    counts = [f"{g[k]} {k if g[k] != 1 else k[:-1]}" for k in ("datasets", "groups") if g[k]]
    return (", ".join(counts) or "empty") + (f" ({g['description']})" if g["description"] else "")


def plural(n: int, word: str) -> str:
    """``1 sample``, ``3 samples``."""
    return f"{n} {word}{'' if n == 1 else 's'}"
