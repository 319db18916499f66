"""Screens come from plugins (``mirrorlab_register_screens``): a third-party plugin installed like any
other adds one (key, palette, help), a key the dashboard uses is refused with a notice, and the camera
finds its marker detector by the role an algorithm declares, not by its port names."""

from __future__ import annotations

from pathlib import Path

import pytest
from mirrorlab.core import Algorithm, Port, hookimpl
from mirrorlab.core.registry import Registry
from mirrorlab.core.tui.app import MirrorlabApp
from mirrorlab.core.tui.camera import detector
from mirrorlab.core.tui.dialogs import HelpScreen
from mirrorlab.core.tui.model import Console
from textual.widgets import Static

from tests.core.tui.test_console import LOOP, SIZE, until
from tests.support import plugin_site

PLUGIN = '''
from mirrorlab.core import ScreenEntry, hookimpl
from textual.screen import Screen
from textual.widgets import Static


class HelloScreen(Screen):
    BINDINGS = [("escape", "app.pop_screen", "Back")]

    def compose(self):
        yield Static(f"hello from a plugin: {len(self.app.model.sources)} sources", id="hello")


@hookimpl
def mirrorlab_register_screens():
    return [ScreenEntry("hellotui_hello", "h", "Hello", "a third-party screen", f"{__name__}:HelloScreen"),
            ScreenEntry("hellotui_again", "p", "Hello again", "one whose key the dashboard uses", f"{__name__}:HelloScreen"),
            ScreenEntry("hellotui_gone", "j", "Gone", "one whose class is missing", f"{__name__}:Missing")]
'''


@pytest.fixture(scope="module")
def hello_site(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return plugin_site(PLUGIN, "mirrorlab-hellotui", "hellotui", tmp_path_factory.mktemp("hellotui-src"),
                       tmp_path_factory.mktemp("hellotui-site"))


async def test_a_third_party_plugin_adds_a_screen(hello_site: Path, with_sites, tmp_path: Path) -> None:
    with_sites(hello_site)
    console = Console.from_recipe(LOOP, tmp_path / "loop.h5")
    app = MirrorlabApp(console)
    try:
        async with app.run_test(size=SIZE) as pilot:
            await pilot.press("h")
            await until(pilot, lambda: type(app.screen).__name__ == "HelloScreen", "the plugin's screen opened")
            assert str(app.screen.query_one("#hello", Static).render()) == "hello from a plugin: 3 sources"
            await pilot.press("escape")
            commands = {c.title: c for c in app.get_system_commands(app.screen)}
            assert commands["Hello"].help == "a third-party screen (h)"
            assert commands["Hello again"].help == "one whose key the dashboard uses"  # palette only
            assert app.screen_problems == ["screen 'Hello again': the key 'p' is taken by 'Preview'; "
                                           "open it from the palette (ctrl+p)"]
            commands["Hello again"].callback()
            await until(pilot, lambda: type(app.screen).__name__ == "HelloScreen", "the palette opened it")
            await pilot.press("escape")
            await pilot.press("j")  # a broken screen: a dialog that names it, the console goes on
            await until(pilot, lambda: getattr(app.screen, "title_text", "") == "Could not open Gone", "the error")
            assert "hellotui_mirrorlab:Missing: AttributeError" in app.screen.body
            await pilot.press("escape")
            await pilot.press("question_mark")
            await until(pilot, lambda: isinstance(app.screen, HelpScreen), "the help")
            assert "[b]h     [/b] a third-party screen" in app.screen.body
            assert "[b]ctrl+p[/b] one whose key the dashboard uses" in app.screen.body
            await pilot.press("escape")
            await app.run_action("quit")
    finally:
        console.close()


class FramesToXY(Algorithm):
    """The ports of a marker detector, without saying it is one."""

    name, version, description = "frames_to_xy", "1.0", "something else that maps frames to points"
    inputs = (Port("frames", "(F, H, W) frames"),)
    outputs = (Port("xy", "(F, K, 2) points", "px"),)

    def run(self, inputs, params, context):
        raise AssertionError("the camera must not run this")


class Lookalike:
    @hookimpl
    def mirrorlab_register_algorithms(self):
        return [FramesToXY]


def test_the_camera_finds_its_detector_by_the_declared_role() -> None:
    lookalike = Registry(entry_points=False, builtins=False)
    lookalike.add_plugin(Lookalike(), "lookalike")
    assert detector(lookalike) is None  # the right port names are not a declaration
    builtins = Registry(entry_points=False)
    assert detector(builtins).name == "detect_markers"

    class Claims(FramesToXY):
        name, roles = "claims_to_detect", ("marker_detector",)
        outputs = (Port("points", "(F, K, 2) points", "px"),)

    class ClaimsPlugin:
        @hookimpl
        def mirrorlab_register_algorithms(self):
            return [Claims]

    info = lookalike.add_plugin(ClaimsPlugin(), "claims")
    assert info.error == ("plugin 'claims': algorithm 'claims_to_detect' declares the role 'marker_detector' "
                          "but has no output 'xy'")
