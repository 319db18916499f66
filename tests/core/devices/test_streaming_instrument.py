"""``StreamingInstrument``: stream lines published as they arrive, on the device's clock, bad ones reported.

The reference ``angle_source`` (a ``StreamingInstrument``) against its simulator over a real pty.
"""

from __future__ import annotations

import re
import threading
from pathlib import Path

import numpy as np
from mirrorlab.core import Session
from mirrorlab.core.clock import SessionClock
from mirrorlab.core.devices import SimulatorServer
from mirrorlab.core.events import Event
from mirrorlab.core.streams import Emitter, StreamRouter
from mirrorlab.instruments.reference import Actuator
from mirrorlab.instruments.reference.models import ActuatorModel

HANG = 60.0  # s: only turns a hang into a failure


def test_a_bad_stream_line_is_reported_and_streaming_goes_on(tmp_path: Path) -> None:
    with Session.create(tmp_path / "s.h5") as s:
        sensor = s.add_instrument("sensor", "angle_source", simulate=True, settings={"rate": 50})
        bad: list[Event] = []
        seen = threading.Event()
        s.events.subscribe(lambda e: (bad.append(e), seen.set()) if e.kind == "bad_sample" else None)
        with s.subscribe("sensor", "angle") as live:
            s.start_acquisition()
            assert live.get(timeout=HANG) is not None
            server = s.simulator("sensor")
            with server.lock:  # between two whole lines of the device
                server.endpoint.send(b"!A 12 not-a-number\n")
            assert seen.wait(HANG)
            live.drain()
            blocks = [live.get(timeout=HANG) for _ in range(5)]
            s.stop_acquisition()
    assert "unusable stream line 'A 12 not-a-number'" in bad[0].message and len(bad) == 1
    assert all(b is not None for b in blocks) and sensor.state == "stopped"
    times = np.concatenate([b.times for b in blocks if b is not None])
    assert np.all(np.diff(times) > 0)  # device stamps, in order, each published as its own block
    assert all(len(b.times) == 1 for b in blocks if b is not None)


def test_lines_the_device_had_to_drop_are_reported() -> None:
    """An actuator streaming 1000 positions a second over a paced 9600-baud line (960 bytes/s) drops lines;
    its ``!OVF <n>`` notices reach the driver's report as ``device_overflow`` warnings naming ``n``."""
    reports: list[tuple[str, str, str]] = []
    got = threading.Event()

    def report(level: str, kind: str, message: str, **data: object) -> None:
        reports.append((level, kind, message))
        if kind == "device_overflow":
            got.set()

    with SimulatorServer(ActuatorModel(), "tcp", baud=9600) as server:
        act = Actuator("act", port=server.url, settings={"rate": 1000.0}, report=report)
        act.connect()
        act.configure()
        router, clock = StreamRouter(), SessionClock()
        act.start(Emitter("act", router, clock, {s.name: s for s in act.streams()}))
        try:
            assert got.wait(HANG)
        finally:
            act.stop()
            act.close()
    level, _, message = next(r for r in reports if r[1] == "device_overflow")
    assert level == "warning" and re.fullmatch(r"actuator 'act' .* dropped [1-9][0-9]* stream lines: .*", message), message
