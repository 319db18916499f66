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


@pytest.fixture(scope="module")
def recording(tmp_path_factory: pytest.TempPathFactory) -> Path:
    from tests.core.tui.test_screens import make_recording

    return make_recording(tmp_path_factory.mktemp("snap") / "rec.h5")


@pytest.fixture
def file_app(recording: Path) -> MirrorlabApp:
    console = Console.from_file(recording)
    yield MirrorlabApp(console)
    console.close()


@pytest.mark.data  # the list shows retarget_bvh.toml, whose BVH file is in ../shared/data
def test_analysis_form(app: MirrorlabApp, snap_compare, monkeypatch: pytest.MonkeyPatch) -> None:
    # The checkout's recipes, whatever the install: retarget_bvh.toml names its BVH file relative to
    # itself, so from an installed copy it is not listed, and the list's scrollbar would differ.
    monkeypatch.setattr("mirrorlab.core.tui.model.BUNDLED", REPO / "sessions")

    async def choose(pilot) -> None:
        from textual.widgets import OptionList

        await pilot.press("a")
        for _ in range(400):  # until the worker has read the analysis recipes (listed last)
            if pilot.app.screen.recipes:
                break
            await pilot.pause(0.05)
        options = pilot.app.screen.query_one("#algorithms", OptionList)
        options.highlighted = [str(o.prompt) for o in options.options].index("derivatives")
        await pilot.press("enter")
        await pilot.wait_for_scheduled_animations()
        await pilot.pause()
        await pilot.pause()  # the list's scrollbar is laid out again after the recipes were added

    assert snap_compare(app, run_before=choose, terminal_size=(80, 24))


def test_plots(file_app: MirrorlabApp, snap_compare) -> None:
    async def trajectory(pilot) -> None:
        await pilot.press("g")
        for _ in range(400):  # until the worker has read and drawn the first plot
            if getattr(pilot.app.screen, "shown", None) is not None:
                break
            await pilot.pause(0.05)
        await pilot.pause()

    assert snap_compare(file_app, run_before=trajectory, terminal_size=(80, 24))


def test_camera(file_app: MirrorlabApp, snap_compare) -> None:
    async def frame(pilot) -> None:
        await pilot.press("c")
        for _ in range(600):  # until the worker has drawn the frame and its markers
            if "markers" in str(pilot.app.screen.query_one("#status").render()):
                break
            await pilot.pause(0.05)
        await pilot.pause()

    assert snap_compare(file_app, run_before=frame, terminal_size=(80, 24))


def test_snapshot_report_is_written_outside_the_clone(request: pytest.FixtureRequest) -> None:
    """A failing snapshot writes an HTML report: not into the clone, where it would be committed."""
    report = Path(request.config.getoption("--snapshot-report"))
    assert report.is_absolute() and REPO.resolve() not in report.resolve().parents
