"""Instrument and controller states are enums whose members are their old strings: typed in the code,
unchanged in events, snapshots, the session file's ``/log`` and everything printed."""

from __future__ import annotations

import json
import typing
from pathlib import Path

import h5py
import pytest
from mirrorlab.core import Session
from mirrorlab.core.controller_runtime import ControllerState
from mirrorlab.core.devices import InstrumentState
from mirrorlab.core.devices.instrument import STATES, StateName
from mirrorlab.core.store import schema


def test_the_state_names_are_the_enum_values() -> None:
    assert STATES == ("idle", "connecting", "acquiring", "reconnecting", "failed", "stopped")
    assert tuple(InstrumentState) == STATES and typing.get_args(StateName) == STATES
    assert [s.value for s in ControllerState] == ["idle", "running", "failed", "stopped"]
    assert InstrumentState.ACQUIRING == "acquiring" and f"{InstrumentState.ACQUIRING}" == "acquiring"
    assert json.dumps({"state": InstrumentState.FAILED}) == '{"state": "failed"}'


def test_set_state_takes_a_member_or_its_name_and_nothing_else(tmp_path: Path) -> None:
    with Session.create(tmp_path / "s.h5") as s:
        act = s.add_instrument("act", "actuator", simulate=True)
        assert act.state is InstrumentState.IDLE
        act.set_state("stopped")
        assert act.state is InstrumentState.STOPPED
        with pytest.raises(ValueError, match=r"state must be one of \('idle', .*'stopped'\), not 'asleep'"):
            act.set_state("asleep")  # type: ignore[arg-type]  # what mypy would refuse
        assert act.state is InstrumentState.STOPPED


def test_states_in_snapshots_events_and_the_file_are_the_strings(tmp_path: Path) -> None:
    path = tmp_path / "s.h5"
    with Session.create(path) as s:
        s.add_instrument("sensor", "angle_source", simulate=True)
        s.add_instrument("act", "actuator", simulate=True)
        s.add_controller("loop", "follow", inputs={"input": "sensor/angle"}, instruments={"output": "act"})
        s.record(0.2)
        snap = s.snapshot()
    assert snap.instruments["sensor"].state is InstrumentState.STOPPED
    assert snap.controllers["loop"].state is ControllerState.STOPPED
    with h5py.File(path, "r") as f:
        log = schema.read_log(f)
    states = [(e["source"], e["data"]["state"], e["message"]) for e in log if e["kind"] == "state"]
    assert ("sensor", "acquiring", f"{s.instruments['sensor'].device_name} is acquiring") in states
    assert ("loop", "running", "controller 'loop' is running") in states
    assert all(type(state) is str and state in STATES + ("running",) for _, state, _ in states)
