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


#: The Dask protocols ``--scheduler`` takes (all over TCP; ``tcp`` when the address names none).
SCHEDULER_SCHEMES = ("tcp", "tls", "ws", "wss")


def scheduler_address(text: str) -> str:
    """argparse type for ``--scheduler``: ``[tcp|tls|ws|wss://]HOST:PORT``, the port 1-65535; returned
    with its protocol (``tcp://`` if none).

    >>> scheduler_address("10.0.0.5:8786"), scheduler_address("tls://[::1]:8786")
    ('tcp://10.0.0.5:8786', 'tls://[::1]:8786')
    >>> scheduler_address("tcp://head:99999")
    Traceback (most recent call last):
    argparse.ArgumentTypeError: 'tcp://head:99999': port 99999 is not 1-65535 (a scheduler listens on 8786 by default)
    """
    scheme, sep, rest = text.partition("://")
    if not sep:
        scheme, rest = "tcp", text
    host, colon, port = rest.rpartition(":")
    if scheme not in SCHEDULER_SCHEMES:
        raise argparse.ArgumentTypeError(f"{text!r}: a scheduler address is {'://, '.join(SCHEDULER_SCHEMES)}:// "
                                         "HOST:PORT, e.g. tcp://10.0.0.5:8786")
    if not colon or not host.strip("[]") or not port.isdigit():
        raise argparse.ArgumentTypeError(f"{text!r} is not HOST:PORT, e.g. tcp://10.0.0.5:8786")
    if not 1 <= int(port) <= 65535:
        raise argparse.ArgumentTypeError(f"{text!r}: port {port} is not 1-65535 (a scheduler listens on 8786 "
                                         "by default)")
    return f"{scheme}://{host}:{int(port)}"


def add_cluster_options(parser: argparse.ArgumentParser) -> None:
    """``--workers N`` (a LocalCluster of N processes) or ``--scheduler ADDRESS`` (a running cluster)."""
    where = parser.add_mutually_exclusive_group()
    where.add_argument("--workers", type=positive_int, metavar="N",
                       help="start a local Dask cluster of N worker processes, one thread each "
                            "(default for batch: one per core)")
    where.add_argument("--scheduler", metavar="ADDRESS", type=scheduler_address,
                       help="use a running Dask scheduler, e.g. tcp://10.0.0.5:8786, which you trust: its "
                            "protocol is pickle, so it runs what it sends (see docs/scale.md)")
