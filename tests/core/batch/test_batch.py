"""`mirrorlab batch` and chunked frames on a real LocalCluster (2 worker processes, one thread each):
results equal serial runs bit for bit, a failing input is reported while the others go on.

The sessions are short demo recordings (``rssr_acquire.toml`` at 6 frames/s, 12 and 10 frames),
recorded once for the module; every analysis runs on copies.
"""

from __future__ import annotations

import csv
import hashlib
import shutil
from pathlib import Path

import h5py
import pytest
from mirrorlab.core import Session
from mirrorlab.core.batch.cluster import dask_client
from mirrorlab.core.batch.executors import ChunkedExecutor
from mirrorlab.core.recipes import load_recipe, run_analysis, run_recipe

from tests.support import REPO, run_cli

ACQUIRE = REPO / "sessions" / "rssr_acquire.toml"
ANALYSIS = REPO / "sessions" / "rssr_analysis.toml"
NO_CONTINUITY = "steps.7.parameters.continuity=false"  # pair_mirror, frame by frame: chunked as well


@pytest.fixture(scope="module")
def sessions(tmp_path_factory: pytest.TempPathFactory) -> list[Path]:
    folder = tmp_path_factory.mktemp("recorded")
    out = []
    for name, frames in (("trial1.h5", 12), ("trial2.h5", 10)):
        recipe = load_recipe(ACQUIRE, ["instruments.rssr.settings.frame_rate=6",
                                       f"instruments.rssr.settings.scene_frames={frames}"])
        out.append(run_recipe(recipe, folder / name))
    return out


def _digest(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _datasets(path: Path) -> dict[str, tuple[str, tuple[int, ...], bytes]]:
    """Every dataset under /results and /report: dtype, shape and bytes."""
    found = {}
    with h5py.File(path, "r") as f:
        for top in ("results", "report"):
            f[top].visititems(lambda name, obj, top=top: found.__setitem__(
                f"{top}/{name}", (str(obj.dtype), obj.shape, obj[()].tobytes())) if isinstance(obj, h5py.Dataset)
                else None)
    return found


def _worker_setup() -> tuple[int, str | None, bool]:
    import os

    import cv2
    import dask

    return cv2.getNumThreads(), os.environ.get("MALLOC_TRIM_THRESHOLD_"), dask.config.get("distributed.worker.profile.enabled")


def _input_digests(path: Path) -> list[str]:
    """``@input_sha256`` of every result run, in order."""
    with Session.open(path) as s:
        return [s.result(r).attrs["input_sha256"] for r in s.results()]


def _serial(source: Path, target: Path, overrides: list[str] = ()) -> Path:
    shutil.copyfile(source, target)
    return run_analysis(load_recipe(ANALYSIS, overrides, analysis=True), target)


@pytest.mark.slow
def test_batch_equals_serial_and_reports_a_failing_input(sessions: list[Path], tmp_path: Path) -> None:
    garbage = tmp_path / "broken.h5"
    garbage.write_text("not an HDF5 file\n")
    before = [_digest(p) for p in sessions]
    proc = run_cli("batch", str(ANALYSIS), *map(str, sessions), str(garbage), "--out", str(tmp_path / "out"),
                   "--workers", "2", "--retries", "1", "--no-progress", timeout=600)
    assert proc.returncode == 1, proc.stderr + proc.stdout
    assert "Traceback" not in proc.stderr
    assert [line for line in proc.stderr.splitlines() if line.startswith("mirrorlab: error:")] == [
        f"mirrorlab: error: 1 of 3 files failed (broken.h5); their errors are in the table and in "
        f"{tmp_path / 'out' / 'batch-summary.csv'}"]
    assert [_digest(p) for p in sessions] == before, "an input was modified"
    table = " ".join(proc.stdout.split())
    assert "2 ok, 1 failed, on 2 worker(s)" in table and all(n in table for n in ("trial1.h5", "trial2.h5", "broken.h5"))
    with (tmp_path / "out" / "batch-summary.csv").open() as f:
        rows = {Path(r["file"]).name: r for r in csv.DictReader(f)}
    assert {n: r["status"] for n, r in rows.items()} == {"trial1.h5": "ok", "trial2.h5": "ok", "broken.h5": "failed"}
    assert rows["broken.h5"]["error"].startswith(f"{garbage}: not an HDF5 file")
    assert float(rows["trial1.h5"]["results_ok"]) == 15 and float(rows["trial1.h5"]["results_failed"]) == 0
    assert float(rows["trial1.h5"]["calibration_rms_mm"]) > 0
    for source in sessions:
        copy = tmp_path / "out" / source.name
        serial = _serial(source, tmp_path / f"serial-{source.name}")
        assert _datasets(copy).keys() == _datasets(serial).keys()
        assert _datasets(copy) == _datasets(serial), source.name
        with Session.open(copy) as s:
            provenance = [s.result(r).attrs["executor"] for r in s.results()]
        assert len(provenance) == 15
        assert all('"workers": 2' in p and '"scheduler": "tcp://' in p and '"mode": "batch"' in p
                   for p in provenance)
        assert "3-D RMS error per marker" in copy.with_suffix(".txt").read_text()  # the report's printout


def test_chunked_frames_equal_serial(sessions: list[Path], tmp_path: Path) -> None:
    """Detection and pairing (without continuity) in chunks of 5 frames on 2 workers, merged in order."""
    source = sessions[0]
    serial = _serial(source, tmp_path / "serial.h5", [NO_CONTINUITY])
    chunked = tmp_path / "chunked.h5"
    shutil.copyfile(source, chunked)
    recipe = load_recipe(ANALYSIS, [NO_CONTINUITY], analysis=True)
    with dask_client(workers=2) as client:
        executor = ChunkedExecutor(client, {"scheduler": client.scheduler.address, "workers": 2}, chunk_frames=5)
        run_analysis(recipe, chunked, executor=executor)
        # each worker: OpenCV on one thread, glibc's own malloc trimming, Dask's stack sampling off
        assert set(client.run(_worker_setup).values()) == {(1, None, False)}
    # the grid's one calibration frame fits a chunk; the 12 experiment frames make 3
    assert executor.chunked == [("detect_markers", 3), ("pair_mirror", 3)]
    assert _datasets(chunked) == _datasets(serial)
    # the input digests too: the workers hashed the frames they read (image rows are blocks of their
    # own), this process the pairing's points (blocks of many rows, not cut at 5-frame chunks)
    assert _input_digests(chunked) == _input_digests(serial)
    with Session.open(chunked) as s:
        assert s.status == "closed" and all(r.status == "ok" for r in s.results())
        assert '"chunk_frames": 5' in s.result("/results/detect_markers/run-0002").attrs["executor"]
