"""``Instrument.set`` returns a :class:`SetStatus` at once; the device's acknowledgement (or error)
arrives on it. The actuator is its simulator behind a real pseudo-terminal, driven by the real driver;
holding the simulator's lock keeps the device from answering, as a busy device would."""

from __future__ import annotations

import gc
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
from mirrorlab.core import DeviceDisconnected, DeviceTimeout, Session, ValidationError
from mirrorlab.core.devices import SetStatus

HANG = 60.0  # s: only turns a hang into a failure


@pytest.fixture
def session(tmp_path: Path) -> Iterator[Session]:
    with Session.create(tmp_path / "s.h5") as s:
        s.add_instrument("act", "actuator", simulate=True)
        yield s


def test_set_returns_before_the_device_answers_and_wait_returns_the_applied_value(session: Session) -> None:
    act = session.instruments["act"]
    server = session.simulator("act")
    with server.lock:  # the device takes no command while this is held
        t0 = time.monotonic()
        status = act.set("target", "0.2 rad")
        returned_in = time.monotonic() - t0
        assert isinstance(status, SetStatus) and returned_in < act.timeout  # a blocking set would wait for TGT's OK
        assert (status.done, status.success, status.exception, status.latency) == (False, False, None, None)
        assert status.value == 0.2 and "pending" in repr(status)
        with pytest.raises(DeviceTimeout, match=r"target = 0.2 was not acknowledged within 0.05 s \(still in flight\)"):
            status.wait(0.05)
        held = time.monotonic() - t0
    assert status.wait(HANG) == 0.2
    assert status.done and status.success and status.exception is None
    assert status.latency is not None and status.latency >= held - 1e-3  # from set() to the OK, which waited
    assert server.model.target == 200_000 and act.settings["target"] == 0.2


def test_set_points_are_sent_in_the_order_given(session: Session) -> None:
    act = session.instruments["act"]
    statuses = [act.set("target", v) for v in (0.1, 0.2, -0.3)]
    assert [s.wait(HANG) for s in statuses] == [0.1, 0.2, -0.3]
    assert session.simulator("act").model.target == -300_000 and act.settings["target"] == -0.3


def test_a_device_error_fails_the_status_and_wait_raises_it(session: Session) -> None:
    act = session.instruments["act"]
    act.close()  # the device is gone: the set-point thread's query raises
    status = act.set("target", 0.1)
    with pytest.raises(DeviceDisconnected, match="is not connected"):
        status.wait(HANG)
    assert status.done and not status.success and isinstance(status.exception, DeviceDisconnected)
    assert act.settings["target"] == 0.0  # not acknowledged: not applied
    assert "failed: DeviceDisconnected" in repr(status)


def test_validation_fails_at_once_in_the_calling_thread(session: Session) -> None:
    act = session.instruments["act"]
    with pytest.raises(ValidationError, match="not live-settable.*live-settable: target"):
        act.set("speed", 1.0)
    with pytest.raises(ValidationError, match="has no parameter 'nope'"):
        act.set("nope", 1.0)
    with pytest.raises(ValidationError, match="above the maximum"):
        act.set("target", 4.0)


def test_callbacks_run_once_done_and_one_that_raises_is_reported(session: Session) -> None:
    act = session.instruments["act"]
    reports: list[tuple[str, str]] = []
    act.report = lambda level, kind, message, **data: reports.append((kind, message))
    seen: list[tuple[str, bool]] = []
    ran = threading.Event()

    def broken(status: SetStatus) -> None:
        raise RuntimeError("a bug in a callback")

    with session.simulator("act").lock:
        status = act.set("target", 0.1)
        status.add_callback(broken)
        status.add_callback(lambda s: (seen.append((threading.current_thread().name, s.success)), ran.set()))
        assert seen == []  # not done: nothing ran
    assert ran.wait(HANG)
    assert seen[0][0].startswith("set-points act") and seen[0][1]  # in the set-point thread, after the OK
    status.add_callback(lambda s: seen.append(("now", s.success)))  # done already: runs at once, here
    assert seen[1] == ("now", True)
    deadline = time.monotonic() + HANG
    while not reports and time.monotonic() < deadline:  # reported after the callbacks ran
        time.sleep(0.005)
    assert reports == [("setpoint_callback_failed", f"{act.device_name}: a callback of the set-point target raised "
                                                   "RuntimeError: a bug in a callback")]


def test_the_set_point_thread_ends_with_its_instrument(tmp_path: Path) -> None:
    """Made on the first set(); an instrument nobody refers to any more leaves no thread behind."""
    with Session.create(tmp_path / "s.h5") as s:
        s.add_instrument("gone", "actuator", simulate=True).set("target", 0.1).wait(HANG)
        assert [t for t in threading.enumerate() if t.name.startswith("set-points gone")]
    del s
    gc.collect()
    deadline = time.monotonic() + HANG
    while [t for t in threading.enumerate() if t.name.startswith("set-points gone")]:
        assert time.monotonic() < deadline, "the set-point thread outlived its instrument"
        time.sleep(0.01)
