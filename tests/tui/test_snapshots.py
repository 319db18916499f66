"""Snapshots (pytest-textual-snapshot) of the key screens at 80×24, on connected but idle simulated
instruments, so nothing on screen depends on time (no clock, no session id, the file's name only)."""

from __future__ import annotations

from pathlib import Path

import pytest
from mirrorlab.core.tui.app import MirrorlabApp
from mirrorlab.core.tui.model import Console

from tests.support import REPO

LOOP = REPO / "sessions" / "follow_loop.toml"


@pytest.fixture
def app(tmp_path: Path) -> MirrorlabApp:
    console = Console.from_recipe(LOOP, tmp_path / "loop.h5")
    yield MirrorlabApp(console)
    console.close()


def test_dashboard(app: MirrorlabApp, snap_compare) -> None:
    assert snap_compare(app, terminal_size=(80, 24))


def test_help(app: MirrorlabApp, snap_compare) -> None:
    assert snap_compare(app, press=["question_mark"], terminal_size=(80, 24))


def test_actuator_detail(app: MirrorlabApp, snap_compare) -> None:
    assert snap_compare(app, press=["down", "enter"], terminal_size=(80, 24))
