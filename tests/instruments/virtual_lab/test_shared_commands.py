"""The simulator commands the device models share (``mirrorlab.instruments.virtual_lab``, ``LineSimulator``):
``SIM:LOAD`` moves the target of every tracker the same way, ``SIM:SEED`` re-seeds every model's noise,
``SIM:FAULT`` answers a wrong argument count with the fault's usage, ``SIM:FAULT?`` and the truth list the
faults alike, and the two line-sensor hosts (film scanner, optical detector) take ``CLK`` and ``THR`` alike."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest
from mirrorlab.core.devices import LineSimulator
from mirrorlab.instruments.film_scanner.model import FilmScannerModel
from mirrorlab.instruments.line_tracker.model import LineTrackerModel
from mirrorlab.instruments.mirror_gimbal.model import MirrorGimbalModel
from mirrorlab.instruments.ultrasonic_tracker.model import UltrasonicTrackerModel
from mirrorlab.instruments.virtual_lab.world import Path, SharedWorld, Sphere, TrackingWorld

TRACKERS: dict[str, Callable[..., LineSimulator]] = {
    "line_tracker": LineTrackerModel, "mirror_gimbal": MirrorGimbalModel, "ultrasonic_tracker": UltrasonicTrackerModel}
MODELS: dict[str, Callable[..., LineSimulator]] = {**TRACKERS, "film_scanner": lambda seed=0: FilmScannerModel(seed=seed)}


def _world() -> TrackingWorld:
    """A grey 90 mm target 2 m ahead and a second sphere beside it."""
    return TrackingWorld((Sphere(Path((0.0, 0.0, 2000.0)), 90.0, 0.6), Sphere(Path((800.0, 0.0, 2500.0)), 50.0)))


@pytest.mark.parametrize("name", TRACKERS)
def test_sim_load_moves_the_target_for_every_simulator_of_the_world_keeping_the_rest(name: str) -> None:
    shared = SharedWorld(_world())
    model, other = TRACKERS[name](shared, seed=1), TRACKERS[name](shared, seed=2)
    assert model.execute("SIM:LOAD LINE 100 0 1500 0 10 0") == ["OK"]
    moved = other.world
    assert moved is model.world and moved.spheres[1:] == _world().spheres[1:]
    assert (moved.spheres[0].radius, moved.spheres[0].brightness) == (90.0, 0.6)
    assert np.linalg.norm(moved.spheres[0].path.velocity) == pytest.approx(10.0)    # mm/s, in any frame


@pytest.mark.parametrize("name", TRACKERS)
@pytest.mark.parametrize("args", ["", " WOBBLE 1 2", " STILL 1", " STILL x 1 2"])
def test_sim_load_answers_its_usage_or_the_bad_number_and_changes_nothing(name: str, args: str) -> None:
    model = TRACKERS[name](_world())
    (reply,) = model.execute("SIM:LOAD" + args)
    expected = "ERR E02 not a number: x" if "x" in args else f"ERR E02 usage: {type(model).load_usage}"
    assert reply == expected and model.world == _world()


def test_the_gimbal_turns_onto_the_loaded_target() -> None:
    model = MirrorGimbalModel(_world())
    model.execute("SIM:LOAD STILL 12 -4 3000")
    h, v = model.world.target_angles(model.clock_ms / 1000.0)
    assert model.axes["H"].state.detector_angle(model.axes["H"].params) == pytest.approx(h, abs=1e-12)
    assert model.axes["V"].state.detector_angle(model.axes["V"].params) == pytest.approx(v, abs=1e-12)


@pytest.mark.parametrize("name", MODELS)
def test_sim_seed_reseeds_the_noise_generator(name: str) -> None:
    model = MODELS[name](seed=3)
    assert model.np_rng.bit_generator.state == np.random.default_rng(3).bit_generator.state
    model.np_rng.random(5)
    assert model.execute("SIM:SEED 11") == ["OK"] and model.seed == 11
    assert model.np_rng.bit_generator.state == np.random.default_rng(11).bit_generator.state


@pytest.mark.parametrize(("name", "fault", "usage"), [
    ("film_scanner", "RAIL 5", "<um> <period_mm>"),
    ("mirror_gimbal", "BACKLASH H", "<axis> <deg>"),
    ("ultrasonic_tracker", "SERVOGAIN 1", "<axis> <factor>"),
    ("line_tracker", "TWOPEAK 12", "<separation_deg> <ratio>"),
])
def test_a_fault_with_the_wrong_argument_count_gets_its_usage(name: str, fault: str, usage: str) -> None:
    model = MODELS[name]()
    assert model.execute(f"SIM:FAULT {fault}") == [f"ERR E02 usage: SIM:FAULT {fault.split()[0]} {usage}"]


@pytest.mark.parametrize(("name", "fault"), [("film_scanner", "RAIL 5 25"), ("mirror_gimbal", "BACKLASH H 0.5"),
                                             ("ultrasonic_tracker", "SERVOGAIN 2 0.5"), ("line_tracker", "SATURATE")])
def test_fault_query_and_truth_list_the_faults_alike(name: str, fault: str) -> None:
    model = MODELS[name]()
    model.execute("SIM:FAULT CLEAR")
    assert model.execute(f"SIM:FAULT {fault}") == ["OK"]
    listed = model.execute("SIM:FAULT?")[:-1]
    assert len(listed) == 1 and listed[0].startswith("FAULT ")
    assert [line for line in model.truth_lines() if line.startswith("FAULT ")] == listed


@pytest.mark.parametrize("command", ["CLK 400000", "CLK 999", "CLK fast", "CLK", "THR 256", "THR -1", "THR"])
def test_both_line_sensor_hosts_refuse_a_clock_or_threshold_alike(command: str) -> None:
    film, detector = FilmScannerModel(), LineTrackerModel()
    assert film.execute(command) == detector.execute(command) and film.execute(command)[0].startswith("ERR ")


def test_both_line_sensor_hosts_take_a_clock_and_threshold() -> None:
    film, detector = FilmScannerModel(), LineTrackerModel()
    assert film.execute("CLK 100000") == ["OK 100000"] and detector.execute("CLK 100000") == ["OK 100000 5.1"]
    assert film.execute("THR 90") == ["OK 90"] == detector.execute("THR 90")


@pytest.mark.parametrize(("name", "command", "usage"), [
    ("film_scanner", "STREAM maybe", "STREAM ON|OFF"), ("film_scanner", "SIM:CLOCK SLOW", "SIM:CLOCK REAL|FAST"),
    ("line_tracker", "STREAM ON OFF", "STREAM ON|OFF"), ("line_tracker", "SELECT BIGGEST", "SELECT WIDEST|NEAREST|FIRST"),
    ("mirror_gimbal", "H:STREAM", "STREAM ON|OFF"), ("ultrasonic_tracker", "BEAM E", "BEAM 0|A|B|C|D"),
    ("ultrasonic_tracker", "TRACK", "TRACK ON|OFF"),
])
def test_a_keyword_command_names_its_choices(name: str, command: str, usage: str) -> None:
    assert MODELS[name]().execute(command) == [f"ERR E02 usage: {usage}"]


@pytest.mark.parametrize("name", MODELS)
def test_keyword_commands_take_their_words_in_any_case(name: str) -> None:
    model = MODELS[name]()
    assert model.execute("SIM:CLOCK fast") == ["OK"] and model.fast
    assert model.execute("STREAM on") == ["OK"] and model.streaming
