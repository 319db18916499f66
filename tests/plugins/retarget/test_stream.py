"""The streaming filter (spec §7), its sinks, and the BVH / C3D / session sources."""

from __future__ import annotations

import csv

import numpy as np
import pytest
from mirrorlab.core import Session
from mirrorlab.plugins.retarget import Chain, LengthDriftWarning, SourceError, approximate
from mirrorlab.plugins.retarget.sources import read_bvh_chain, read_marker_chain, session_marker_chain
from mirrorlab.plugins.retarget.stream import CSVSink, MemorySink, RetargetFilter, SessionSink, compute_for, poses

from tests.plugins.retarget.optimum import optimum_bounds
from tests.support import SHARED_DATA
from tests.tolerances import EPS, abs_err, roundoff

from .test_fixtures import T2_IN, T2_OUT, objective, t3_input

BVH = SHARED_DATA / "bvh" / "01_01.bvh"
C3D = SHARED_DATA / "mocap" / "markers_analogs.c3d"
ARM = ["RightArm", "RightForeArm", "RightHand", "RFingers"]
CMU_MM = 25.4 / 0.45      # mm per CMU ASF length unit


def test_deterministic_paper_mode_is_the_batch_paper_mode_and_keeps_the_lag_bounds() -> None:
    X = t3_input()
    t = np.arange(100) / 30.0
    sink = MemorySink()
    stats = RetargetFilter(compute_for(X, T2_OUT, "paper", sweeps=3), 30.0, [sink]).run(poses(X, t))
    out = sink.arrays()
    assert stats.frames_in == stats.computed == stats.published == 100 and stats.dropped == 0
    assert out["index"].tolist() == list(range(100)) and abs_err(out["time"], t) <= roundoff(scale=t.max())
    batch = approximate(X, T2_OUT, "paper", sweeps=3)
    # the same 3 sweeps from the same start, one row vs a block of rows: the rounding of 3 sweeps x 4
    # angles x up to 10 trial evaluations on angles of ~1 rad (not amplified: the tracking contracts)
    assert np.abs(out["q"] - batch.q).max() <= roundoff(scale=max(1.0, np.abs(batch.q).max()), ops=3 * 4 * 10)
    ref = approximate(X, T2_OUT, "lm", max_iter=100)
    assert (out["f"] - ref.f).max() <= 0.2 and out["f"].mean() <= 1.02 * ref.f.mean()   # the spec's lag bounds
    lm = MemorySink()
    RetargetFilter(compute_for(X, T2_OUT, "lm"), 30.0, [lm]).run(poses(X, t))
    # LM streamed (20 iterations a frame) and batch (100): both stop on their tolerances near the
    # same minimum, each within its bound of it (tests/plugins/retarget/optimum.py)
    obj = objective(T2_IN, T2_OUT)
    arms = obj.arms(X)
    close = optimum_bounds(obj, lm.arrays()["q"], arms).f + optimum_bounds(obj, ref.q, arms).f
    assert (np.abs(lm.arrays()["f"] - ref.f) <= close).all()


def test_realtime_mode_counters_are_consistent() -> None:
    X = t3_input(200)
    sink = MemorySink()
    stats = RetargetFilter(compute_for(X, T2_OUT), 400.0, [sink]).run(poses(X, np.arange(200) / 400.0), realtime=True)
    idx = sink.arrays()["index"]
    assert stats.frames_in == 200
    assert stats.computed + stats.dropped == stats.frames_in        # every input is solved or overwritten
    assert 0 < stats.published <= stats.computed
    assert np.all(np.diff(idx) > 0) and idx[-1] == 199              # in order; the last pose is always served
    assert len(stats.latencies) == stats.published and min(stats.latencies) >= 0


def test_csv_and_session_sinks(tmp_path) -> None:
    X = t3_input(20)
    t = np.arange(20) / 10.0
    path = tmp_path / "out.csv"
    with Session.create(tmp_path / "s.h5", description="retarget sink") as s:
        sinks = [CSVSink(path, T2_OUT.dof), SessionSink(s, "results/retarget_stream/run-0001", {"method": "lm"})]
        RetargetFilter(compute_for(X, T2_OUT), 10.0, sinks).run(poses(X, t))
    rows = list(csv.reader(path.open()))
    assert rows[0][:3] == ["frame", "time_s", "q0_rad"] and len(rows) == 21
    with Session.open(tmp_path / "s.h5") as s:
        run = "results/retarget_stream/run-0001"
        assert s.node(f"{run}/q").shape == (20, 4) and s.attributes(run)["method"] == "lm"
        # the CSV prints q with 10 significant digits (half a unit: 5e-10 relative), parsed back exactly
        q = s.read(f"{run}/q")[:, 0]
        assert (np.abs(q - [float(r[2]) for r in rows[1:]]) <= (5e-10 + EPS) * np.abs(q)).all()


@pytest.mark.data
def test_bvh_reader_reproduces_the_elbow_angle_range_and_constant_lengths() -> None:
    m = read_bvh_chain(BVH, ARM, scale=CMU_MM, skip=1)
    # the file's "Frame Time: .0083333" is 1/120 s to its printed digits (±5e-8 s: 6e-6 relative)
    assert m.joints.shape == (2751, 4, 3) and m.rate == pytest.approx(120.0, rel=5e-8 / 0.0083333)
    u = m.joints[:, 0] - m.joints[:, 1]
    v = m.joints[:, 2] - m.joints[:, 1]
    elbow = 180 - np.degrees(np.arccos((u * v).sum(-1) / np.linalg.norm(u, axis=-1) / np.linalg.norm(v, axis=-1)))
    # the motion's documented range, to 1 decimal (±0.05°), plus the arccos of joints rounded at up to
    # 2.8 m over segments of ~200 mm (an elbow 6.6° from straight keeps arccos well conditioned)
    lever = np.abs(m.joints).max() / min(np.linalg.norm(u, axis=-1).min(), np.linalg.norm(v, axis=-1).min())
    printed = 0.05 + np.degrees(roundoff(cond=lever, ops=10) / np.sin(np.radians(6.6)))
    assert elbow.min() == pytest.approx(6.6, abs=printed) and elbow.max() == pytest.approx(128.1, abs=printed)
    seg = np.linalg.norm(np.diff(m.joints, axis=1), axis=-1)
    # fixed offsets carried through the rotations of up to 2.8 m of chain: lengths constant to their
    # rounding (the former 1e-9 was just above it)
    size = np.abs(m.joints).max()
    assert np.ptp(seg, axis=0).max() <= 2 * roundoff(scale=size, ops=20)
    # the BVH offsets as printed ("-5.24190 -0.00000 -0.00000", "-3.44417 ..."), scaled to mm
    assert seg[0, :2] == pytest.approx([5.2419 * CMU_MM, 3.44417 * CMU_MM], abs=2 * roundoff(scale=size, ops=20))
    with pytest.raises(SourceError, match="no joint 'RightWing'.*RightForeArm"):
        read_bvh_chain(BVH, ["RightArm", "RightWing"])


@pytest.mark.data
def test_c3d_and_session_marker_chains(tmp_path) -> None:
    joints = ["ACRO_tip", "EPICl+EPICm", "STYLr+STYLu"]
    m = read_marker_chain(C3D, joints)
    assert m.joints.shape == (580, 3, 3) and m.rate == 100.0
    from mirrorlab.plugins.kinematics.store import import_markers

    with Session.create(tmp_path / "m.h5") as s:
        import_markers(s, C3D, "trial")
    ms = session_marker_chain(tmp_path / "m.h5", "trial", joints)
    assert np.array_equal(np.isnan(ms.joints), np.isnan(m.joints))
    assert np.nanmax(np.abs(ms.joints - m.joints)) == 0.0
    # a spherical shoulder + hinge elbow copies three points when the lengths match: f is the skin-marker drift
    lengths = np.nanmedian(np.linalg.norm(np.diff(m.joints, axis=1), axis=-1), axis=0)
    with pytest.warns(LengthDriftWarning, match="input arm 0 .* 5 %"):     # skin markers: the arm stretches 7 %
        res = approximate(m.joints, Chain(lengths, ["zyx", "y"]))
    ok = np.isfinite(res.f)
    # skin markers drift ~7 % along the arm (the warning): a median residual of centimetres would mean
    # a wrong copy; 10 mm is a plausibility margin on real data, not a precision claim
    assert ok.sum() > 300 and np.sqrt(np.median(res.f[ok])) < 10.0       # mm

    with pytest.raises(SourceError, match="joint 'ELBOW'"):
        read_marker_chain(C3D, ["ACRO_tip", "ELBOW"])
