"""Every hook goes through pluggy: lifecycle and CLI hooks in pluggy's order, wrapped by hook
wrappers, one failing plugin reported while the others run; the screen hook and the CLI hook's
typed command table."""

from __future__ import annotations

import argparse
import inspect
import typing
from collections.abc import Iterator
from pathlib import Path

import pytest
from mirrorlab.core import ScreenEntry, Session, Subcommands, hookimpl
from mirrorlab.core import hookspecs as specs
from mirrorlab.core.registry import Registry


def _registry(*plugins: object) -> Registry:
    """A registry of only ``plugins`` (named by their class), added in this order."""
    reg = Registry(entry_points=False, builtins=False)
    for plugin in plugins:
        info = reg.add_plugin(plugin, type(plugin).__name__.lower())
        assert info.ok, info.error
    return reg


class Recorder:
    """Lifecycle plugins that write what they see into one shared list."""

    def __init__(self) -> None:
        self.calls: list[str] = []

    def plugins(self) -> tuple[object, ...]:
        calls = self.calls

        class Last:
            @hookimpl(trylast=True)
            def mirrorlab_session_closing(self, session: Session, status: str) -> None:
                calls.append(f"last {status}")

        class First:
            @hookimpl(tryfirst=True)
            def mirrorlab_session_closing(self, session: Session, status: str) -> None:
                calls.append(f"first {status}")

        class Plain:
            @hookimpl
            def mirrorlab_session_closing(self, status: str) -> None:  # a subset of the parameters
                calls.append(f"plain {status}")

        class Wrapper:
            @hookimpl(wrapper=True)
            def mirrorlab_session_closing(self, session: Session) -> Iterator[None]:
                calls.append("wrap>")
                try:
                    return (yield)
                except RuntimeError as exc:
                    calls.append(f"wrapper saw {exc}")
                    raise
                finally:
                    calls.append("<wrap")

        # registered trylast first and tryfirst before the plain one: only pluggy's order puts them right
        return Last(), First(), Plain(), Wrapper()


def test_lifecycle_hooks_run_in_pluggy_order_each_inside_the_wrappers(tmp_path: Path) -> None:
    recorder = Recorder()
    reg = _registry(*recorder.plugins())
    with Session.create(tmp_path / "order.h5", registry=reg):
        pass
    assert recorder.calls == ["wrap>", "first closed", "<wrap", "wrap>", "plain closed", "<wrap",
                              "wrap>", "last closed", "<wrap"]


def test_a_raising_implementation_is_reported_and_the_others_still_run(tmp_path: Path) -> None:
    recorder = Recorder()
    calls = recorder.calls

    class Boom:
        @hookimpl
        def mirrorlab_session_closing(self, status: str) -> None:
            calls.append("boom")
            raise RuntimeError("disk on fire")

    last, first, plain, wrapper = recorder.plugins()
    reg = _registry(last, first, Boom(), plain, wrapper)  # plain registered after boom: called before it
    path = tmp_path / "boom.h5"
    with Session.create(path, registry=reg):
        pass
    assert [c for c in calls if c not in ("wrap>", "<wrap")] == [
        "first closed", "plain closed", "boom", "wrapper saw disk on fire", "last closed"]
    with Session.open(path) as s:
        assert s.status == "closed"  # the session closed as if nothing happened
        errors = [e for e in s.log() if e["kind"] == "plugin_error"]
    assert [(e["level"], e["message"]) for e in errors] == [
        ("warning", "plugin 'boom' failed in mirrorlab_session_closing: RuntimeError: disk on fire")]


def test_notify_reports_each_failing_plugin_once_and_never_raises() -> None:
    class Broken:
        @hookimpl
        def mirrorlab_recording_started(self, session: object) -> None:
            raise ValueError("no")

    class Fine:
        seen: list[object] = []

        @hookimpl
        def mirrorlab_recording_started(self, session: object) -> None:
            self.seen.append(session)

    reg = _registry(Broken(), Fine())
    assert reg.notify("mirrorlab_recording_started", session="s") == [
        "plugin 'broken' failed in mirrorlab_recording_started: ValueError: no"]
    assert Fine.seen == ["s"]
    assert reg.notify("mirrorlab_recording_started", plugins=["fine"], session="t") == [] and Fine.seen == ["s", "t"]


# -- the CLI hook ----------------------------------------------------------------------------------
def test_the_cli_hook_gets_a_typed_command_table_not_argparse_internals() -> None:
    hints = typing.get_type_hints(specs.mirrorlab_add_cli_commands, vars(specs) | {"Subcommands": Subcommands})
    assert hints["subparsers"] is Subcommands
    assert "_SubParsersAction" not in inspect.getsource(specs)

    class Adds:
        @hookimpl
        def mirrorlab_add_cli_commands(self, subparsers: Subcommands) -> None:
            p = subparsers.add_parser("hello", help="say hello")
            p.set_defaults(func=lambda args: 0)

    class Clashes:
        @hookimpl(trylast=True)
        def mirrorlab_add_cli_commands(self, subparsers: Subcommands) -> None:
            subparsers.add_parser("hello", help="another hello")

    reg = _registry(Adds(), Clashes())
    action = argparse.ArgumentParser(prog="mirrorlab").add_subparsers()
    table = Subcommands(action, ["hello"])
    assert reg.notify("mirrorlab_add_cli_commands", subparsers=table) == [
        "plugin 'clashes' failed in mirrorlab_add_cli_commands: ValueError: a command named 'hello' already exists"]
    assert "hello" in table and action.choices["hello"].get_default("func") is not None


# -- the screen hook -------------------------------------------------------------------------------
def test_screens_are_registered_through_their_hook_and_checked() -> None:
    entry = ScreenEntry("acme_trend", "f5", "ACME trend", "the thermometer's trend", "acme_mirrorlab.screen:Trend")

    class Screens:
        @hookimpl
        def mirrorlab_register_screens(self) -> list[ScreenEntry]:
            return [entry]

    class Wrong:
        @hookimpl
        def mirrorlab_register_screens(self) -> list[object]:
            return ["acme_mirrorlab.screen:Trend"]

    reg = _registry(Screens())
    assert reg.names("screen") == ["acme_trend"] and reg.get("screen", "acme_trend") is entry
    assert reg.installed()["screens"].provides == {"screen": ["acme_trend"]}
    info = reg.add_plugin(Wrong(), "wrong")
    assert info.error == ("plugin 'wrong': mirrorlab_register_screens returned 'acme_mirrorlab.screen:Trend', which is "
                          "not a ScreenEntry; screens are declared as mirrorlab.core.tui.screens.ScreenEntry(name, key, "
                          "title, help, target)")
    with pytest.raises(ValueError, match=r"screen 'x': target 'Trend' is not \"module:Class\""):
        ScreenEntry("x", "x", "X", "an x", "Trend")


def test_the_builtin_screens_come_from_their_plugins_hook() -> None:
    reg = Registry(entry_points=False)
    assert reg.names("screen") == ["chain", "dexterity"]
    assert not reg.installed()["mirrorlab.plugins.retarget"].loaded  # known from the declaration alone
    chain = reg.get("screen", "chain")
    assert reg.provider("screen", "chain").name == "mirrorlab.plugins.retarget"
    assert (chain.key, chain.title, chain.load().__module__) == ("v", "Virtual chain", "mirrorlab.plugins.retarget.screen")
    assert reg.provider("screen", "dexterity").name == "mirrorlab.plugins.mechanisms"
