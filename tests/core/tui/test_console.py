"""The operator console through Textual's pilot: real simulated instruments, real session files.

Every wait is on the session's state or the screen (polled through ``pilot.pause``), bounded by a
number of polls, never a sleep against a finite source.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path

import pytest
from mirrorlab.core import Session
from mirrorlab.core.tui.app import MirrorlabApp
from mirrorlab.core.tui.detail import SourceScreen, StreamPlot
from mirrorlab.core.tui.dialogs import FaultDialog, HelpScreen
from mirrorlab.core.tui.model import Console
from mirrorlab.core.tui.steps import StepsScreen
from textual.pilot import Pilot
from textual.widgets import Input, Static

from tests.support import REPO
from tests.tolerances import roundoff

LOOP = REPO / "sessions" / "follow_loop.toml"
SIZE = (80, 24)


async def until(pilot: Pilot, condition: Callable[[], bool], what: str, polls: int = 400) -> None:
    """Let the app run until ``condition()`` holds (checked every 50 ms of app time, at most ``polls`` times)."""
    for _ in range(polls):
        if condition():
            return
        await pilot.pause(0.05)
    raise AssertionError(f"timed out waiting until {what}")


@pytest.fixture
def loop_console(tmp_path: Path) -> Console:
    console = Console.from_recipe(LOOP, tmp_path / "loop.h5", ["instruments.sensor.reconnect=3"])
    yield console
    console.close()


async def test_preview_record_stop_and_quit_close_the_file(loop_console: Console) -> None:
    app = MirrorlabApp(loop_console)
    session = loop_console.session
    async with app.run_test(size=SIZE) as pilot:
        assert not session.acquiring and not session.recording  # opened: connected, nothing recorded
        await pilot.press("p")
        await until(pilot, lambda: len(loop_console.streams[("sensor", "angle")].values) > 20, "the angle streams")
        assert not session.recording
        await pilot.press("r")
        await until(pilot, lambda: app.snapshot is not None and app.snapshot.instruments["sensor"].samples > 50,
                    "the recording has samples")
        assert "RECORDING" in str(app.query_one("#info", Static).render())
        await pilot.press("r")
        await until(pilot, lambda: not session.recording, "the recording stopped")
        assert session.acquiring  # acquisition goes on after the recording
        await pilot.press("s")
        await until(pilot, lambda: not session.acquiring, "acquisition stopped")
        await app.run_action("quit")  # what ctrl+q does
    assert ("ctrl+q", "quit") in [(b.key, b.action) for b in MirrorlabApp.BINDINGS]
    assert loop_console.closed and app.return_code == 0
    with Session.open(session.path) as s:
        assert s.status == "closed"
        times, angle = s.stream("sensor", "angle")
        assert len(angle) > 50 and s.attributes("instruments/sensor/angle")["dropped"] == 0
        assert len(s.stream("loop", "latency").data) > 0  # the controller ran and was recorded


async def test_set_point_from_the_detail_form_is_validated_and_acknowledged(loop_console: Console) -> None:
    app = MirrorlabApp(loop_console)
    actuator = loop_console.session.instruments["actuator"]
    async with app.run_test(size=SIZE) as pilot:
        await pilot.press("down", "enter")  # the second row: the actuator
        await until(pilot, lambda: isinstance(app.screen, SourceScreen), "the detail screen opened")
        assert app.screen.source == "actuator"
        assert [p.stream for p in app.screen.query(StreamPlot)] == ["position"]  # one live plot per scalar stream
        field = app.screen.query_one("#param-target", Input)
        assert not field.disabled and app.screen.query_one("#param-speed", Input).disabled  # only live ones edit
        field.value = "9 rad"
        await pilot.pause()
        problem = app.screen.query_one("#problem-target", Static)
        assert "above the maximum" in str(problem.render())  # validated as typed, nothing sent
        assert actuator.settings["target"] == 0.0
        field.value = "5 deg"
        field.focus()
        await pilot.press("enter")
        # 5 deg converted to rad: a product, rounded
        acked = roundoff(scale=math.radians(5), ops=2)
        await until(pilot, lambda: abs(actuator.settings["target"] - math.radians(5)) <= acked, "the set-point acked")
        assert str(problem.render()) == ""
        await pilot.press("escape")
        assert not isinstance(app.screen, SourceScreen)


async def test_unplugged_device_shows_its_reconnect_countdown_then_failure(loop_console: Console) -> None:
    app = MirrorlabApp(loop_console)
    async with app.run_test(size=SIZE) as pilot:
        await pilot.press("p")
        await until(pilot, lambda: len(loop_console.streams[("sensor", "angle")].values) > 5, "the angle streams")
        loop_console.session.simulator("sensor").close()  # unplugged for good
        await until(pilot, lambda: isinstance(app.screen, FaultDialog), "the fault dialog opened")
        body = app.screen.query_one("#body", Static)
        await until(pilot, lambda: "s left of its reconnect budget" in str(body.render()), "the countdown shows")
        assert "Check the cable and the power" in str(body.render())
        await until(pilot, lambda: "has failed" in str(body.render()), "the budget ran out")
        assert "press p to acquire again" in str(body.render())
        assert "Traceback" not in str(body.render())
        await pilot.press("escape")
        assert not isinstance(app.screen, FaultDialog)
        assert loop_console.session.instruments["actuator"].state == "acquiring"  # the others keep going


async def test_recipe_steps_run_with_progress_and_cancel(tmp_path: Path) -> None:
    console = Console.from_recipe(LOOP, tmp_path / "steps.h5", ["steps.1.seconds=600"])
    app = MirrorlabApp(console)
    try:
        async with app.run_test(size=SIZE) as pilot:
            await pilot.press("t")
            assert isinstance(app.screen, StepsScreen)
            assert app.screen.query_one("#steps").row_count == 2
            await pilot.press("enter")  # run from the first step: preview 1 s, then acquire 600 s
            await until(pilot, lambda: console.current_step is not None and console.current_step.action == "acquire"
                        and console.session.recording, "the acquire step records")
            status = app.screen.query_one("#status", Static)
            await until(pilot, lambda: "running step 1: acquire" in str(status.render()), "the running step shows")
            await until(pilot, lambda: (app.screen.query_one("#progress").progress or 0) > 0, "progress moves")
            await pilot.press("x")
            await until(pilot, lambda: console.current_step is None and not console.session.recording,
                        "the step ended on request")
            await pilot.press("escape")
            await app.run_action("quit")
    finally:
        console.close()
    with Session.open(tmp_path / "steps.h5") as s:
        assert s.status == "closed" and len(s.stream("sensor", "angle").data) > 0
        steps = [e["message"] for e in s.log() if e["kind"] == "step"]
    assert steps == ["step 0: preview", "step 1: acquire"]


async def test_help_and_every_action_in_the_command_palette(loop_console: Console) -> None:
    app = MirrorlabApp(loop_console)
    async with app.run_test(size=SIZE) as pilot:
        await pilot.press("question_mark")
        assert isinstance(app.screen, HelpScreen)
        await pilot.press("escape")
        assert not isinstance(app.screen, HelpScreen)
        titles = [c.title for c in app.get_system_commands(app.screen)]
        # every key's action (the plugins' screens' keys too) is in the palette too
        keyed = {b.binding.description for b in app.screen.active_bindings.values()
                 if b.node is app and b.binding.action != "command_palette"}  # ctrl+p opens the palette itself
    assert {"Help", "Preview", "Record", "Stop", "Steps", "Analysis", "Browse", "Plots", "Camera", "Virtual chain",
            "Dexterity task", "Quit"} <= keyed
    assert keyed <= set(titles) and titles.count("Quit") == 1
    assert {"Open sensor", "Open actuator", "Open loop"} <= set(titles)


async def test_a_session_file_opens_for_browsing_and_analysis(tmp_path: Path) -> None:
    path = tmp_path / "rec.h5"
    with Session.create(path, description="browsed") as s:
        s.add_instrument("sensor", "angle_source", simulate=True)
        s.record(0.3)
    console = Console.from_file(path)
    app = MirrorlabApp(console)
    try:
        async with app.run_test(size=SIZE) as pilot:
            await pilot.pause()
            assert "a analysis, b browse, g plots" in str(app.query_one("#info", Static).render())
            lines = [str(line.text) for line in app.query_one("#log").lines]
            assert any(line.startswith("sensor/angle: ") and "samples rad" in line for line in lines), lines
            await pilot.press("r")  # refused with a notice, nothing raised
            assert not console.session.recording
    finally:
        console.close()
    with Session.open(path) as s:
        assert s.status == "closed"  # opened writable for analysis, left as it was
