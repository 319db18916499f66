"""Experiments on the simulated ultrasonic tracker (``instruments.md`` §2.6, §5).

* :func:`search_path`: the static search from an offset (Fig. 4.19: 12 deg off axis).
* :func:`loses_target` / :func:`tracking_limit`: a target circling the tracker at constant range
  through 76 deg (nearly the +-40 deg platform range) is lost when it leaves the main lobe
  (pointing error above 15 deg, §2.6) or the tracker reports it lost (flag ``L``); the limit is
  the smallest rate that is lost (bisection). A target slightly faster than the search's
  ``h0 / cycle`` falls behind only slowly, so within the finite sweep this limit lies a little
  above that theoretical bound.
* :func:`cycle_times`: the modelled duration of each search cycle.
* :func:`stage_tracking`: a target on the x-y stage (Fig. 4.22), a line or an ellipse, followed
  for whole cycles; the pointing error against the thesis's accuracy of about 5 deg.
"""

from __future__ import annotations

import math

import numpy as np
from mirrorlab.instruments.virtual_lab.experiments import bisect_limit, with_faults
from mirrorlab.instruments.virtual_lab.worlds import TRACKING_WORLD, build_world

from .model import DEFAULT_SERVO, TARGET_RADIUS, Servo, UltrasonicTrackerModel

MAIN_LOBE = math.radians(15.0)


def _pointing(model: UltrasonicTrackerModel) -> tuple[np.ndarray, float]:
    lines = {l.split()[1]: l.split()[2:] for l in model.execute("SIM:TRUTH?")[:-1]}
    return np.radians([float(x) for x in lines["PLATFORM"]]), math.radians(float(lines["ERROR"][0]))


def search_path(offset: tuple[float, float] = (0.0, math.radians(12.0)), cycles: int = 25, seed: int = 0,
                range_mm: float = 1000.0) -> np.ndarray:
    """Platform angles ``(cycles + 1, 2)`` rad after each search cycle, target at ``offset`` from the start.

    The platform starts at (0, 0) and the target stands at ``offset`` (theta1, theta2).

    Examples
    --------
    >>> path = search_path(cycles=30)
    >>> round(math.degrees(float(path[-1, 1])))                 # found near theta2 = 12 deg
    12
    """
    model = UltrasonicTrackerModel(seed=seed)
    model.execute(f"SIM:LOAD STILL {math.degrees(offset[0]):.6f} {math.degrees(offset[1]):.6f} {range_mm:.3f}")
    path = [_pointing(model)[0]]
    model.execute("TRACK ON")
    for _ in range(cycles):
        model.advance(model.next_cycle_s - model.clock_ms / 1000.0 + 1e-6)
        path.append(_pointing(model)[0])
    return np.array(path)


def loses_target(rate: float, servo: Servo | None = DEFAULT_SERVO, seed: int = 0, range_mm: float = 1300.0,
                 sweep: float = math.radians(76.0), faults: tuple[str, ...] = ()) -> bool:
    """Whether a target circling at ``rate`` (rad/s) through ``sweep`` at ``range_mm`` is lost.

    Examples
    --------
    >>> loses_target(math.radians(10.0)), loses_target(math.radians(50.0))
    (False, True)
    """
    model = with_faults(UltrasonicTrackerModel(seed=seed, servo=servo), faults)
    half = math.degrees(sweep) / 2
    model.execute(f"AIM {-half:.6f} 0")
    model.advance(1.0)
    model.execute(f"SIM:LOAD CIRCLE {-half:.6f} {math.degrees(rate):.6f} {range_mm:.3f} 0.5")
    model.execute("TRACK ON")
    start = model.clock_ms / 1000.0 + 0.5
    end = start + sweep / rate
    while model.clock_ms / 1000.0 < end:
        model.advance(0.05)
        _, error = _pointing(model)
        if error > MAIN_LOBE or "L" in model.track_flags:
            return True
    return False


def tracking_limit(servo: Servo | None = DEFAULT_SERVO, seed: int = 0, lo: float = math.radians(5.0),
                   hi: float = math.radians(60.0), tol: float = math.radians(0.25),
                   faults: tuple[str, ...] = ()) -> float:
    """Smallest circling rate (rad/s) that is lost, to within ``tol`` (bisection)."""
    return bisect_limit(lambda rate: loses_target(rate, servo, seed, faults=faults), lo, hi, tol)


def cycle_times(range_mm: float = 1300.0, cycles: int = 50, seed: int = 0) -> np.ndarray:
    """Durations (s) of ``cycles`` search cycles on a still target at ``range_mm`` (from ``!TRK`` times).

    Examples
    --------
    >>> round(float(cycle_times(cycles=40).mean()), 2)          # about 80 ms at 1.3 m (§2.4)
    0.08
    """
    model = UltrasonicTrackerModel(seed=seed)
    model.execute(f"SIM:LOAD STILL 0 0 {range_mm:.3f}")
    model.execute("STREAM ON")
    model.execute("TRACK ON")
    stamps: list[int] = []
    while len(stamps) <= cycles:
        model.advance(0.05)
        stamps += [int(line.split()[1]) for line in model.stream_lines() if line.startswith("!TRK")]
    return np.diff(stamps[: cycles + 1]) / 1000.0


def stage_tracking(scene: str = "stage_line", width: float = 600.0, height: float = 0.0, period: float = 50.0,
                   cycles: float = 1.0, range_mm: float = 1000.0, seed: int = 0,
                   step: float = 0.1) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Track the 130 mm sphere on the x-y stage (Fig. 4.22) for ``cycles`` stage cycles of ``period`` s.

    The stage moves the sphere ``range_mm`` ahead on a line of stroke ``width`` (``"stage_line"``)
    or an ellipse ``width`` x ``height`` (``"stage_ellipse"``), mm, starting 1 s after the search.
    Returns times (s), true target angles and platform angles ``(n, 2)`` (theta1, theta2, rad) and
    the pointing error (rad), every ``step`` s.

    Examples
    --------
    >>> t, target, platform, error = stage_tracking(period=17.0, cycles=0.25)
    >>> bool(np.degrees(error[20:]).max() < 5.0), round(float(np.degrees(np.ptp(target[:, 0]))))
    (True, 17)
    """
    world = build_world({**TRACKING_WORLD.defaults(), "scene": scene, "width": width, "height": height,
                         "period": period, "range": range_mm, "start": 1.0, "target_radius": TARGET_RADIUS})
    model = UltrasonicTrackerModel(world, seed=seed)
    model.execute("TRACK ON")
    rows = []
    for _ in range(int(round((1.0 + cycles * period) / step))):
        model.advance(step)
        platform, error = _pointing(model)
        rows.append([model.clock_ms / 1000.0, *model.target_angles(model.clock_ms / 1000.0), *platform, error])
    out = np.array(rows)
    return out[:, 0], out[:, 1:3], out[:, 3:5], out[:, 5]
