"""One simulated world for every tracker of a session, and its truth under /truth/world (real ptys, real file).

A fixed line tracker and the active mirror watch one walker. Checked: both simulators hold the same
world object on the session clock; the fixed detector's marks sit at the pixel of the truth's target
direction; the gimbal's detector centres the same target and turns the mirror to half its angle;
/truth/world agrees with the analytic trajectory, the stored mirror angles with the normal, and
``in_mirror`` with the reflection geometry recomputed from them.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from mirrorlab.core import Session, ValidationError
from mirrorlab.instruments.line_tracker import LineTrackerModel
from mirrorlab.instruments.mirror_gimbal import MirrorGimbalModel
from mirrorlab.instruments.virtual_lab.line_sensor.sensor import angle_to_pixel
from mirrorlab.instruments.virtual_lab.world import SharedWorld, image_in_mirror, mirror_normal
from mirrorlab.instruments.virtual_lab.worlds import TRACKING_WORLD, build_world

from tests.tolerances import roundoff

WALK = {"scene": "walk", "range": 3000.0, "width": 600.0, "speed": 300.0, "start": 0.5}


def test_two_trackers_share_one_world_and_its_truth_is_recorded(tmp_path) -> None:
    with Session.create(tmp_path / "shared.h5") as s:
        s.set_world(WALK)
        s.add_instrument("fixed", "line_tracker", simulate=True, settings={"threshold": 60})
        s.add_instrument("mirror", "mirror_gimbal", simulate=True, settings={"threshold": 60})
        fixed, mirror = s.simulator("fixed").model, s.simulator("mirror").model
        assert fixed.scene is mirror.scene and fixed.scene.shared
        s.record(2.5)
        marks = s.stream("fixed", "mark")
        gimbal = s.stream("mirror", "h")
        assert s.exists("/truth/world") and s.attributes("truth/world")["kind"] == "ground truth (shared tracking world)"
        stored = s.truth("world")
        truth = {name: (stored[f"{name}/time"], stored[f"{name}/data"])
                 for name in ("target", "target_angles", "mirror_angles", "mirror_normal", "in_mirror")}
        assert s.attributes("truth/world/target")["unit"] == "mm"
        assert s.attributes("truth/world/in_mirror")["description"].startswith("the target's image")
    t, target = truth["target"]
    # camera frames: differences of session stamps of a few s, good to eps |t| over 1/24 s
    assert np.all(np.diff(t) == pytest.approx(1 / 24.0, rel=roundoff(cond=24 * np.abs(t).max(), ops=2)))
    assert t[0] <= marks.times[0] + 1 / 24.0 and t[-1] >= marks.times[-1] - 1 / 24.0
    world = build_world({**TRACKING_WORLD.defaults(), **WALK})
    np.testing.assert_allclose(target, [world.target_position(tk) for tk in t], rtol=0,
                               atol=roundoff(scale=np.abs(target).max(), ops=10))  # the same path, evaluated again
    assert np.ptp(target[:, 0]) > 400.0                                       # the walker moved meanwhile

    # The fixed detector saw the truth's target direction (its clock is the session's, to a few ms).
    h_true = np.interp(marks.times, t, truth["target_angles"][1][:, 0])
    m = marks.data[:, 0]
    seen = ~np.isnan(m)
    assert seen.mean() > 0.9
    off = np.abs(m[seen] - angle_to_pixel(h_true[seen]))      # px; the driver stamps within a few ms
    assert np.median(off) < 2.0 and off.max() < 10.0   # a few ms of stamp at <= 860 px/s: ~2 px, spikes below 10
    # The gimbal's own detector saw the same target, through its angle (twice the mirror's, up to its backlash).
    k, mirror_h = gimbal.data[:, 0], gimbal.data[:, 2]
    h_true = np.interp(gimbal.times, t, truth["target_angles"][1][:, 0])
    ok = ~np.isnan(k)
    assert ok.mean() > 0.9 and np.ptp(mirror_h) > math.radians(3.0)         # it tracked: the mirror turned
    off = np.abs(k[ok] - angle_to_pixel(h_true[ok] - 2 * mirror_h[ok]))   # px; detector backlash up to 4 px
    assert np.median(off) < 5.0 and off.max() < 15.0
    # the 24 Hz truth interpolated at the driver's stamps (a few ms off) while the mirror turns at up to
    # half the target's 15 deg/s: ~0.1 deg; 0.3 deg
    np.testing.assert_allclose(mirror_h, np.interp(gimbal.times, t, truth["mirror_angles"][1][:, 0]),
                               atol=math.radians(0.3))

    # Normal and in_mirror: the analytic reflection geometry of the stored angles.
    angles, normals, inside = truth["mirror_angles"][1], truth["mirror_normal"][1], truth["in_mirror"][1]
    np.testing.assert_allclose(normals, [mirror_normal(h, v, (0, 0, 1)) for h, v in angles], rtol=0,
                               atol=roundoff(ops=10))  # unit vectors from the same formula
    assert inside.tolist() == [image_in_mirror(world.camera, p, (0, 0, 0), n, 1000.0, 125.0)
                               for p, n in zip(target, normals)]
    assert inside.all()                                                       # the active mirror kept it


def test_a_bad_world_setting_is_named_and_nothing_starts(tmp_path) -> None:
    with Session.create(tmp_path / "bad.h5") as s:
        s.set_world({"scene": "moonwalk"})
        with pytest.raises(ValidationError, match="world.scene"):
            s.add_instrument("fixed", "line_tracker", simulate=True)
        assert not s.instruments


def test_simulators_of_a_shared_world_share_its_clock_and_its_loads() -> None:
    """In process, on a stepped clock: one scene, one time base, and a SIM:LOAD seen by every simulator."""
    now = [5.0]
    shared = SharedWorld(build_world({**TRACKING_WORLD.defaults(), "scene": "still", "azimuth": 0.05}), lambda: now[0])
    tracker, mirror = LineTrackerModel(shared, seed=1), MirrorGimbalModel(shared, seed=2)
    assert tracker.execute("TIME?") == mirror.execute("TIME?") == ["OK 5000"]
    now[0] = 7.5
    tracker.advance(0.01)                      # the server's idle tick: the clock catches up with the world
    mirror.advance(100.0)                      # and never runs ahead of it
    assert tracker.execute("TIME?") == mirror.execute("TIME?") == ["OK 7500"]
    assert mirror.execute("SIM:LOAD LINE 0 0 3000 100 0 0") == ["OK"]
    assert tracker.world is mirror.world and tracker.world.target_position(7.5).tolist() == [0.0, 0.0, 3000.0]
    assert shared.world_at(6.0).target_position(6.0)[0] == pytest.approx(3000.0 * math.sin(0.05), rel=roundoff(ops=4))
    now[0] = 8.5
    tracker.advance(0.01)
    assert tracker.execute("SIM:TRUTH?")[1] == f"TRUTH TARGET {math.degrees(math.atan(0.1 / 3)):.4f} " \
        f"{float(angle_to_pixel(math.atan(0.1 / 3))):.3f}"
