"""What the console shows of a session file: its tree, a dataset's preview, attributes and
provenance, as plain text (no widgets). These read the file: call them from a worker thread.

Units: each dataset's ``unit`` attribute; times in session seconds.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from typing import Any

import h5py
import numpy as np

#: Values shown of a dataset (the first rows); the rest is summarised by its shape.
PREVIEW_ROWS = 6
#: Attributes whose JSON text is the provenance of a run or a session.
PROVENANCE = ("parameters", "inputs", "input_sha256", "executor", "settings", "identity", "recipe_effective")


@dataclass(frozen=True)
class Node:
    """One group or dataset of the file: its path, and for a dataset its shape, type and unit."""

    path: str
    is_dataset: bool
    shape: tuple[int, ...] = ()
    dtype: str = ""
    unit: str = ""

    @property
    def name(self) -> str:
        return self.path.rsplit("/", 1)[-1] or "/"

    @property
    def label(self) -> str:
        """``xy  (120, 8, 2) float64 px`` for a dataset, the name for a group."""
        if not self.is_dataset:
            return self.name
        return f"{self.name}  {self.shape} {self.dtype} {self.unit}".rstrip()


def _text(value: Any) -> str:
    if isinstance(value, bytes):
        return value.decode("utf-8", "replace")
    if isinstance(value, np.ndarray) and value.dtype.kind in "OS":
        return str([_text(v) for v in value.tolist()])
    return str(value)


def walk(group: h5py.Group) -> list[Node]:
    """Every group and dataset under ``group``, in the file's order (parents before children).

    A recorded stream's ``data`` takes the unit of its stream group (where the store keeps it)."""
    nodes: list[Node] = []

    def visit(name: str, obj: h5py.HLObject) -> None:
        if isinstance(obj, h5py.Dataset):
            unit = obj.attrs.get("unit", obj.parent.attrs.get("unit", "") if obj.name.endswith("/data") else "")
            dtype = f"{len(obj.dtype.names)} fields" if obj.dtype.names else str(obj.dtype)  # a table: short
            nodes.append(Node(obj.name, True, tuple(obj.shape), dtype, _text(unit)))
        else:
            nodes.append(Node(obj.name, False))

    group.visititems(visit)
    return nodes


def datasets(group: h5py.Group) -> list[Node]:
    """The datasets of :func:`walk`, as candidate inputs of an algorithm."""
    return [n for n in walk(group) if n.is_dataset]


def attributes(obj: h5py.HLObject) -> list[tuple[str, str]]:
    """``(name, text)`` of each attribute; JSON attributes (provenance) pretty-printed."""
    out = []
    for key, value in obj.attrs.items():
        text = _text(value)
        if key in PROVENANCE:
            try:
                text = json.dumps(json.loads(text), indent=1, sort_keys=True)
            except ValueError:
                pass
        out.append((key, text))
    return out


def preview(ds: h5py.Dataset, rows: int = PREVIEW_ROWS) -> str:
    """The first ``rows`` entries of a dataset (numpy's summary of larger entries), or its text."""
    if ds.shape == ():
        return _text(ds[()])
    if ds.dtype.kind in "OS" or h5py.check_string_dtype(ds.dtype) is not None:
        return "\n".join(_text(v) for v in ds[:rows])
    head = ds[: min(rows, ds.shape[0])]
    with np.printoptions(precision=4, threshold=60, edgeitems=2, linewidth=76, suppress=True):
        text = np.array2string(np.asarray(head))
    more = ds.shape[0] - len(head)
    return text + (f"\n… {more} more of {ds.shape[0]}" if more > 0 else "")


def describe(file: h5py.File, path: str) -> str:
    """What the browser shows of one node: kind, shape, unit, attributes (with provenance), preview."""
    obj = file[path]
    lines = [f"[{'dataset' if isinstance(obj, h5py.Dataset) else 'group'}] {obj.name}"]
    if isinstance(obj, h5py.Dataset):
        lines.append(f"shape {obj.shape}, {obj.dtype}")
    else:
        lines.append(f"{len(obj)} members")
    attrs = attributes(obj)
    if attrs:
        lines += ["", "attributes:"] + [f"  {k} = {v}" if "\n" not in v else f"  {k} =\n{v}" for k, v in attrs]
    if isinstance(obj, h5py.Dataset):
        lines += ["", "first values:", preview(obj)]
    return "\n".join(lines)
