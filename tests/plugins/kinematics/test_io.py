"""C3D / TRC / Qualisys readers and C3D / CSV writers."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from mirrorlab.core.errors import MirrorlabWarning
from mirrorlab.plugins.kinematics import (
    KinematicsIOError,
    read_c3d,
    read_qualisys_tsv,
    read_trc,
    write_c3d,
    write_csv,
)

from tests.derived_bounds import F32
from tests.tolerances import abs_err, roundoff

MISSING = {"SCAP_CP": 92, "LARMl": 49, "STERr": 32, "STERl": 31, "STYLu": 29, "LASTC": 23, "MEDH": 22,
           "boite:droite_int": 10, "boite:gauche_ext": 6, "boite:gauche_int": 5, "boite:droite_ext": 3,
           "CLAV_post": 2, "CLAVl": 1}


def test_read_c3d_real(data_dir):
    d = read_c3d(data_dir / "mocap" / "markers_analogs.c3d")
    assert d.rate == 100.0 and d.points.shape == (580, 51, 3) and len(d.labels) == 51
    assert d.labels[0] == "boite:gauche_ext" and "Daphnee:ACRO_tip" in d.labels
    counts = {lab.removeprefix("Daphnee:"): int(n) for lab, n in zip(d.labels, np.isnan(d.points[..., 0]).sum(0)) if n}
    assert counts == MISSING
    assert np.isnan(d.points).any(-1).sum() == np.isnan(d.points).all(-1).sum()  # whole points missing
    assert d.time[0] == 0.0 and d.time[-1] == pytest.approx(5.79, abs=roundoff(scale=5.79, ops=2))  # 579 / 100.0
    with pytest.raises(KinematicsIOError, match="similar"):
        d.marker("ACRO")


def test_read_trc_real_truncated(data_dir):
    with pytest.warns(MirrorlabWarning, match="declares 652 frames but the file holds 93"):
        d = read_trc(data_dir / "mocap" / "markers.trc")
    assert d.rate == 100.0 and d.points.shape == (93, 51, 3)  # header says 652 frames
    assert d.labels[:2] == ["ASISl", "ASISr"] and d.labels[0] != ""
    # decimal text parsed (correctly rounded) and scaled by 1 (mm): one rounding
    assert d.points[0, 0] == pytest.approx([733.7041, 80.9832, 191.8668], abs=roundoff(scale=733.7041))


def test_read_trc_units_and_blanks(tmp_path):
    p = tmp_path / "m.trc"
    p.write_text(
        "PathFileType\t4\t(X/Y/Z)\tm.trc\n"
        "DataRate\tCameraRate\tNumFrames\tNumMarkers\tUnits\tOrigDataRate\tOrigDataStartFrame\tOrigNumFrames\n"
        "50\t50\t2\t2\tm\t50\t1\t2\n"
        "Frame#\tTime\tA\t\t\tB\t\t\n"
        "\t\tX1\tY1\tZ1\tX2\tY2\tZ2\n"
        "\n"
        "1\t0\t0.1\t0.2\t0.3\t\t\t\n"
        "2\t0.02\t0.1\t0.2\t0.3\t1\t2\t3\n"
    )
    d = read_trc(p)
    assert d.labels == ["A", "B"] and d.rate == 50.0
    # metres × 1000: the parsed decimal's rounding and the product's
    assert d.points[0, 0] == pytest.approx([100, 200, 300], abs=roundoff(scale=300.0, ops=2))
    assert np.isnan(d.points[0, 1]).all()
    assert d.points[1, 1] == pytest.approx([1000, 2000, 3000], abs=roundoff(scale=3000.0, ops=2))


def test_c3d_round_trip(tmp_path):
    rng = np.random.default_rng(0)
    pts = rng.normal(0, 500, (40, 4, 3))
    pts[5:9, 2] = np.nan
    labels = ["S_A", "S_C", "hand", "box"]
    p = tmp_path / "recon.c3d"
    write_c3d(p, labels, 42.0, pts)
    d = read_c3d(p)
    assert d.labels == labels and d.rate == 42.0
    assert np.array_equal(np.isnan(d.points), np.isnan(pts))
    assert abs_err(d.points, pts) <= F32 * np.nanmax(np.abs(pts))  # float32 storage: one rounding

    with pytest.raises(KinematicsIOError):
        write_c3d(p, labels[:2], 42.0, pts)


def test_csv_export(tmp_path):
    pts = np.arange(12.0).reshape(2, 2, 3)
    pts[1, 0] = np.nan
    p = tmp_path / "m.csv"
    write_csv(p, ["a", "b"], 100.0, pts, first_frame=10)
    lines = p.read_text().splitlines()
    assert lines[0] == "frame,time_s,a_x_mm,a_y_mm,a_z_mm,b_x_mm,b_y_mm,b_z_mm"
    assert lines[2] == "11,0.11,,,,9,10,11"


def test_qualisys_reader(data_dir):
    d = read_qualisys_tsv(data_dir / "trajectories" / "6_throws_minimal_tracking_loss.tsv")
    assert d.rate == 300.0 and d.points.shape == (6282, 11, 3)
    assert np.isnan(d.points[:, 2:5, 0]).sum(0).tolist() == [219, 339, 220]
    assert int(np.isfinite(d.points[:, 6:, 0]).sum()) == 4021


def test_reader_errors(tmp_path):
    with pytest.raises(KinematicsIOError, match="no such"):
        read_c3d(tmp_path / "none.c3d")
    bad = tmp_path / "bad.c3d"
    bad.write_bytes(b"not a c3d")
    with pytest.raises(KinematicsIOError):
        read_c3d(bad)
    t = tmp_path / "bad.trc"
    t.write_text("hello\n")
    with pytest.raises(KinematicsIOError, match="TRC"):
        read_trc(t)


def _trc(path, header_markers: int, names: list[str], rows: list[str]) -> None:
    path.write_text(
        "PathFileType\t4\t(X/Y/Z)\tm.trc\n"
        "DataRate\tCameraRate\tNumFrames\tNumMarkers\tUnits\n"
        f"100\t100\t{len(rows)}\t{header_markers}\tmm\n"
        "Frame#\tTime\t" + "\t\t\t".join(names) + "\t\t\n"
        "\t\t" + "\t".join(f"X{k}\tY{k}\tZ{k}" for k in range(1, len(names) + 1)) + "\n"
        "\n" + "".join(r + "\n" for r in rows))


def test_trc_values_past_num_markers_are_a_warning(tmp_path):
    p = tmp_path / "m.trc"
    _trc(p, 2, ["A", "B", "C"], ["1\t0\t1\t2\t3\t4\t5\t6\t\t\t", "2\t0.01\t1\t2\t3\t4\t5\t6\t7\t8\t9"])
    with pytest.warns(MirrorlabWarning) as caught:
        d = read_trc(p)
    assert [str(w.message) for w in caught] == [
        f"{p}: line 8 holds values of 3 markers but the header's NumMarkers is 2; reading the first 2: "
        "correct NumMarkers (line 3) to read the others"]
    assert d.labels == ["A", "B"] and d.points.shape == (2, 2, 3)
    # empty cells past the markers (trailing tabs, as many writers leave) are no values
    _trc(p, 2, ["A", "B"], ["1\t0\t1\t2\t3\t4\t5\t6\t\t\t", "2\t0.01\t1\t2\t3\t4\t5\t6\t\t"])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert read_trc(p).points.shape == (2, 2, 3)
