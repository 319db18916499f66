"""The console's analysis, browser, plots and camera screens, connect / disconnect and the
themes, through Textual's pilot on real session files and simulated instruments.

Every wait is on the session's state or the screen, bounded by a number of polls (see ``until``).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from mirrorlab.core import Algorithm, Port, Session, hookimpl
from mirrorlab.core.registry import Registry
from mirrorlab.core.tui.analysis import AnalysisScreen
from mirrorlab.core.tui.app import SCREENS, MirrorlabApp
from mirrorlab.core.tui.browser import BrowserScreen
from mirrorlab.core.tui.camera import CameraScreen
from mirrorlab.core.tui.detail import SourceScreen
from mirrorlab.core.tui.dialogs import ErrorDialog
from mirrorlab.core.tui.model import Console
from mirrorlab.core.tui.plots import PlotsScreen
from textual.widgets import OptionList, Select, Static, Tree

from tests.core.tui.test_console import LOOP, SIZE, until

FRAMES = 6


def make_recording(path: Path, registry: Registry | None = None) -> Path:
    """A closed session: a virtual-lab camera (6 frames of the RSSR scene), an angle sensor, a
    marker trajectory (mm) and its derivatives (a velocity in mm/s, a smoothed angle in rad)."""
    with Session.create(path, description="screens", registry=registry) as s:
        s.add_instrument("cam", "film_scanner", settings={"source": "virtual", "scene": "rssr",
                                                          "scene_frames": FRAMES, "frame_rate": "30 Hz"})
        s.add_instrument("sensor", "angle_source", simulate=True)
        s.record(instruments=["cam"])  # until the camera's film ends
        s.record(0.3, instruments=["sensor"])
        t = np.arange(50) / 50.0
        s.write_group("markers/walk", {"time": t, "xyz": np.stack([np.stack([100 * t, 50 * t ** 2, 0 * t], -1)] * 2, 1)},
                      {"unit": "mm", "time_unit": "s"})  # as a marker set: the units on its group
        s.run("derivatives", {"time": "/markers/walk/time", "values": "/markers/walk/xyz"})
        times, _ = s.stream("sensor", "angle")
        s.run("derivatives", {"time": "/instruments/sensor/angle/time", "values": "/instruments/sensor/angle/data"})
        assert len(times) > 2
    return path


@pytest.fixture(scope="module")
def recording(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return make_recording(tmp_path_factory.mktemp("screens") / "rec.h5")


class WaitForCancel(Algorithm):
    """Reports progress until it is cancelled (a run that only ends on request)."""

    name, version, description = "wait_for_cancel", "1.0", "counts until cancelled (a test of the console)"
    inputs = (Port("values", "(T,) anything"),)
    outputs = (Port("count", "(1,) progress reports made"),)

    def run(self, inputs, params, context):
        for i in range(100_000):
            context.progress(i, None, f"waiting {i}")
            context.cancel.wait(0.01)
        return {"count": np.array([i])}


class WaitPlugin:
    @hookimpl
    def mirrorlab_register_algorithms(self):
        return [WaitForCancel]


async def test_screens_open_by_key_and_from_the_palette(recording: Path) -> None:
    console = Console.from_file(recording)
    app = MirrorlabApp(console)
    try:
        async with app.run_test(size=SIZE) as pilot:
            titles = [c.title for c in app.get_system_commands(app.screen)]
            assert {e.title for e in SCREENS} <= set(titles) and "Light / dark" in titles
            for key, cls in (("a", AnalysisScreen), ("b", BrowserScreen), ("g", PlotsScreen), ("c", CameraScreen)):
                await pilot.press(key)
                assert isinstance(app.screen, cls)
                await pilot.press("escape")
                assert app.screen is app.screen_stack[0]
            await pilot.press("t")  # a file has no steps: a notice, no screen
            assert app.screen is app.screen_stack[0]
    finally:
        console.close()


async def test_browser_shows_the_tree_attributes_provenance_and_previews(recording: Path) -> None:
    console = Console.from_file(recording)
    app = MirrorlabApp(console)
    try:
        async with app.run_test(size=SIZE) as pilot:
            await pilot.press("b")
            tree = app.screen.query_one("#tree", Tree)
            await until(pilot, lambda: len(tree.root.children) > 0, "the tree is read")
            detail = app.screen.query_one("#detail", Static)
            labels = {str(n.label) for n in tree.root.children}
            assert {"instruments", "results", "config"} <= labels
            results = next(n for n in tree.root.children if str(n.label) == "results")
            results.expand()
            results.children[0].expand()
            run = results.children[0].children[0]  # /results/derivatives/run-0001
            run.expand()
            await pilot.pause()
            tree.move_cursor(run)
            await until(pilot, lambda: "run-0001" in str(detail.render()), "the run's attributes")
            text = str(detail.render())
            assert "parameters =" in text and '"values": "/markers/walk/xyz"' in text  # provenance, pretty
            velocity = next(c for c in run.children if c.data.name == "velocity")
            assert "mm/s" in str(velocity.label)
            tree.move_cursor(velocity)
            await until(pilot, lambda: "first values:" in str(detail.render()), "the dataset preview")
            assert "shape (50, 2, 3), float64" in str(detail.render())
    finally:
        console.close()


async def test_analysis_runs_an_algorithm_from_its_form_and_shows_the_result(recording: Path, tmp_path: Path) -> None:
    path = tmp_path / "copy.h5"
    path.write_bytes(recording.read_bytes())
    console = Console.from_file(path)
    app = MirrorlabApp(console)
    try:
        async with app.run_test(size=SIZE) as pilot:
            await pilot.press("a")
            screen = app.screen
            assert isinstance(screen, AnalysisScreen)
            await until(pilot, lambda: bool(screen.paths), "the datasets are read")
            algorithms = screen.query_one("#algorithms", OptionList)
            algorithms.highlighted = [str(o.prompt) for o in algorithms.options].index("detect_markers")
            await pilot.press("enter")
            await until(pilot, lambda: bool(screen.query("#input-frames")), "the form is built")
            assert screen.query_one("#input-frames", Select).value == "/instruments/cam/frames/data"  # guessed
            screen.query_one("#param-min_area").value = "-1"
            await pilot.press("ctrl+r")
            await pilot.pause()
            assert console.running is None  # refused: min_area below its minimum
            screen.query_one("#param-min_area").value = "4"
            await pilot.press("ctrl+r")
            result = screen.query_one("#result", Static)
            await until(pilot, lambda: ": ok" in str(result.render()), "the result shows", polls=1200)
            text = str(result.render())
            assert "xy  (6," in text and '"min_area": 4.0' in text and '"frames": "/instruments/cam/frames/data"' in text
            assert not console.session.writable  # written only while the run ran, read-only again
    finally:
        console.close()
    with Session.open(path) as s:
        run = s.result(s.results("detect_markers")[-1])
        assert run.ref.status == "ok" and run.attrs["parameters"]["min_area"] == 4.0
        assert run.outputs["xy"].shape[0] == FRAMES


async def test_analysis_run_cancelled_with_x_is_stored_as_cancelled(tmp_path: Path) -> None:
    registry = Registry()
    registry.add_plugin(WaitPlugin(), "wait")  # a third-party algorithm appears by itself
    path = tmp_path / "cancel.h5"
    with Session.create(path, registry=registry) as s:
        s.write_group("data", {"values": np.arange(5.0)})
    console = Console(Session.open(path, writable=True, registry=registry))
    app = MirrorlabApp(console)
    try:
        async with app.run_test(size=SIZE) as pilot:
            await pilot.press("a")
            screen = app.screen
            await until(pilot, lambda: bool(screen.paths), "the datasets are read")
            algorithms = screen.query_one("#algorithms", OptionList)
            algorithms.highlighted = [str(o.prompt) for o in algorithms.options].index("wait_for_cancel")
            await pilot.press("enter")
            await until(pilot, lambda: bool(screen.query("#input-values")), "the form is built")
            screen.query_one("#input-values", Select).value = "/data/values"
            screen.query_one("#input-values", Select).focus()
            await pilot.press("ctrl+r")
            status = screen.query_one("#status", Static)
            await until(pilot, lambda: "waiting" in str(status.render()), "the progress shows")
            await pilot.press("x")
            result = screen.query_one("#result", Static)
            await until(pilot, lambda: "cancelled" in str(result.render()), "the run is cancelled")
            assert console.running is None
    finally:
        console.close()
    with Session.open(path) as s:
        assert [r.status for r in s.results("wait_for_cancel")] == ["cancelled"]


async def test_plots_find_trajectories_velocities_and_angles(recording: Path) -> None:
    console = Console.from_file(recording)
    app = MirrorlabApp(console)
    try:
        async with app.run_test(size=SIZE) as pilot:
            await pilot.press("g")
            select = app.screen.query_one("#what", Select)
            await until(pilot, lambda: select.value != Select.NULL, "the datasets are found")
            labels = [str(prompt) for prompt, _ in select._options]
            kinds = {label.split(":")[0] for label in labels}
            assert {"trajectories", "velocities", "joint angles", "tracker angles"} <= kinds, labels
            assert "trajectories: /results/derivatives/run-0001/smoothed" in labels
            select.value = "/instruments/sensor/angle/data"
            screen = app.screen
            await until(pilot, lambda: screen.shown is not None and screen.shown.path == select.value, "the plot")
            assert screen.shown.kind == "tracker angles" and screen.shown.xlabel == "session time (s)"
            assert screen.shown.ylabel == "data (deg)"  # radians shown in degrees
            select.value = "/results/derivatives/run-0001/smoothed"
            await until(pilot, lambda: screen.shown.path == select.value, "the trajectory plot")
            assert (screen.shown.xlabel, screen.shown.ylabel) == ("x (mm)", "y (mm)")
            x, y, _ = screen.shown.lines[0]
            # the parabola y = 50 t², x = 100 t as plotted: a check of what is shown, to a millimetre (the
            # GCV spline's bias on these noise-free samples is far below it), not of the smoother
            assert np.allclose(y, 0.005 * x ** 2, atol=1.0)
    finally:
        console.close()


async def test_camera_shows_a_recorded_frame_with_its_markers(recording: Path) -> None:
    console = Console.from_file(recording)
    app = MirrorlabApp(console)
    try:
        async with app.run_test(size=SIZE) as pilot:
            await pilot.press("c")
            status = app.screen.query_one("#status", Static)
            await until(pilot, lambda: "markers" in str(status.render()), "the frame is drawn", polls=600)
            assert f"cam/frames frame {FRAMES}/{FRAMES}" in str(status.render()) and "(detect_markers)" in str(status.render())
            count = int(str(status.render()).split(" markers")[0].rsplit(" ", 1)[-1])
            assert count > 0
            await pilot.press("home")
            await until(pilot, lambda: f"frame 1/{FRAMES}" in str(status.render()), "the first frame")
            lines = app.screen.query_one("#frame", Static).render()
            assert lines is not None
    finally:
        console.close()


async def test_disconnect_and_connect_from_the_detail_screen(tmp_path: Path) -> None:
    console = Console.from_recipe(LOOP, tmp_path / "loop.h5")
    app = MirrorlabApp(console)
    sensor = console.session.instruments["sensor"]
    try:
        async with app.run_test(size=SIZE) as pilot:
            await pilot.press("enter")
            assert isinstance(app.screen, SourceScreen) and app.screen.source == "sensor"
            await pilot.press("ctrl+o")
            await until(pilot, lambda: "sensor" in console.disconnected, "the sensor is disconnected")
            assert sensor.state == "stopped"
            await pilot.press("escape", "p")  # the others preview; the disconnected one stays off
            await until(pilot, lambda: console.session.instruments["actuator"].state == "acquiring", "the preview")
            assert sensor.state == "stopped"
            await pilot.press("s")
            await until(pilot, lambda: not console.session.acquiring, "stopped")
            await pilot.press("enter", "ctrl+o")
            await until(pilot, lambda: sensor.state == "idle" and "sensor" not in console.disconnected, "connected")
            await pilot.press("escape", "p")
            await until(pilot, lambda: len(console.streams[("sensor", "angle")].values) > 3, "it streams again")
            await app.run_action("quit")
    finally:
        console.close()


async def test_theme_switches_between_light_and_dark(tmp_path: Path) -> None:
    console = Console.from_recipe(LOOP, tmp_path / "loop.h5")
    app = MirrorlabApp(console)
    try:
        async with app.run_test(size=SIZE) as pilot:
            assert app.theme == "textual-dark"
            await pilot.press("d")
            assert app.theme == "textual-light"
            await pilot.press("d")
            assert app.theme == "textual-dark"
    finally:
        console.close()


async def test_ctrl_q_stops_and_closes_the_session_file(tmp_path: Path) -> None:
    console = Console.from_recipe(LOOP, tmp_path / "quit.h5")
    app = MirrorlabApp(console)
    async with app.run_test(size=SIZE) as pilot:
        await pilot.press("p")
        await until(pilot, lambda: console.session.acquiring, "acquiring")
        await pilot.press("ctrl+q")  # the key itself, as the operator presses it
    assert console.closed and app.return_code == 0
    with Session.open(tmp_path / "quit.h5") as s:
        assert s.status == "closed"


async def test_camera_follows_the_live_frames_of_a_preview(tmp_path: Path) -> None:
    session = Session.create(tmp_path / "live.h5")
    session.add_instrument("cam", "film_scanner", settings={"source": "virtual", "scene": "rssr",
                                                            "scene_frames": 100_000, "frame_rate": "10 Hz"})
    console = Console(session)
    app = MirrorlabApp(console)
    try:
        async with app.run_test(size=SIZE) as pilot:
            await pilot.press("c")
            status = app.screen.query_one("#status", Static)
            await until(pilot, lambda: "press p (preview)" in str(status.render()), "the hint")
            await pilot.press("p")
            await until(pilot, lambda: "markers (detect_markers)" in str(status.render()), "a live frame", polls=600)
            first = str(status.render()).split(" at ")[1].split(" s")[0]
            await until(pilot, lambda: str(status.render()).split(" at ")[1].split(" s")[0] != first, "the next frame")
            await app.run_action("quit")
    finally:
        console.close()


@pytest.mark.slow
async def test_demo_flow_record_then_reconstruct_then_plots(tmp_path: Path) -> None:
    """What a newcomer does: open the demo recipe, record, stop, run the demo's analysis recipe
    (a 3-D reconstruction) from the analysis screen, and look at its trajectories."""
    from mirrorlab.core.cli.run_cmd import DEMO_ACQUIRE

    console = Console.from_recipe(DEMO_ACQUIRE, tmp_path / "demo.h5")
    app = MirrorlabApp(console)
    session = console.session
    try:
        async with app.run_test(size=SIZE) as pilot:
            await pilot.press("r")
            await until(pilot, lambda: session.recording, "recording")
            await until(pilot, lambda: all(i.state != "acquiring" for i in session.instruments.values()),
                        "the films end", polls=2000)
            if session.recording:
                await pilot.press("r")
            await until(pilot, lambda: not session.recording, "the recording stopped")
            await pilot.press("a")
            await until(pilot, lambda: isinstance(app.screen, AnalysisScreen) and bool(app.screen.query("#algorithms")),
                        "the analysis screen is shown")
            screen = app.screen
            options = screen.query_one("#algorithms", OptionList)
            await until(pilot, lambda: "recipe:rssr_analysis.toml" in [o.id for o in options.options], "the recipes")
            options.highlighted = [o.id for o in options.options].index("recipe:rssr_analysis.toml")
            await pilot.press("enter", "ctrl+r")
            result = screen.query_one("#result", Static)
            await until(pilot, lambda: "results stored" in str(result.render()), "the analysis ran", polls=4000)
            assert "/results/reconstruct_mirror/run-0001: ok" in str(result.render())
            stored = len(session.results())
            await pilot.press("ctrl+r")  # again: its calibration group is taken, so nothing runs
            await until(pilot, lambda: isinstance(app.screen, ErrorDialog), "the error dialog")
            assert "steps.3.camera: /calibration/cam already exists" in app.screen.body
            assert "fresh copy of the recording" in app.screen.body and len(session.results()) == stored
            await pilot.press("escape")
            await pilot.press("escape", "g")
            select = app.screen.query_one("#what", Select)
            await until(pilot, lambda: app.screen.shown is not None, "a plot")
            assert app.screen.shown.kind == "trajectories"
            assert any(str(p).startswith("trajectories: /results/reconstruct_mirror/") for p, _ in select._options)
            await app.run_action("quit")
    finally:
        console.close()
