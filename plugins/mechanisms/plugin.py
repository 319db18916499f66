"""Registration of the mechanism adapters: algorithms, recipe steps and the ``mirrorlab mechanisms`` CLI."""

from __future__ import annotations

import argparse

from .algorithms import ALGORITHMS
from .steps import STEPS


def add_cli_commands(subparsers: argparse._SubParsersAction) -> None:
    from .cli import add

    add(subparsers)


__all__ = ["ALGORITHMS", "STEPS", "add_cli_commands"]
