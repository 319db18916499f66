"""Registration of the retarget adapters (algorithm, recipe step, CLI); nothing else lives here."""

from __future__ import annotations

import argparse

from .algorithms import Retarget, RetargetStep

ALGORITHMS = [Retarget]
STEPS = [RetargetStep]


def add_cli_commands(subparsers: argparse._SubParsersAction) -> None:
    """Add ``mirrorlab retarget ...`` (see :mod:`.cli`)."""
    from .cli import add

    add(subparsers)
