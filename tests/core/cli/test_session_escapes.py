"""Text read from a session file reaches the terminal escaped: ``session info`` and ``session tree`` of a
file from another lab whose attributes or names hold ESC / OSC sequences (issue 20)."""

from __future__ import annotations

import json
from pathlib import Path

import h5py
from mirrorlab.core.session import Session

from tests.support import run_cli

#: Clear the screen, retitle the window (OSC 0), and a C1 CSI: what a hostile file could send.
HOSTILE = "ana\x1b[2J\x1b]0;owned\x07\x9b31m"


def _hostile_session(path: Path) -> None:
    with Session.create(path, operator="ana", description="plain"):
        pass
    with h5py.File(path, "r+") as f:  # written by another program: no mirrorlab check on the way
        f.attrs["operator"] = HOSTILE
        f.attrs["description"] = "line one\nline two"
        f.create_group("notes\x1b[8m")


def test_info_and_tree_escape_control_characters(tmp_path: Path) -> None:
    path = tmp_path / "other_lab.h5"
    _hostile_session(path)
    info = run_cli("session", "info", str(path))
    assert info.returncode == 0, info.stderr
    assert "  operator: ana\\x1b[2J\\x1b]0;owned\\x07\\x9b31m\n" in info.stdout
    assert "  description: line one\\x0aline two\n" in info.stdout
    tree = run_cli("session", "tree", str(path))
    assert tree.returncode == 0, tree.stderr
    assert "notes\\x1b[8m/" in tree.stdout
    for out in (info.stdout, tree.stdout):
        assert not any(ord(c) < 0x20 and c != "\n" or 0x7f <= ord(c) < 0xa0 for c in out), out
    # JSON keeps the text as it is (JSON escapes control characters itself)
    data = json.loads(run_cli("session", "info", str(path), "--json").stdout)
    assert data["attributes"]["operator"] == HOSTILE


def test_the_summary_of_run_on_another_labs_session_is_escaped(tmp_path: Path) -> None:
    """``mirrorlab run RECIPE --session FILE`` ends with a summary of FILE's groups and their descriptions."""
    path = tmp_path / "other_lab.h5"
    with Session.create(path) as s:
        s.write_group("report", {"pairs": [1, 2]}, {"description": "summary\x1b]0;owned\x07"})
    recipe = tmp_path / "wait.toml"
    recipe.write_text('[[steps]]\naction = "wait"\nseconds = 0\n')
    proc = run_cli("run", str(recipe), "--session", str(path), "--no-progress")
    assert proc.returncode == 0, proc.stderr
    assert "  /report: 1 dataset (summary\\x1b]0;owned\\x07)\n" in proc.stdout and "\x1b" not in proc.stdout
