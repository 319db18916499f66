"""The Examples in the tracker and gimbal modules' docstrings run and pass."""

from __future__ import annotations

import pytest

from tests.support import assert_examples_pass

MODULES = [
    "mirrorlab.instruments.virtual_lab.line_sensor.sensor",
    "mirrorlab.instruments.virtual_lab.line_sensor.view",
    "mirrorlab.instruments.virtual_lab.line_sensor.detector",
    "mirrorlab.instruments.virtual_lab.simulators",
    "mirrorlab.instruments.line_tracker.driver",
    "mirrorlab.instruments.line_tracker.experiments",
    "mirrorlab.instruments.virtual_lab.world",
    "mirrorlab.instruments.virtual_lab.worlds",
    "mirrorlab.instruments.virtual_lab.figures",
    "mirrorlab.instruments.virtual_lab.experiments",
    "mirrorlab.instruments.mirror_gimbal.dynamics",
    "mirrorlab.instruments.mirror_gimbal.driver",
    "mirrorlab.instruments.mirror_gimbal.experiments",
    "mirrorlab.instruments.ultrasonic_tracker.acoustics",
    "mirrorlab.instruments.ultrasonic_tracker.echoes",
    "mirrorlab.instruments.ultrasonic_tracker.search",
    "mirrorlab.instruments.ultrasonic_tracker.experiments",
    "mirrorlab.instruments.ultrasonic_tracker.driver",
    "mirrorlab.instruments.reference.chains",
]


@pytest.mark.parametrize("name", MODULES)
def test_module_examples(name: str) -> None:
    assert_examples_pass(name)
