"""The live session runtime: acquisition apart from recording, controllers and set-points, the
snapshot, cooperative stops, per-recording counters, byte-bounded subscriptions, error classes.

Every device is a simulator behind a real pseudo-terminal, driven by the real driver; every wait
is on an event, a subscription or device state, bounded only to turn a hang into a failure.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import numpy as np
import pytest
from mirrorlab.core import DeviceError, Session, SessionError, ValidationError
from mirrorlab.core.controller_runtime import ControllerContext
from mirrorlab.core.controllers import Controller
from mirrorlab.core.events import Event
from mirrorlab.core.streams import Block

from tests.tolerances import roundoff

HANG = 60.0  # s: only turns a hang into a failure


def wait_for(predicate: Callable[[], bool], what: str, timeout: float = HANG) -> None:
    deadline = time.monotonic() + timeout
    while not predicate():
        assert time.monotonic() < deadline, f"timed out waiting for {what}"
        time.sleep(0.005)


def collect(session: Session, kind: str) -> list[Event]:
    seen: list[Event] = []
    session.events.subscribe(lambda e: seen.append(e) if e.kind == kind else None)
    return seen


def next_blocks(sub, n: int) -> list[Block]:
    blocks = []
    while len(blocks) < n:
        block = sub.get(timeout=HANG)
        assert block is not None, f"no block of {sub.keys} within {HANG} s"
        blocks.append(block)
    return blocks


@pytest.fixture
def loop(tmp_path: Path) -> Iterator[Session]:
    """A 100 Hz angle source, an actuator and a ``follow`` controller (gain 0.5) between them."""
    with Session.create(tmp_path / "loop.h5") as s:
        s.add_instrument("sensor", "angle_source", simulate=True, settings={"rate": 100, "frequency": 2.0})
        s.add_instrument("act", "actuator", simulate=True)
        s.add_controller("loop", "follow", settings={"gain": 0.5}, inputs={"input": "sensor/angle"},
                         instruments={"output": "act"})
        yield s


def test_acquisition_streams_without_writing_and_recording_switches_the_file_on(loop: Session) -> None:
    with loop.subscribe("sensor", "angle") as live:
        loop.start_acquisition(["sensor"])
        next_blocks(live, 20)
        assert "angle" not in loop.members("instruments/sensor")  # acquiring wrote nothing
        thread = loop.instruments["sensor"]._thread
        loop.start_recording(["sensor"])
        assert loop.instruments["sensor"]._thread is thread  # the device was not restarted
        live.drain()  # what came before the recording
        next_blocks(live, 20)
        stats = loop.stop_recording()
        assert loop.instruments["sensor"].state == "acquiring" and loop.acquiring  # acquisition goes on
        next_blocks(live, 5)
        assert stats["sensor/angle"]["samples"] >= 20 and stats["sensor/angle"]["dropped"] == 0
        assert loop.node("instruments/sensor/angle/data").shape[0] == stats["sensor/angle"]["samples"]
        loop.stop_acquisition()
    assert live.closed and loop.instruments["sensor"].state == "stopped" and not loop.acquiring


def test_the_loop_records_setpoints_and_latency_of_each_command(loop: Session) -> None:
    with loop.subscribe("loop", "latency") as latencies:
        loop.start_recording()
        next_blocks(latencies, 50)
        snap = loop.snapshot()
        loop.stop_acquisition()  # the loop, then the instruments, then the recording: nothing sent goes unrecorded
    assert snap.controllers["loop"].state == "running" and snap.controllers["loop"].latency.count >= 50
    assert not loop.recording
    g = loop.read_group("controllers/loop")
    assert loop.attributes("controllers/loop")["plugin"] == "follow"
    assert loop.json_attribute("controllers/loop", "instruments") == {"output": "act"}
    sent = g["output.target/data"]
    angles = loop.read("instruments/sensor/angle/data")
    assert len(sent) >= 50 and g["latency/data"].shape == sent.shape
    assert loop.stream("loop", "output.target").unit == "rad" and loop.stream("loop", "latency").unit == "s"
    # every set-point is exactly half of a recorded angle sample (θt = θv / 2)
    assert np.isin(sent, 0.5 * angles).all()
    assert (g["latency/data"] > 0).all()
    # the actuator holds the last set-point it acknowledged (integer µrad on the wire)
    assert loop.instruments["act"].query("TGT?").field(0, "µrad", int) == round(sent[-1] * 1e6)


class Breaks(Controller):
    """Fails on its fifth block."""

    name = "breaks"
    version = "1.0.0"
    description = "test controller that raises"
    inputs = {"input": "any scalar stream"}
    commands = {"output": ("target",)}

    def on_block(self, role: str, block: Block, ctx: ControllerContext) -> None:
        self.seen = getattr(self, "seen", 0) + 1
        if self.seen == 5:
            raise RuntimeError("bug in the control law")
        ctx.set("output", "target", 0.1, sample_time=float(block.times[-1]))


def test_a_failing_controller_is_reported_and_its_instruments_hold(tmp_path: Path) -> None:
    with Session.create(tmp_path / "s.h5") as s:
        s.add_instrument("sensor", "angle_source", simulate=True)
        s.add_instrument("act", "actuator", simulate=True, settings={"speed": 1e-3})
        runner = s.add_controller("c", Breaks, inputs={"input": "sensor/angle"}, instruments={"output": "act"})
        failed = collect(s, "controller_failed")
        s.start_acquisition()
        wait_for(lambda: runner.state == "failed", "the controller to fail")
        assert len(failed) == 1 and "RuntimeError: bug in the control law" in failed[0].message
        assert s.snapshot().controllers["c"].state == "failed"
        assert s.instruments["act"].status().state == "HOLD"
        assert s.instruments["sensor"].state == "acquiring"  # the instruments go on


def test_set_sends_one_parameter_and_nothing_else(loop: Session) -> None:
    act = loop.instruments["act"]
    model = loop.simulator("act").model
    with loop.simulator("act").lock:
        model.rate_hz = 7.0  # changed on the device itself: re-sending settings would undo it
    converted = roundoff(scale=np.radians(10), ops=2)        # 10 deg -> rad: a product, rounded
    assert act.set("target", "10 deg").wait() == pytest.approx(np.radians(10), abs=converted)
    assert model.target == round(np.radians(10) * 1e6) and model.rate_hz == 7.0
    with pytest.raises(ValidationError, match="not live-settable; change it with configure"):
        act.set("rate", 20.0)
    with pytest.raises(ValidationError, match="above the maximum"):
        act.set("target", 4.0)
    assert act.settings["target"] == pytest.approx(np.radians(10), abs=converted)


def test_snapshot_never_waits_for_a_busy_device_and_stop_aborts_its_command(tmp_path: Path) -> None:
    """The film scanner homes for > 10 s in real time; snapshot() and stop must not wait for it."""
    with Session.create(tmp_path / "s.h5") as s:
        cam = s.add_instrument("cam", "film_scanner", simulate=True, simulator={"clock": "REAL"})
        s.start_acquisition()
        wait_for(lambda: cam.client is not None and cam.client.pending is not None
                 and cam.client.pending.startswith("HOME"), "the scanner to be busy homing")
        started = time.monotonic()
        worst = 0.0
        for _ in range(50):
            t0 = time.perf_counter()
            snap = s.snapshot()
            worst = max(worst, time.perf_counter() - t0)
        assert snap.instruments["cam"].state == "acquiring" and cam.client.pending == "HOME"  # still homing
        assert worst < 0.5  # a call through the busy command channel would wait seconds
        t0 = time.monotonic()
        s.stop_acquisition()
        stopped_in = time.monotonic() - t0
        assert stopped_in < 5.0 and time.monotonic() - started < 10.0  # HOME alone takes longer
        assert cam.state == "stopped" and cam.failed is None
        assert not [t for t in threading.enumerate() if t.name == "acquire cam"]


def test_request_stop_ends_record_from_another_thread_without_an_exception(loop: Session) -> None:
    started = threading.Event()
    loop.events.subscribe(lambda e: started.set() if e.kind == "recording_started" else None)
    outcome: dict[str, object] = {}

    def script() -> None:
        try:
            outcome["stats"] = loop.record(600, ["sensor"])
        except BaseException as exc:  # noqa: BLE001 - the test reports it
            outcome["error"] = exc

    thread = threading.Thread(target=script)
    with loop.subscribe("sensor", "angle") as live:
        thread.start()
        assert started.wait(HANG)
        next_blocks(live, 1)
        loop.request_stop()
    thread.join(HANG)
    assert not thread.is_alive() and "error" not in outcome
    assert loop.recorded_seconds < 600 and not loop.recording and not loop.acquiring
    assert outcome["stats"]["sensor/angle"]["samples"] > 0  # type: ignore[index]
    assert any(e["kind"] == "stopped_on_request" for e in loop.log())


def test_a_second_recording_reports_only_its_own_drops(loop: Session) -> None:
    loop.router.recorder_queue.maxsize = 1  # a recorder that cannot keep up
    loop.start_recording(["sensor"])
    for k in range(20_000):  # as a device thread would publish, faster than the recorder takes
        loop.router.publish("sensor", "angle", [k * 1e-3], [0.0])
    first = loop.stop_recording()
    loop.router.recorder_queue.maxsize = 4096
    with loop.subscribe("sensor", "angle") as live:
        loop.start_recording(["sensor"])
        live.drain()  # what came before the recording
        next_blocks(live, 10)
        second = loop.stop_recording()
    assert first["sensor/angle"]["dropped"] > 0
    assert second["sensor/angle"]["dropped"] == 0 and second["sensor/angle"]["samples"] >= 10
    assert loop.attributes("instruments/sensor/angle")["dropped"] == 0
    assert loop.snapshot().instruments["sensor"].dropped == 0


def test_subscriptions_are_bounded_by_bytes_and_released_with_the_session(tmp_path: Path) -> None:
    with Session.create(tmp_path / "s.h5") as s:
        s.add_instrument("sensor", "angle_source", simulate=True, settings={"rate": 500})
        small = s.subscribe("sensor", "angle", max_bytes=10 * 16)  # ten one-sample blocks
        s.start_acquisition()
        wait_for(lambda: small.dropped > 20, "the subscription to drop old blocks")
        assert small.nbytes <= 10 * 16 and len(small.drain()) <= 10
    assert small.closed and small.get(timeout=HANG) is None  # released: returns at once


def test_a_failed_recorder_is_an_event_and_ends_the_recording(loop: Session) -> None:
    failed = collect(loop, "recorder_failed")
    loop.start_recording(["sensor"])
    loop.router.publish("sensor", "angle", [1.0, 2.0], np.zeros((2, 3)))  # values that fit no dataset
    wait_for(lambda: bool(failed), "recorder_failed")
    assert "record into a new session file" in failed[0].message
    assert loop.snapshot().recorder.error
    with pytest.raises(TypeError, match="broadcast"):
        loop.stop_recording()  # the recorder's error surfaces to whoever stops it
    assert not loop.recording


def test_an_unplugged_device_fails_after_its_reconnect_budget(tmp_path: Path) -> None:
    with Session.create(tmp_path / "s.h5") as s:
        sensor = s.add_instrument("sensor", "angle_source", simulate=True, reconnect=0.5)
        events = collect(s, "reconnect_budget")
        s.start_acquisition()
        wait_for(lambda: sensor.last_status is not None, "a first status")
        s.simulator("sensor").close()  # gone for good
        wait_for(lambda: sensor.state == "failed", "the budget to run out")
        assert len(events) == 1 and "did not come back within 0.5 s" in events[0].message


def _in_thread(call: Callable[[], None]) -> tuple[threading.Thread, threading.Event]:
    done = threading.Event()
    worker = threading.Thread(target=lambda: (call(), done.set()))
    worker.start()
    return worker, done


def test_disconnecting_and_connecting_an_instrument_take_the_session_lock(loop: Session) -> None:
    sensor, act = loop.instruments["sensor"], loop.instruments["act"]
    loop.start_acquisition()
    wait_for(lambda: loop.controllers["loop"].running, "the loop to run")
    with loop._runtime.lock:  # another thread changes the session's state meanwhile
        worker, done = _in_thread(lambda: loop.disconnect_instrument("sensor"))
        assert not done.wait(0.3) and sensor.state == "acquiring"  # it waits for the lock
    assert done.wait(HANG), "disconnect_instrument hangs"
    worker.join()
    assert sensor.state == "stopped" and not loop.controllers["loop"].running  # its controller stopped with it
    assert act.state == "acquiring" and loop.snapshot().instruments["sensor"].acquiring is False  # the others go on
    with loop._runtime.lock:
        worker, done = _in_thread(lambda: loop.connect_instrument("sensor"))
        assert not done.wait(0.3) and sensor.state == "stopped"
    assert done.wait(HANG), "connect_instrument hangs"
    worker.join()
    assert sensor.state == "idle"
    with loop.subscribe("sensor", "angle") as live:
        loop.start_acquisition(["sensor"])
        next_blocks(live, 5)  # connected again: it streams


def test_a_recorded_instrument_is_not_disconnected_and_a_failed_connect_leaves_it_stopped(loop: Session) -> None:
    sensor = loop.instruments["sensor"]
    loop.start_recording(["sensor"])
    with pytest.raises(SessionError, match="sensor is being recorded; stop the recording before disconnecting it"):
        loop.disconnect_instrument("sensor")
    assert sensor.state == "acquiring" and loop.recording
    loop.stop_recording()
    with pytest.raises(SessionError, match="no instrument 'nope' in this session; its instruments: sensor, act"):
        loop.disconnect_instrument("nope")
    loop.disconnect_instrument("sensor")
    loop.simulator("sensor").close()  # the device is gone: connecting fails
    states = collect(loop, "state")
    with pytest.raises(DeviceError):
        loop.connect_instrument("sensor")
    assert sensor.state == "stopped" and states[-1].message.endswith("did not connect")


def test_a_folder_source_resumes_where_it_was_after_a_reconnect(tmp_path: Path) -> None:
    import cv2

    frames = tmp_path / "frames"
    frames.mkdir()
    for k in range(6):
        cv2.imwrite(str(frames / f"{k}.png"), np.full((32, 64), 40 * k, np.uint8))
    with Session.create(tmp_path / "s.h5") as s:
        cam = s.add_instrument("cam", "film_scanner", settings={"source": "folder", "path": str(frames)})
        assert [int(cam.read()["frame_index"][0]) for _ in range(3)] == [0, 1, 2]
        cam.reconnect()
        assert int(cam.read()["frame_index"][0]) == 3


def test_controller_bindings_are_checked_when_added(tmp_path: Path) -> None:
    with Session.create(tmp_path / "s.h5") as s:
        s.add_instrument("sensor", "angle_source", simulate=True)
        s.add_instrument("act", "actuator", simulate=True)
        with pytest.raises(ValidationError) as err:
            s.add_controller("c", "follow", settings={"parameter": "speed"},
                             inputs={"input": "sensor/nothing"}, instruments={"output": "act", "extra": "act"})
        text = str(err.value)
        assert "controllers.c.inputs.input: 'sensor/nothing' is no stream of this session; sensor has: angle" in text
        assert "controllers.c.instruments.output: actuator 'act' has no live-settable speed" in text
        assert "controllers.c.instruments.extra: follow commands no 'extra'" in text
        assert not s.controllers and not s.exists("controllers/c")


class Bursts(Controller):
    """Sends five set-points per input sample without waiting, 200 in all, then nothing."""

    name = "bursts"
    version = "1.0.0"
    description = "test controller that sends faster than the actuator acknowledges"
    inputs = {"input": "any scalar stream"}
    commands = {"output": ("target",)}
    GIVEN = 200

    def setup(self, ctx: ControllerContext) -> None:
        self.given: list[float] = []

    def on_block(self, role: str, block: Block, ctx: ControllerContext) -> None:
        for t in block.times.tolist():
            for _ in range(5):
                if len(self.given) < self.GIVEN:
                    self.given.append(1e-3 * (len(self.given) + 1))
                    ctx.send("output", "target", self.given[-1], sample_time=t)


def test_send_keeps_the_newest_setpoint_and_records_what_was_acknowledged(tmp_path: Path) -> None:
    with Session.create(tmp_path / "s.h5") as s:
        s.add_instrument("sensor", "angle_source", simulate=True, settings={"rate": 100})
        s.add_instrument("act", "actuator", simulate=True)
        runner = s.add_controller("c", Bursts, inputs={"input": "sensor/angle"}, instruments={"output": "act"})
        s.start_recording()

        def accounted() -> bool:
            snap = s.snapshot().controllers["c"]
            return snap.commands + snap.superseded_commands == Bursts.GIVEN

        wait_for(accounted, "every value sent or superseded")
        snap = s.snapshot().controllers["c"]
        s.stop_acquisition()
        given = runner.controller.given
        sent = s.read("controllers/c/output.target/data")
        assert snap.superseded_commands > 0 and snap.failed_commands == 0, snap
        assert len(sent) == snap.commands and s.node("controllers/c/latency/data").shape == sent.shape
        # what reached the actuator is the given values in order, some skipped, the last one always
        positions = [int(np.argmin(np.abs(np.asarray(given) - v))) for v in sent]
        # the floats as given, stored: exact but for rounding
        assert np.allclose(np.asarray(given)[positions], sent, atol=roundoff(scale=max(given)), rtol=0)

        assert positions == sorted(set(positions)) and positions[-1] == len(given) - 1
        assert s.instruments["act"].query("TGT?").field(0, "µrad", int) == round(given[-1] * 1e6)
