"""The host-side active-mirror loop: ultrasonic tracker → ``follow_target`` → mirror gimbal, over ptys."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from mirrorlab.core import Session

HANG = 120.0


def test_the_mirror_follows_the_tracker_by_half_its_angle(tmp_path: Path) -> None:
    with Session.create(tmp_path / "active.h5") as s:
        s.add_instrument("tracker", "ultrasonic_tracker", simulate=True)
        s.add_instrument("mirror", "mirror_gimbal", simulate=True)
        s.add_controller("loop", "follow_target", settings={"v_offset": math.radians(1.0)},
                         inputs={"direction": "tracker/direction"}, instruments={"mirror": "mirror"})
        with s.subscribe("loop", "latency") as latency:
            s.start_recording()
            for _ in range(6):
                assert latency.get(timeout=HANG) is not None, "no set-point acknowledged"
            s.stop_acquisition()
        g = s.read_group("controllers/loop")
        directions = s.read("instruments/tracker/direction/data")
        sent_h, sent_v = g["mirror.h_angle/data"], g["mirror.v_angle/data"]
        assert len(g["latency/data"]) == len(sent_h) + len(sent_v) >= 6  # one latency per command, both axes
        seen = directions[directions[:, 3] == 0]  # samples not flagged lost
        assert np.isin(sent_h, 0.5 * seen[:, 0]).all()
        assert np.isin(sent_v, 0.5 * seen[:, 1] + math.radians(1.0)).all()
        assert s.attributes("controllers/loop/mirror.h_angle")["unit"] == "rad"
        assert s.snapshot().controllers["loop"].failed_commands == 0
