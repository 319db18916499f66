"""Built-in instrument plugins; each sub-package is one instrument with its simulator.

``virtual_lab`` is not an instrument: it is the simulated experiment (scenes, camera, mirrors,
renderer, ground truth) that the simulators film; it knows nothing of them. The film scanner's
:mod:`~mirrorlab.instruments.film_scanner.virtual` films it, and this package's lifecycle hook
stores the truth of every recording made on it under ``/truth/<instrument>``, and that of a
session's shared tracking world under ``/truth/world`` (:mod:`.virtual_lab.worlds`).
"""

from __future__ import annotations

from typing import Any

from mirrorlab.core import hookimpl


@hookimpl
def mirrorlab_recording_stopped(session: Any, statistics: dict[str, Any]) -> None:
    from .film_scanner.virtual import record_all_truth  # imported when a recording ends, not at start-up
    from .virtual_lab.worlds import record_world_truth

    record_all_truth(session)
    record_world_truth(session)


@hookimpl
def mirrorlab_register_instruments() -> list[type]:
    from .film_scanner import FilmScanner
    from .line_tracker import LineTracker
    from .mirror_gimbal import MirrorGimbal
    from .reference import Actuator, AngleSource, ChainSource
    from .ultrasonic_tracker import UltrasonicTracker

    return [FilmScanner, LineTracker, MirrorGimbal, UltrasonicTracker, AngleSource, Actuator, ChainSource]


@hookimpl
def mirrorlab_register_steps() -> list[type]:
    from .line_tracker.steps import STEPS as LINE
    from .mirror_gimbal.steps import STEPS as GIMBAL
    from .ultrasonic_tracker.steps import STEPS as ULTRASONIC

    return [*ULTRASONIC, *LINE, *GIMBAL]


__all__ = ["mirrorlab_recording_stopped", "mirrorlab_register_instruments", "mirrorlab_register_steps"]
