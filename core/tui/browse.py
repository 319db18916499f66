"""What the console shows of a session file: its tree, a dataset's preview, attributes and
provenance, as plain text (no widgets), read through the session's read API. These read the
file: call them from a worker thread.

Units: each dataset's ``unit`` attribute; times in session seconds.
"""

from __future__ import annotations

import json
from typing import TYPE_CHECKING, Any

import numpy as np

from ..cli.outputs import printable
from ..session import Node

if TYPE_CHECKING:
    from ..session import Session

__all__ = ["PREVIEW_ROWS", "PROVENANCE", "Node", "attributes", "datasets", "describe", "label", "preview", "walk"]

#: Values shown of a dataset (the first rows); the rest is summarised by its shape.
PREVIEW_ROWS = 6
#: Attributes whose JSON text is the provenance of a run or a session.
PROVENANCE = ("parameters", "inputs", "input_sha256", "executor", "settings", "identity", "recipe_effective")


def label(node: Node) -> str:
    """``xy  (120, 8, 2) float64 px`` for a dataset (a table's type as its number of fields), the name for a group."""
    if not node.is_dataset or node.dtype is None:
        return printable(node.name)  # a name from another lab's file may hold terminal escapes
    dtype = f"{len(node.dtype.names)} fields" if node.dtype.names else str(node.dtype)  # a table: short
    return printable(f"{node.name}  {node.shape} {dtype} {node.unit}".rstrip())


def _text(value: Any) -> str:
    if isinstance(value, bytes):
        return value.decode("utf-8", "replace")
    if isinstance(value, np.ndarray) and value.dtype.kind in "OS":
        return str([_text(v) for v in value.tolist()])
    return str(value)


def walk(session: Session) -> list[Node]:
    """Every group and dataset of the session's file, in the file's order (parents before children).

    A recorded stream's ``data`` takes the unit of its stream group (where the store keeps it)."""
    return session.tree()


def datasets(session: Session) -> list[Node]:
    """The datasets of :func:`walk`, as candidate inputs of an algorithm."""
    return [n for n in walk(session) if n.is_dataset]


def attributes(session: Session, path: str) -> list[tuple[str, str]]:
    """``(name, text)`` of each attribute of ``path``; JSON attributes (provenance) pretty-printed."""
    out = []
    for key, value in session.attributes(path).items():
        text = _text(value)
        if key in PROVENANCE:
            try:
                text = json.dumps(json.loads(text), indent=1, sort_keys=True)
            except ValueError:
                pass
        out.append((key, text))
    return out


def preview(session: Session, node: Node, rows: int = PREVIEW_ROWS) -> str:
    """The first ``rows`` entries of a dataset (numpy's summary of larger entries), or its text."""
    if node.shape == ():
        return _text(session.read(node.path))
    head = session.read(node.path, slice(0, min(rows, node.shape[0])))
    if node.dtype is not None and node.dtype.kind in "OS":  # text (h5py's strings are objects or bytes)
        return "\n".join(_text(v) for v in head)
    with np.printoptions(precision=4, threshold=60, edgeitems=2, linewidth=76, suppress=True):
        text = np.array2string(np.asarray(head))
    more = node.shape[0] - len(head)
    return text + (f"\n… {more} more of {node.shape[0]}" if more > 0 else "")


def describe(session: Session, path: str) -> str:
    """What the browser shows of one node: kind, shape, unit, attributes (with provenance), preview."""
    node = session.node(path)
    lines = [f"[{'dataset' if node.is_dataset else 'group'}] {node.path}"]
    if node.is_dataset:
        lines.append(f"shape {node.shape}, {node.dtype}")
    else:
        lines.append(f"{node.members} members")
    attrs = attributes(session, path)
    if attrs:
        lines += ["", "attributes:"] + [f"  {k} = {v}" if "\n" not in v else f"  {k} =\n{v}" for k, v in attrs]
    if node.is_dataset:
        lines += ["", "first values:", preview(session, node)]
    return printable("\n".join(lines), lines=True)  # names, attributes, text of a file from elsewhere
