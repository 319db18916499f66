"""The console's browser shows a file's names and attributes with control characters escaped: an ESC
or OSC sequence in a file from another lab must not reach the terminal through Textual (issue 20)."""

from __future__ import annotations

from pathlib import Path

import h5py
from mirrorlab.core.session import Session
from mirrorlab.core.tui import browse


def test_names_and_attributes_of_a_hostile_file_are_escaped(tmp_path: Path) -> None:
    path = tmp_path / "other_lab.h5"
    with Session.create(path, operator="ana"):
        pass
    with h5py.File(path, "r+") as f:  # written by another program
        f.attrs["operator"] = "ana\x1b]0;owned\x07"
        f.create_dataset("notes\x1b[8m", data=[1.0, 2.0]).attrs["unit"] = "mm\x1b[2J"
    with Session.open(path) as s:
        root = browse.describe(s, "/")
        node = next(n for n in browse.walk(s) if n.name.startswith("notes"))
        shown = browse.label(node), browse.describe(s, node.path)
    assert "  operator = ana\\x1b]0;owned\\x07\n" in root
    assert shown[0].startswith("notes\\x1b[8m  (2,) float64")
    assert "[dataset] /notes\\x1b[8m\n" in shown[1] and "unit = mm\\x1b[2J" in shown[1]
    for text in (root, *shown):
        assert "\x1b" not in text and "\x07" not in text
