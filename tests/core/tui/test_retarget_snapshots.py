"""Snapshots (pytest-textual-snapshot) of the virtual-chain and dexterity screens at 80×24, each taken
once its worker's result is on screen (nothing shown depends on time)."""

from __future__ import annotations

from pathlib import Path

import pytest
from mirrorlab.core.tui.app import MirrorlabApp
from mirrorlab.core.tui.model import Console
from mirrorlab.plugins.mechanisms.screen import DexterityScreen
from mirrorlab.plugins.retarget.screen import ChainScreen
from textual.pilot import Pilot

from tests.core.tui.test_console import LOOP, until


@pytest.fixture
def app(tmp_path: Path) -> MirrorlabApp:
    console = Console.from_recipe(LOOP, tmp_path / "loop.h5")
    yield MirrorlabApp(console)
    console.close()


def test_virtual_chain(app: MirrorlabApp, snap_compare) -> None:
    async def turned(pilot: Pilot) -> None:
        await pilot.press("v", "up", "up", "right", "down")
        await until(pilot, lambda: isinstance(app.screen, ChainScreen) and app.screen.result is not None
                    and app.screen.result.pose == app.screen.pose, "the newest pose is retargeted")

    assert snap_compare(app, run_before=turned, terminal_size=(80, 24))


def test_dexterity_task(app: MirrorlabApp, snap_compare) -> None:
    async def moved(pilot: Pilot) -> None:
        await pilot.press("m", *["left", "down", "down"] * 5)
        screen = app.screen
        assert isinstance(screen, DexterityScreen)
        await until(pilot, lambda: screen.best is not None and screen.area_positions == len(screen.a),
                    "the optimum and the swept area are computed", polls=2400)

    assert snap_compare(app, run_before=moved, terminal_size=(80, 24))
