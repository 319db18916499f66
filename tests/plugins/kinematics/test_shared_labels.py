"""Two different markers under one label: never a silent "first one wins".

The file below has two ``RKNE`` 116 mm apart (markers 1 and 4): a knee marker that stays put and a
second one that moves. Reading warns; naming ``RKNE`` is refused as ambiguous (exit 2) with the
marker numbers and how to pick each; ``RKNE#4`` picks the second one, in every command.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from mirrorlab.core.errors import MirrorlabWarning
from mirrorlab.plugins.kinematics import KinematicsIOError, read_c3d, read_trc, write_c3d
from mirrorlab.plugins.kinematics.io import resolve_label

from tests.support import run_cli

LABELS = ["RKNE", "LKNE", "RANK", "RKNE", "LANK"]
AMBIGUOUS = "marker 'RKNE' is ambiguous: it names markers 1 ('RKNE') and 4 ('RKNE'); give 'RKNE#1' or 'RKNE#4'"
SPEED = 0.5  # m/s of the second RKNE (along x); the other markers stand still


def _points() -> np.ndarray:
    t = np.arange(60) / 100.0
    base = np.array([[0.0, 0.0, 500.0], [0.0, 200.0, 500.0], [0.0, 0.0, 100.0], [116.0, 0.0, 500.0],
                     [0.0, 200.0, 100.0]])
    pts = np.repeat(base[None], t.size, axis=0)
    pts[:, 3, 0] += 1000.0 * SPEED * t
    return pts


@pytest.fixture(scope="module")
def trial(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("shared") / "trial.c3d"
    write_c3d(path, LABELS, 100.0, _points())
    return path


def test_reading_warns_and_naming_the_label_is_refused(trial: Path) -> None:
    with pytest.warns(MirrorlabWarning) as caught:
        d = read_c3d(trial)
    assert [str(w.message) for w in caught] == [
        f"{trial}: markers share labels: 'RKNE' (markers 1 and 4); such a label is refused as ambiguous: name one "
        "marker as LABEL#N (its number), e.g. 'RKNE#4'"]
    assert d.labels == LABELS  # the file's labels, as they are
    with pytest.raises(KinematicsIOError) as info:
        d.marker("RKNE")
    assert str(info.value) == AMBIGUOUS
    assert np.array_equal(d.marker("RKNE#4"), d.points[:, 3]) and np.array_equal(d.marker("RKNE#1"), d.points[:, 0])
    assert np.linalg.norm(d.marker("RKNE#4")[0] - d.marker("RKNE#1")[0]) == pytest.approx(116.0, rel=1e-6)


def test_label_number_syntax() -> None:
    assert resolve_label(LABELS, "RKNE#4") == 3 and resolve_label(LABELS, "LKNE") == 1
    assert resolve_label(["S:RKNE", "S:LKNE", "S:RKNE"], "RKNE#3") == 2  # the tail of a prefixed label
    with pytest.raises(KinematicsIOError, match=r"no marker 'RKNE#2': marker 2 is 'LKNE'; LABEL#N names marker N"):
        resolve_label(LABELS, "RKNE#2")
    with pytest.raises(KinematicsIOError, match=r"no marker 'RKNE#9': there are 5 markers"):
        resolve_label(LABELS, "RKNE#9")
    with pytest.raises(KinematicsIOError, match=r"it names markers 1 \('A:RKNE'\) and 2 \('B:RKNE'\); give 'A:RKNE' "
                                                r"or 'B:RKNE'"):
        resolve_label(["A:RKNE", "B:RKNE"], "RKNE")
    assert resolve_label(["A#1", "B"], "A#1") == 0  # a label that itself holds '#' is still found as it is


def test_trc_with_a_shared_label_warns_too(tmp_path: Path) -> None:
    p = tmp_path / "m.trc"
    p.write_text("PathFileType\t4\t(X/Y/Z)\tm.trc\n"
                 "DataRate\tCameraRate\tNumFrames\tNumMarkers\tUnits\n"
                 "100\t100\t1\t2\tmm\n"
                 "Frame#\tTime\tRKNE\t\t\tRKNE\t\t\n"
                 "\t\tX1\tY1\tZ1\tX2\tY2\tZ2\n"
                 "\n"
                 "1\t0\t1\t2\t3\t4\t5\t6\n")
    with pytest.warns(MirrorlabWarning, match=r"m.trc: markers share labels: 'RKNE' \(markers 1 and 2\)"):
        assert read_trc(p).labels == ["RKNE", "RKNE"]


def _json(proc) -> dict:
    assert proc.returncode == 0, proc.stderr
    return json.loads(proc.stdout)


def test_derivatives_refuse_the_shared_label_and_pick_by_number(trial: Path) -> None:
    proc = run_cli("kinematics", "derivatives", str(trial), "--markers", "RKNE", "--no-progress")
    assert proc.returncode == 2 and proc.stderr.splitlines()[-1] == f"mirrorlab: error: --markers: {AMBIGUOUS}"
    picked = _json(run_cli("kinematics", "derivatives", str(trial), "--markers", "RKNE#4", "--json", "--no-progress"))
    # the moving one: 0.5 m/s = 500 mm/s (a smoothing spline of a straight line at constant speed is exact up to its
    # regularisation; 1e-6 relative is far looser than that and far tighter than telling 0.5 from 0)
    assert list(picked["markers"]) == ["RKNE#4"]
    assert picked["markers"]["RKNE#4"]["max_speed_mm_s"] == pytest.approx(1000 * SPEED, rel=1e-6)
    every = _json(run_cli("kinematics", "derivatives", str(trial), "--json", "--no-progress"))
    assert list(every["markers"]) == ["RKNE#1", "LKNE", "RANK", "RKNE#4", "LANK"]  # no name hides another
    assert every["markers"]["RKNE#1"]["max_speed_mm_s"] < 1e-3 * SPEED
    assert every["markers"]["RKNE#4"] == picked["markers"]["RKNE#4"]


def test_rigid_and_angles_refuse_it_too(trial: Path) -> None:
    proc = run_cli("kinematics", "rigid", str(trial), "--markers", "RKNE,LKNE,RANK", "--no-progress")
    assert proc.returncode == 2 and AMBIGUOUS in proc.stderr
    rigid = _json(run_cli("kinematics", "rigid", str(trial), "--markers", "RKNE#1,LKNE,RANK,LANK", "--json",
                          "--no-progress"))
    assert rigid["markers"] == ["RKNE#1", "LKNE", "RANK", "LANK"] and rigid["frames_with_pose"] == 60
    proc = run_cli("kinematics", "angles", str(trial), "--P0", "LANK", "--P1", "RKNE", "--P2", "RANK", "--P3", "LKNE",
                   "--no-progress")
    assert proc.returncode == 2 and f"--P1: {AMBIGUOUS}" in proc.stderr


def test_a_session_keeps_the_labels_and_refuses_the_shared_one(trial: Path, tmp_path: Path) -> None:
    session = tmp_path / "s.h5"
    proc = run_cli("kinematics", "import", str(trial), "--session", str(session), "--json")
    assert proc.returncode == 0 and json.loads(proc.stdout)["labels"] == LABELS
    assert proc.stderr.startswith("mirrorlab: warning: ") and len(proc.stderr.splitlines()) == 1
    proc = run_cli("kinematics", "derivatives", str(session), "--markers", "RKNE", "--no-progress")
    assert proc.returncode == 2 and AMBIGUOUS in proc.stderr
    picked = _json(run_cli("kinematics", "derivatives", str(session), "--markers", "RKNE#4", "--json",
                           "--no-progress"))
    assert picked["markers"]["RKNE#4"]["max_speed_mm_s"] == pytest.approx(1000 * SPEED, rel=1e-6)
    csv, c3d = tmp_path / "out.csv", tmp_path / "out.c3d"
    for out in (csv, c3d):
        assert run_cli("kinematics", "export", str(session), "trial", "--out", str(out)).returncode == 0
    assert csv.read_text().splitlines()[0].split(",")[2:14:3] == ["RKNE#1_x_mm", "LKNE_x_mm", "RANK_x_mm", "RKNE#4_x_mm"]
    with pytest.warns(MirrorlabWarning, match="markers share labels"):
        assert read_c3d(c3d).labels == LABELS  # a C3D keeps the labels as they are
