"""The virtual-chain and dexterity screens through Textual's pilot, checked against ground truth.

Every wait is on the screen's state (polled through ``pilot.pause``), bounded by a number of polls.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from mirrorlab.core.tui.app import MirrorlabApp
from mirrorlab.core.tui.model import Console
from mirrorlab.plugins.mechanisms.screen import LENGTH, TILT, DexterityScreen
from mirrorlab.plugins.retarget import Chain, Objective, approximate
from mirrorlab.plugins.retarget.screen import INPUT_LINKS, OUTPUT_LINKS, START, STEP, ChainScreen
from textual.widgets import Static

from tests.core.tui.test_console import LOOP, SIZE, until
from tests.plugins.retarget.optimum import optimum_bounds
from tests.tolerances import roundoff


@pytest.fixture
def app(tmp_path: Path) -> MirrorlabApp:
    console = Console.from_recipe(LOOP, tmp_path / "loop.h5")
    yield MirrorlabApp(console)
    console.close()


async def test_both_screens_are_in_the_command_palette(app: MirrorlabApp) -> None:
    async with app.run_test(size=SIZE) as pilot:
        keys = {(b.binding.key, b.binding.description) for b in app.screen.active_bindings.values()}
        commands = {c.title: c for c in app.get_system_commands(app.screen)}
        commands["Virtual chain"].callback()
        await until(pilot, lambda: isinstance(app.screen, ChainScreen), "the palette opened the chain")
        await pilot.press("escape")
        commands["Dexterity task"].callback()
        await until(pilot, lambda: isinstance(app.screen, DexterityScreen), "the palette opened the task")
        await pilot.press("escape")
        await until(pilot, lambda: not isinstance(app.screen, DexterityScreen), "back on the dashboard")
        await app.run_action("quit")  # stops the dashboard's polling before the test's app goes away
    assert {("v", "Virtual chain"), ("m", "Dexterity task")} <= keys  # the plugins' keys on the dashboard


async def test_virtual_chain_is_retargeted_to_the_optimum_of_each_pose(app: MirrorlabApp) -> None:
    async with app.run_test(size=SIZE) as pilot:
        await pilot.press("v")
        await until(pilot, lambda: isinstance(app.screen, ChainScreen) and app.screen.result is not None,
                    "the first pose is retargeted")
        screen = app.screen
        await pilot.press("up", "up", "right", "down", "right", "right", "up")
        await until(pilot, lambda: screen.result.pose == screen.pose, "the newest pose is retargeted")
        result = screen.result
        expected = np.array(START) + STEP * np.array([2, -1, 0, 1])   # joint 0 up twice, joint 1 down, joint 3 up
        # the screen adds STEP per key press (7 presses): rounding of the sums only
        angle_tol = roundoff(scale=np.abs(expected).max(), ops=8)
        np.testing.assert_allclose(result.angles, expected, rtol=0, atol=angle_tol)
        X = Chain(list(INPUT_LINKS), ["z"] * 4).forward(expected[None])
        output = Chain(list(OUTPUT_LINKS), ["z", "z"])
        batch = approximate(X, output)   # a first frame: the multistart optimum
        # two solves of the same pose: each within its solver's bound of the same minimum
        obj = Objective(output, batch.pairs, batch.input.parents)
        arms, base = obj.arms(X), (np.eye(3), X[:, 0])
        b_screen, b_batch = optimum_bounds(obj, result.q[None], arms, *base), optimum_bounds(obj, batch.q, arms, *base)
        assert result.f == pytest.approx(batch.f[0], abs=b_screen.f[0] + b_batch.f[0])
        np.testing.assert_allclose(np.remainder(result.q - batch.q[0] + np.pi, 2 * np.pi) - np.pi, 0, rtol=0,
                                   atol=b_screen.q[0] + b_batch.q[0])
        # the same forward kinematics of angles equal to rounding: that rounding times the reach, plus
        # the positions' own rounding
        reach = float(np.sum(INPUT_LINKS))
        np.testing.assert_allclose(result.inputs, X[0], rtol=0, atol=reach * angle_tol + roundoff(scale=reach, ops=20))
        status = str(screen.query_one("#chain-status", Static).render())
        assert f"f = {result.f:.4g} mm²" in status
        await pilot.press("escape")
        assert not isinstance(app.screen, ChainScreen)
        await app.run_action("quit")


async def test_dexterity_task_area_is_the_analytic_area_of_the_motion(app: MirrorlabApp) -> None:
    """Tilt the segment about B to horizontal in 30 steps of 3°, then slide it along the x axis to the
    goal: the swept area is the 30 triangles between successive positions, 15 l² sin 3° (the slide
    sweeps none); the optimum is spec §6's (2.4995 for l = 3, scaled by l²)."""
    async with app.run_test(size=SIZE) as pilot:
        await pilot.press("m")
        await until(pilot, lambda: isinstance(app.screen, DexterityScreen), "the task opened")
        screen = app.screen
        await pilot.press(*["down"] * 30)
        await pilot.press(*["left"] * 30)
        await until(pilot, lambda: screen.area_positions == len(screen.a), "the area of the whole motion")
        assert len(screen.a) == 61 and screen.done
        # 30 triangles from cross products of l-long rods 3° apart: each loses 1 / sin 3° of its digits
        area = 15 * LENGTH ** 2 * math.sin(TILT)
        assert screen.area == pytest.approx(area, abs=roundoff(cond=1 / math.sin(TILT), scale=area, ops=40))
        astroid = 3 * math.pi * LENGTH ** 2 / 32
        assert screen.astroid_area == pytest.approx(astroid, abs=roundoff(scale=astroid, ops=4))
        await until(pilot, lambda: screen.best is not None, "the optimal wall is computed", polls=2400)
        # spec §6's positions-only optimum (2.4995 for l = 3): a method figure of the optimiser on its
        # discretisation, with a margin (not rounding)
        assert screen.best.area / (LENGTH / 3) ** 2 == pytest.approx(2.4995, abs=2e-3)

        status = str(screen.query_one("#dex-status", Static).render())
        assert "done" in status and f"{screen.area:9.0f} mm²" in status
        await pilot.press("0")
        assert len(screen.a) == 1 and screen.area == 0.0 and not screen.done
        await app.run_action("quit")
