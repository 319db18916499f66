"""The cluster options shared by ``mirrorlab batch`` and ``mirrorlab run --session`` (Dask not imported)."""

from __future__ import annotations

import argparse


def _whole(text: str, least: int) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a whole number") from None
    if value < least:
        raise argparse.ArgumentTypeError(f"{value} must be at least {least}")
    return value


def positive_int(text: str) -> int:
    """argparse type: an integer ≥ 1.

    >>> positive_int("2")
    2
    """
    return _whole(text, 1)


def count(text: str) -> int:
    """argparse type: an integer ≥ 0.

    >>> count("0")
    0
    """
    return _whole(text, 0)


def add_cluster_options(parser: argparse.ArgumentParser) -> None:
    """``--workers N`` (a LocalCluster of N processes) or ``--scheduler ADDRESS`` (a running cluster)."""
    where = parser.add_mutually_exclusive_group()
    where.add_argument("--workers", type=positive_int, metavar="N",
                       help="start a local Dask cluster of N worker processes, one thread each "
                            "(default for batch: one per core)")
    where.add_argument("--scheduler", metavar="ADDRESS",
                       help="use a running Dask scheduler, e.g. tcp://10.0.0.5:8786 (see docs/scale.md)")
