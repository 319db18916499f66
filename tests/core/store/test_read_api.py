"""The session's read API: datasets by path (whole, or frames by index), nodes and trees, attributes
(text and JSON decoded), groups and truth, and a file read while it records, all as plain values.

A real session file with a simulated angle source behind a pty; what is read back is compared with
what was written.
"""

from __future__ import annotations

import time
from pathlib import Path

import h5py
import numpy as np
import pytest
from mirrorlab.core import Node, Session, SessionError

HANG = 60.0  # s: only turns a hang into a failure
XY = np.arange(12.0).reshape(6, 2)
POSITIONS = np.arange(24.0).reshape(2, 4, 3)


def _no_h5py(value: object) -> bool:
    """Whether ``value`` (or any value it holds) is free of h5py objects."""
    if isinstance(value, dict):
        return all(_no_h5py(v) for v in value.values())
    return not type(value).__module__.startswith("h5py")


@pytest.fixture(scope="module")
def recorded(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("read") / "s.h5"
    with Session.create(path, operator="ana") as s:
        s.add_instrument("sensor", "angle_source", simulate=True, settings={"rate": 100})
        s.record(0.3)
        s.write_group("truth/cam", {"xy": XY}, {"unit": "px", "labels": ["a", "b"], "rate": 50.0})
        s.write_group("truth/cam/markers", {"positions": POSITIONS}, {"description": "true positions, mm"})
    return path


def test_datasets_nodes_and_trees_read_as_written(recorded: Path) -> None:
    with Session.open(recorded) as s:
        assert s.exists("/truth/cam/xy") and s.exists("truth/cam") and s.exists("/") and not s.exists("/truth/nope")
        assert s.members("/truth/cam") == ["markers", "xy"]
        assert s.members("/truth/nope") == [] and s.members("/truth/cam/xy") == []  # no such group, a dataset
        assert {"config", "instruments", "controllers", "calibration", "results", "truth", "log"} <= set(s.members())
        assert np.array_equal(s.read("/truth/cam/xy"), XY)
        assert s.read("/truth/cam/xy", 4).tolist() == XY[4].tolist()                  # a frame by its index
        assert np.array_equal(s.read("truth/cam/xy", slice(1, 3)), XY[1:3])            # frames 1 and 2
        assert [n.path for n in s.tree("/truth")] == ["/truth/cam", "/truth/cam/markers",
                                                      "/truth/cam/markers/positions", "/truth/cam/xy"]
        node = s.node("/truth/cam/xy")
        assert isinstance(node, Node) and node.is_dataset and node.shape == (6, 2) and node.dtype == np.float64
        assert node.unit == "" and node.attrs == () and node.name == "xy"
        group = s.node("/truth/cam")
        assert not group.is_dataset and group.members == 2 and group.attrs == ("labels", "rate", "unit")
        data = s.node("/instruments/sensor/angle/data")  # a stream's data: its stream group's unit
        times, angles = s.stream("sensor", "angle")
        assert data.unit == "rad" and data.shape == angles.shape and len(times) > 0
        assert np.array_equal(s.read("/instruments/sensor/angle/data"), angles)
        assert [n.path for n in s.tree()] == [n.path for n in s.tree("/")]
        assert all(_no_h5py(v) for v in (node, s.read("/truth/cam/xy"), s.read("/truth/cam/xy", 0), *s.tree()))


def test_attributes_groups_and_truth(recorded: Path) -> None:
    with Session.open(recorded) as s:
        attrs = s.attributes("/truth/cam")
        assert attrs["unit"] == "px" and isinstance(attrs["unit"], str) and attrs["rate"] == 50.0
        assert attrs["labels"] == '["a", "b"]' and s.json_attribute("/truth/cam", "labels") == ["a", "b"]
        assert s.json_attribute("/truth/cam", "absent", {"default": 1}) == {"default": 1}
        assert s.attributes()["operator"] == "ana" and s.attributes("/")["status"] == "closed"
        assert s.json_attribute("/instruments/sensor", "settings")["rate"] == 100.0
        group = s.read_group("/truth/cam")
        assert sorted(group) == ["markers/positions", "xy"] and np.array_equal(group["markers/positions"], POSITIONS)
        truth = s.truth("cam")
        assert sorted(truth) == sorted(group) and np.array_equal(truth["xy"], XY)
        assert _no_h5py(attrs) and _no_h5py(truth)


@pytest.mark.parametrize(("call", "message"), [
    (lambda s: s.read("/truth/nope"), "no dataset /truth/nope in "),
    (lambda s: s.read("/truth/cam"), "no dataset /truth/cam in "),      # a group is no dataset
    (lambda s: s.tree("/truth/cam/xy"), "no group /truth/cam/xy in "),  # nor a dataset a group
    (lambda s: s.node("/nope"), "no /nope in "),
    (lambda s: s.attributes("/nope"), "no /nope in "),
    (lambda s: s.read_group("/nope"), "no group /nope in "),
    (lambda s: s.truth("nope"), "no /truth/nope in "),
])
def test_a_missing_path_is_one_line_naming_it(recorded: Path, call, message: str) -> None:
    with Session.open(recorded) as s, pytest.raises(SessionError) as raised:
        call(s)
    text = str(raised.value)
    assert text.startswith(message) and str(recorded) in text and "\n" not in text
    assert "mirrorlab session tree" in text or "truth groups here: cam" in text  # what to do


def test_a_session_hands_out_no_h5py_file(recorded: Path) -> None:
    """The read API replaces the raw handle: a session has no ``file`` to touch."""
    with Session.open(recorded) as s:
        assert not hasattr(s, "file")
        assert not any(isinstance(v, h5py.HLObject) for v in vars(s).values())


def test_reading_while_recording_sees_what_the_recorder_flushed(tmp_path: Path) -> None:
    """In SWMR mode the datasets are refreshed before they are read, so the growing recording shows."""
    with Session.create(tmp_path / "live.h5") as s:
        s.add_instrument("sensor", "angle_source", simulate=True, settings={"rate": 200})
        s.start_recording()
        path, seen = "/instruments/sensor/angle/data", []
        deadline = time.monotonic() + HANG
        while len(seen) < 2:  # two reads of a growing dataset: the recorder flushes about every 0.5 s
            n = s.node(path).shape[0]
            if n and (not seen or n > seen[-1]):
                seen.append(n)
                assert s.read(path).shape[0] >= n and s.read(path, n - 1).shape == ()  # the newest sample
            assert time.monotonic() < deadline, f"the recording did not grow: {seen}"
            time.sleep(0.05)
        stats = s.stop_recording()
        assert s.node(path).shape[0] == stats["sensor/angle"]["samples"] >= seen[-1]
