"""``--overwrite`` for commands that create a session file, the CLI's wording of its refusal, and
wording shared by the commands' summaries."""

from __future__ import annotations

import argparse
import contextlib
from collections.abc import Iterator
from typing import Any

from ..errors import SessionExistsError


def add_overwrite_option(parser: argparse.ArgumentParser, option: str = "--out", also: str = "") -> None:
    """Add ``--overwrite``: a new session replaces the file named by ``option`` if it exists (``also``:
    what else it replaces, said in the help)."""
    parser.add_argument("--overwrite", action="store_true",
                        help=f"replace an existing {option} file with a new session (the old file stays "
                             f"until the new session holds data){also}")


@contextlib.contextmanager
def cli_advice(option: str = "--out") -> Iterator[None]:
    """Reword :class:`SessionExistsError` for the command line: ``--overwrite``, not ``overwrite=True``."""
    try:
        yield
    except SessionExistsError as exc:
        raise SessionExistsError(exc.path, f"add --overwrite to replace it, or choose another {option}") from None


def add_allow_port_url_option(parser: argparse.ArgumentParser) -> None:
    """Add ``--allow-port-url``: a port may be any pyserial URL, not only a device path, ``socket://``,
    ``loop://`` or ``rfc2217://`` (see :func:`mirrorlab.core.devices.transport.port_problem`)."""
    parser.add_argument("--allow-port-url", action="store_true",
                        help="accept any pyserial URL as an instrument's port (spy://, alt://, hwgrep://...: they "
                             "can write files or open other devices); without it a port is a device path, "
                             "socket://, loop:// or rfc2217://")


def printable(text: str, lines: bool = False) -> str:
    r"""``text`` with control characters escaped (``\x1b``), for text read from a file that reaches a
    terminal: an ESC or OSC sequence in a file from elsewhere must not move the cursor, retitle the
    window or hide what follows. ``lines``: keep line ends (text shown in a pane of several lines).

    >>> printable("ana" + chr(27) + "]0;pwned" + chr(7) + " smith")
    'ana\\x1b]0;pwned\\x07 smith'
    >>> printable("a" + chr(10) + "b", lines=True) == "a" + chr(10) + "b"
    True
    """
    return text.translate(_ESCAPES_BUT_LINES if lines else _ESCAPES)


def escaped(data: Any) -> Any:
    r"""``data`` (nested dicts and lists, e.g. :meth:`Session.describe`) with every text, keys too,
    :func:`printable`.

    >>> escaped({"operator": "x" + chr(27) + "[2J", "n": [1, "a" + chr(10)]})
    {'operator': 'x\\x1b[2J', 'n': [1, 'a\\x0a']}
    """
    if isinstance(data, str):
        return printable(data)
    if isinstance(data, dict):
        return {escaped(k): escaped(v) for k, v in data.items()}
    if isinstance(data, list | tuple):
        return [escaped(v) for v in data]
    return data


#: C0 and C1 control characters and DEL, as Python writes them escaped.
_ESCAPES = {c: f"\\x{c:02x}" for c in (*range(0x20), *range(0x7f, 0xa0))}
_ESCAPES_BUT_LINES = {c: text for c, text in _ESCAPES.items() if c != ord("\n")}


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
