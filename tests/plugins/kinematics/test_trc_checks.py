"""TRC files that disagree with themselves (issue 20): rows out of time order, infinite values, a
NumMarkers far beyond the columns. Each is reported naming the file and where, never stored as is."""

from __future__ import annotations

import tracemalloc
import warnings
from pathlib import Path

import numpy as np
import pytest
from mirrorlab.core import MirrorlabWarning
from mirrorlab.plugins.kinematics.errors import KinematicsIOError
from mirrorlab.plugins.kinematics.io import read_trc


def _trc(path: Path, markers: int, rows: list[list[str]], declared: int | None = None) -> Path:
    """A tab-separated TRC file of ``markers`` markers (NumMarkers ``declared``, default the same)."""
    names = "\t\t\t".join(f"M{k}" for k in range(1, markers + 1))
    coords = "\t".join(f"X{k}\tY{k}\tZ{k}" for k in range(1, markers + 1))
    path.write_text("PathFileType\t4\t(X/Y/Z)\tm.trc\nDataRate\tCameraRate\tNumFrames\tNumMarkers\tUnits\n"
                    f"100\t100\t{len(rows)}\t{declared or markers}\tmm\nFrame#\tTime\t{names}\t\t\n\t\t{coords}\n\n"
                    + "".join("\t".join(r) + "\n" for r in rows))
    return path


def _row(frame: int, markers: int, value: str = "1.5") -> list[str]:
    return [str(frame), f"{(frame - 1) / 100:g}", *[value] * (3 * markers)]


def test_rows_in_reverse_time_order_are_refused(tmp_path: Path) -> None:
    """They were stored reversed: frame 3 first, with the time of frame 1."""
    p = _trc(tmp_path / "m.trc", 2, [_row(3, 2), _row(2, 2), _row(1, 2)])
    with pytest.raises(KinematicsIOError) as caught:
        read_trc(p)
    assert str(caught.value) == (f"{p}: line 8: Frame# 2 after 3 (line 7); the rows must be in increasing time order: "
                                 "sort them by Frame# and remove repeated frames")
    repeated = _trc(tmp_path / "r.trc", 1, [_row(1, 1), _row(2, 1), _row(2, 1)])
    with pytest.raises(KinematicsIOError, match=r"line 9: Frame# 2 after 2 \(line 8\)"):
        read_trc(repeated)
    times = _trc(tmp_path / "t.trc", 1, [_row(1, 1), ["2", "0.5", "1", "1", "1"], ["3", "0.2", "1", "1", "1"]])
    with pytest.raises(KinematicsIOError, match=r"line 9: Time 0.2 after 0.5 \(line 8\)"):
        read_trc(times)


@pytest.mark.parametrize("value", ["1e999", "-1e999", "inf"])
def test_an_infinite_value_is_refused_naming_line_and_column(value: str, tmp_path: Path) -> None:
    """``1e999`` was stored as inf."""
    rows = [_row(1, 2), _row(2, 2)]
    rows[1][6] = value  # Y of the second marker: column 7
    p = _trc(tmp_path / "m.trc", 2, rows)
    with pytest.raises(KinematicsIOError) as caught:
        read_trc(p)
    assert str(caught.value) == (f"{p}: line 8, column 7: value {float(value)} is not a finite coordinate; correct it, "
                                 "or leave the cell empty for a missing marker")


def test_num_markers_beyond_the_columns_is_reported_and_sized_by_the_data(tmp_path: Path) -> None:
    """``NumMarkers=100000`` over 51 markers' columns allocated 223 MB of NaN."""
    p = _trc(tmp_path / "m.trc", 51, [_row(k, 51) for k in range(1, 41)], declared=100_000)
    tracemalloc.start()
    try:
        with pytest.warns(MirrorlabWarning) as caught:
            d = read_trc(p)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert [str(w.message) for w in caught] == [
        f"{p}: the header's NumMarkers is 100000 but the coordinate labels (line 5) and the data rows hold columns "
        "of 51 markers; reading 51: correct NumMarkers (line 3)"]
    assert d.points.shape == (40, 51, 3) and len(d.labels) == 51 and np.all(d.points == 1.5)
    # the file's text and rows are a few hundred kB; 100 000 markers of NaN per row would be 96 MB
    assert peak < 4_000_000, peak


def test_a_header_matching_its_columns_is_read_without_warning(tmp_path: Path) -> None:
    p = _trc(tmp_path / "m.trc", 3, [_row(1, 3), [*_row(2, 2), "", "", ""]])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        d = read_trc(p)
    assert d.points.shape == (2, 3, 3) and np.isnan(d.points[1, 2]).all()


def test_an_import_step_name_is_an_identifier(tmp_path: Path) -> None:
    """The step's ``name`` names ``/markers/<name>``: checked when the recipe is validated."""
    from tests.support import run_cli

    p = _trc(tmp_path / "m.trc", 1, [_row(1, 1)])
    recipe = tmp_path / "r.toml"
    recipe.write_text(f'[[steps]]\naction = "import_markers"\nfile = "{p}"\nname = "/truth/fake"\n')
    proc = run_cli("run", str(recipe), "--check")
    assert proc.returncode == 2
    assert f"{recipe}: steps.0.name: '/truth/fake' is not a label" in proc.stderr
