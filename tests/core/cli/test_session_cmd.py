"""``mirrorlab session info | check | export`` on real files: statuses, live recordings, output."""

from __future__ import annotations

import csv
import io
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from mirrorlab.core import Session

from tests.support import run_cli


@pytest.fixture(scope="module")
def scanned(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A film-scanner recording (streams without a unit) plus /calibration, /truth and /report."""
    path = tmp_path_factory.mktemp("scan") / "scan.h5"
    with Session.create(path, operator="ana") as s:
        s.add_instrument("cam", "film_scanner", simulate=True, settings={"lines": 32}, simulator={"clock": "FAST"})
        s.record(seconds=0.5)
        s.write_group("calibration/cam", {"rms": 0.4, "residuals": np.zeros((7, 2))}, {"model": "projective"})
        s.write_group("truth/cam/markers", {"points": np.zeros((4, 2, 3))}, {"labels": ["S_A", "S_C"]})
        s.write_group("truth/cam/analytic", {"phi": np.zeros(4)})
        s.write_group("report", {"systematic": np.ones(3), "pairs": np.array([5, 6, 7])},
                      {"description": "demo summary"})
    return path


def test_check_exits_1_for_an_aborted_recording(tmp_path: Path) -> None:
    path = tmp_path / "aborted.h5"
    with pytest.raises(RuntimeError), Session.create(path) as s:
        s.write_group("calibration/cam", {"k": np.eye(3)})  # something kept, so the file stays
        raise RuntimeError("the instrument stopped")  # leaving `with` by an exception aborts it
    proc = run_cli("session", "check", str(path))
    assert proc.returncode == 1, proc.stdout
    assert "INCOMPLETE (status 'aborted'" in proc.stdout and "did not finish" in proc.stdout
    report = json.loads(run_cli("session", "check", str(path), "--json").stdout)
    assert report["complete"] is False and report["status"] == "aborted"


def test_info_says_a_live_recording_is_being_recorded(tmp_path: Path, acme_site: Path, with_sites) -> None:
    registry = with_sites(acme_site)
    path = tmp_path / "live.h5"
    with Session.create(path, registry=registry) as s:
        s.add_instrument("thermo", "acme_thermometer", simulate=True, settings={"rate": 100})
        s.start_recording()
        try:
            proc = run_cli("session", "info", str(path))
            data = json.loads(run_cli("session", "info", str(path), "--json").stdout)
        finally:
            s.stop_recording()
    assert proc.returncode == 0, proc.stderr
    first = proc.stdout.splitlines()[0]
    assert "being recorded right now by pid" in first and "crash" not in proc.stdout, first
    assert data["writer"] and data["writer"].startswith("pid ")


def test_info_shows_units_only_when_declared_and_every_group(scanned: Path) -> None:
    proc = run_cli("session", "info", str(scanned))
    assert proc.returncode == 0, proc.stderr
    assert "[]" not in proc.stdout, proc.stdout
    lines = proc.stdout.splitlines()
    assert any(line.strip().startswith("frames: ") and "32×512 uint8" in line for line in lines), lines
    for text in ("/calibration/cam: 2 datasets", "/truth/cam: 2 groups", "/report: 2 datasets (demo summary)"):
        assert any(text in line for line in lines), (text, lines)
    groups = json.loads(run_cli("session", "info", str(scanned), "--json").stdout)["groups"]
    assert groups["/calibration/cam"] == {"datasets": 2, "groups": 0, "description": ""}


def test_info_shows_text_that_is_not_utf8_with_replacement_characters_and_says_so(tmp_path: Path) -> None:
    """Latin-1 text written by another tool: a fixed-length bytes attribute and a variable-length string
    declared UTF-8 (h5py reads its bytes as lone surrogates); not a damaged file, never raw bytes out."""
    import h5py

    path = tmp_path / "latin1.h5"
    with Session.create(path, operator="ana"):
        pass
    with h5py.File(path, "r+") as f:
        f.attrs["operator"] = np.bytes_(b"J\xf6rg")
        f.attrs.create("description", b"caf\xe9 lab", dtype=h5py.string_dtype("utf-8"))
        f.create_group("report").attrs["description"] = np.bytes_(b"r\xe9sum\xe9")
        f["report"].create_dataset("x", data=[1.0])
    proc = subprocess.run([sys.executable, "-m", "mirrorlab.core.cli", "session", "info", str(path)], capture_output=True)
    assert proc.returncode == 0, proc.stderr
    out = proc.stdout.decode("utf-8")                 # strict: no undecodable bytes reach the terminal
    assert "operator: J\ufffdrg\n" in out and "description: caf\ufffd lab\n" in out
    assert "/report: 1 dataset (r\ufffdsum\ufffd)" in out
    assert ("note: text in the file that is not valid UTF-8, shown with \ufffd for the bytes that could not be "
            "decoded: attributes.description, attributes.operator, groups./report.description") in out
    data = json.loads(run_cli("session", "info", str(path), "--json").stdout)
    assert data["attributes"]["operator"] == "J\ufffdrg"
    assert data["not_utf8"] == ["attributes.description", "attributes.operator", "groups./report.description"]


def test_export_names_columns_with_units(scanned: Path, tmp_path: Path, acme_site: Path) -> None:
    rows = list(csv.reader(io.StringIO(run_cli("session", "export", str(scanned), "cam/frame_index").stdout)))
    assert rows[0] == ["time_s", "frame_index"]
    header = next(csv.reader(io.StringIO(run_cli("session", "export", str(scanned), "/truth/cam/markers/points").stdout)))
    assert header[:4] == ["points_S_A_0", "points_S_A_1", "points_S_A_2", "points_S_C_0"] and len(header) == 6
    header = next(csv.reader(io.StringIO(run_cli("session", "export", str(scanned), "/report/pairs").stdout)))
    assert header == ["pairs"]
    scalar = run_cli("session", "export", str(scanned), "/calibration/cam/rms")
    assert scalar.returncode == 0 and scalar.stdout.splitlines() == ["rms", "0.4"], scalar.stderr


def test_export_writes_the_file_it_names_and_says_what_it_wrote(scanned: Path, tmp_path: Path) -> None:
    """``--format npy`` writes exactly ``--out`` and reports it (it wrote ``fr.csv.npy`` and said
    ``wrote fr.csv``); a name numpy would change is refused before anything is written (exit 2);
    a CSV file gets a one-line summary too (CSV on stdout stays bare)."""
    refused = run_cli("session", "export", str(scanned), "cam/frame_index", "--format", "npy",
                      "--out", str(tmp_path / "fr.csv"))
    assert refused.returncode == 2
    assert refused.stderr.strip() == (f"mirrorlab: error: --out: {tmp_path / 'fr.csv'} does not fit --format npy: "
                                      "name the file fr.npy")
    assert list(tmp_path.iterdir()) == []
    npy = run_cli("session", "export", str(scanned), "cam/frame_index", "--format", "npy", "--out", str(tmp_path / "fr.npy"))
    assert npy.returncode == 0, npy.stderr
    with Session.open(scanned) as s:
        _, expected = s.stream("cam", "frame_index")
    n = len(expected)  # how many frames 0.5 s of scanning gave depends on the machine's load
    assert npy.stdout.strip() == f"wrote {tmp_path / 'fr.npy'}: {n} sample{'s' * (n != 1)} of scalar int64"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["fr.npy"]
    assert np.array_equal(np.load(tmp_path / "fr.npy"), expected)
    assert run_cli("session", "export", str(scanned), "cam/frame_index", "--out", str(tmp_path / "x.npy")).returncode == 2
    table = run_cli("session", "export", str(scanned), "cam/frame_index", "--out", str(tmp_path / "fr.csv"))
    assert table.returncode == 0, table.stderr
    assert table.stdout.strip() == f"wrote {tmp_path / 'fr.csv'}: {len(expected)} rows of 2 columns"
    assert len((tmp_path / "fr.csv").read_text().splitlines()) == len(expected) + 1


def test_export_a_controller_stream(tmp_path: Path) -> None:
    """A controller's stream exports like an instrument's (it failed with a KeyError)."""
    from tests.support import REPO

    out = tmp_path / "loop.h5"
    proc = run_cli("run", str(REPO / "sessions" / "follow_loop.toml"), "--out", str(out), "--set", "steps.0.seconds=0.1",
                   "--set", "steps.1.seconds=0.5", "--no-progress")
    assert proc.returncode == 0, proc.stderr
    exported = run_cli("session", "export", str(out), "loop/latency")
    assert exported.returncode == 0, exported.stderr
    rows = list(csv.reader(io.StringIO(exported.stdout)))
    with Session.open(out) as s:
        times, _ = s.stream("loop", "latency")
    assert rows[0] == ["time_s", "latency_s"] and len(rows) == len(times) + 1 > 1
