"""Batch re-processing on Dask distributed: speed-up over files, chunked detection per worker, memory.

Run: ``python benchmarks/bench_batch.py [--files 8] [--frames 20000] [--chunk-frames 1000] [--only a|b]``

(a) **Many sessions.** One short RSSR demo recording (``sessions/rssr_acquire.toml``, 24 frames at
12 frames/s) is copied to ``--files`` inputs; ``mirrorlab.core.batch.runner.run_batch`` runs
``sessions/rssr_analysis.toml`` on all of them, on a ``LocalCluster`` of 1 worker (the baseline)
and of 2 workers (processes, one thread each). Each cluster is started and warmed up (every worker
imports the plugins) before the clock starts; start-up times are printed apart. Printed: seconds,
files/s and the speed-up of 2 workers over 1 (goal ≥ 1.6×).

(b) **One long recording in chunks.** A session with a ``--frames`` 512 × 344 uint8 image stream
(the scanner's format; 100 distinct binary frames of 20 discs each, cycled) is analysed with
``detect_markers``: by ``Session.run`` in one process without Dask (reads the frames, detects them
all), once with OpenCV's default thread pool (which puts more than one core to work at times) and
once with OpenCV on one thread (the baseline: one core, as each worker runs), and by
``Session.run`` with a ``ChunkedExecutor`` on 2 workers (``--chunk-frames`` per task, read by each
worker from the file in SWMR mode, merged in frame order). Printed: frames/s of each, frames/s per
worker and its ratio to the one-thread baseline (goal ≥ 0.85), the speed-up over the default process,
whether the outputs are equal bit for bit, and the peak resident memory of each worker (bounded by
about one chunk of frames plus its detections, whatever the recording's length). The recording is
flushed to disk before the runs, and each worker detects one blank frame before the clock starts
(OpenCV initialises on its first call), as the baseline process has by then.

Both parts print the machine's load average: these are 2-core machines shared with other work, and a
busy core lowers every ratio here. All files live in a temporary directory removed at the end.
"""

from __future__ import annotations

import argparse
import os
import shutil
import tempfile
import time
from pathlib import Path

import h5py
import numpy as np
from mirrorlab.core import Session
from mirrorlab.core.batch.cluster import dask_client, describe
from mirrorlab.core.batch.executors import ChunkedExecutor
from mirrorlab.core.batch.runner import run_batch
from mirrorlab.core.recipes import load_recipe, run_recipe
from mirrorlab.core.store import schema
from mirrorlab.core.streams import StreamSpec

REPO = Path(__file__).resolve().parents[1]
ACQUIRE = REPO / "sessions" / "rssr_acquire.toml"
ANALYSIS = REPO / "sessions" / "rssr_analysis.toml"
SHAPE = (344, 512)


def _warm_up() -> int:
    """Run on every worker: import what the analysis imports and detect markers in one blank frame
    (OpenCV's first call initialises it), as the baseline process has, so that the timing is the work itself."""
    from mirrorlab.core.algorithms import execute
    from mirrorlab.core.registry import get_registry

    registry = get_registry()
    execute(registry.algorithm("detect_markers"), {"frames": np.zeros((1, *SHAPE), np.uint8)}, {})
    return len(registry.names("algorithm"))


def _peak_rss_mib() -> float:
    """Peak resident memory of this process, MiB: ``VmHWM`` of /proc/self/status (Linux).

    Not ``getrusage``'s ``ru_maxrss``: a process started by fork + exec (Dask's spawned workers)
    keeps its parent's high-water mark there, e.g. the 3.4 GB of frames the baseline read.
    """
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmHWM:"):
            return int(line.split()[1]) / 1024
    raise RuntimeError("no VmHWM in /proc/self/status (not Linux?)")


def _cpu_seconds() -> float:
    """User + system CPU time of this process so far, s (run on each worker, too)."""
    import resource

    usage = resource.getrusage(resource.RUSAGE_SELF)
    return usage.ru_utime + usage.ru_stime


def _load() -> str:
    return "load average " + ", ".join(f"{x:.2f}" for x in os.getloadavg())


def many_sessions(tmp: Path, files: int) -> None:
    recipe = load_recipe(ACQUIRE, ["instruments.rssr.settings.frame_rate=12", "instruments.rssr.settings.scene_frames=24"])
    source = run_recipe(recipe, tmp / "recorded.h5")
    inputs = []
    for i in range(files):
        inputs.append(tmp / "inputs" / f"trial{i:02d}.h5")
        inputs[-1].parent.mkdir(exist_ok=True)
        shutil.copyfile(source, inputs[-1])
    seconds = {}
    for workers in (1, 2):
        start = time.perf_counter()
        with dask_client(workers=workers) as client:
            client.run(_warm_up)
            up = time.perf_counter() - start
            start = time.perf_counter()
            results = run_batch(client, ANALYSIS, inputs, tmp / f"out{workers}", describe(client))
            seconds[workers] = time.perf_counter() - start
            peak = client.run(_peak_rss_mib)
        failed = [r for r in results if r.status != "ok"]
        assert not failed, failed[0].error
        print(f"  {workers} worker(s): {seconds[workers]:6.1f} s for {files} files ({files / seconds[workers]:.2f} files/s; "
              f"cluster start {up:.1f} s; peak worker memory {', '.join(f'{m:.0f}' for m in peak.values())} MiB)")
    ratio = seconds[1] / seconds[2]
    print(f"  speed-up 2 workers / 1 worker: {ratio:.2f}x (goal >= 1.6x) {'ok' if ratio >= 1.6 else 'MISSED'}")


def _long_session(path: Path, frames: int) -> None:
    """A session whose camera stream holds ``frames`` frames, written as the recorder writes (chunked, resizable)."""
    from bench_detection import scanner_frame  # same folder: the scanner scene of the detection benchmark

    rng = np.random.default_rng(7)
    distinct = np.stack([scanner_frame(rng, SHAPE)[0] for _ in range(100)])
    with Session.create(path, description="bench_batch: long recording"):
        pass
    with h5py.File(path, "a", libver=schema.LIBVER) as f:  # the store's layout, written here without a device
        group = f["instruments"].create_group("cam")
        stream = schema.create_stream(group, StreamSpec("frames", "u1", SHAPE, "grey level", 100.0))
        for start in range(0, frames, len(distinct)):
            block = distinct[:min(len(distinct), frames - start)]
            schema.append(stream["data"], block)
            schema.append(stream["time"], (start + np.arange(len(block))) / 100.0)


def long_recording(tmp: Path, frames: int, chunk_frames: int) -> None:
    path = tmp / "long.h5"
    _long_session(path, frames)
    os.sync()  # the recording is on disk before the clock starts: no writeback competes with the runs
    import cv2

    inputs = {"frames": "/instruments/cam/frames/data"}
    with Session.open(path, writable=True) as s:
        start, cpu = time.perf_counter(), _cpu_seconds()
        s.run("detect_markers", inputs)  # OpenCV's default thread pool: more than one core at times
        pooled_s, pooled_cpu = time.perf_counter() - start, _cpu_seconds() - cpu
        threads = cv2.getNumThreads()
        cv2.setNumThreads(1)  # one core, as each worker runs (core/batch/worker_setup.py)
        start, cpu = time.perf_counter(), _cpu_seconds()
        serial = s.run("detect_markers", inputs)
        serial_s, serial_cpu = time.perf_counter() - start, _cpu_seconds() - cpu
        cv2.setNumThreads(threads)
        with dask_client(workers=2) as client:
            client.run(_warm_up)
            s.executor = ChunkedExecutor(client, describe(client), chunk_frames)
            before = client.run(_cpu_seconds)
            start = time.perf_counter()
            chunked = s.run("detect_markers", inputs)
            chunked_s = time.perf_counter() - start
            workers_cpu = sum(client.run(_cpu_seconds).values()) - sum(before.values())
            peak = client.run(_peak_rss_mib)
        s.executor = None
        a, b = s.result(serial).outputs, s.result(chunked).outputs
        equal = a.keys() == b.keys() and all(a[k].dtype == b[k].dtype and a[k].tobytes() == b[k].tobytes() for k in a)
    base, fast = frames / serial_s, frames / chunked_s
    per_worker = fast / 2
    print(f"  one process, no Dask, OpenCV's {threads} threads: {pooled_s:6.1f} s, {frames / pooled_s:7.0f} frames/s "
          f"(CPU {pooled_cpu:.1f} s: {pooled_cpu / pooled_s:.2f} cores)")
    print(f"  one process, no Dask, one thread (baseline): {serial_s:6.1f} s, {base:7.0f} frames/s "
          f"(CPU {serial_cpu:.1f} s)")
    print(f"  2 workers, chunks of {chunk_frames}: {chunked_s:6.1f} s, {fast:7.0f} frames/s, "
          f"{per_worker:.0f} frames/s per worker; {pooled_s / chunked_s:.2f}x the default process")
    print(f"  per worker / one single-threaded process: {per_worker / base:.2f} (goal >= 0.85) "
          f"{'ok' if per_worker / base >= 0.85 else 'MISSED'}")
    # More CPU in the workers than in one process is work added by the chunking (reads, transfers);
    # the same CPU over a longer time is two processes slowing each other (memory bandwidth, load).
    print(f"  CPU time: one process {serial_cpu:.1f} s, workers {workers_cpu:.1f} s in all "
          f"({workers_cpu / serial_cpu:.2f}x)")
    print(f"  outputs equal bit for bit: {equal}")
    print(f"  peak worker memory: {', '.join(f'{m:.0f}' for m in peak.values())} MiB "
          f"(one chunk of frames: {chunk_frames * SHAPE[0] * SHAPE[1] / 2**20:.0f} MiB)")
    assert equal, "chunked detection differs from the serial one"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--files", type=int, default=8)
    parser.add_argument("--frames", type=int, default=20000)
    parser.add_argument("--chunk-frames", type=int, default=1000)
    parser.add_argument("--only", choices=("a", "b"), help="run one of the two parts")
    args = parser.parse_args()
    print(f"bench_batch: {os.cpu_count()} cores, {_load()}")
    with tempfile.TemporaryDirectory() as folder:
        if args.only != "b":
            print(f"(a) {args.files} sessions, rssr_analysis.toml, 1 vs 2 workers")
            many_sessions(Path(folder), args.files)
        if args.only != "a":
            print(f"(b) detect_markers on a {args.frames}-frame recording ({SHAPE[1]} x {SHAPE[0]} px)")
            long_recording(Path(folder), args.frames, args.chunk_frames)
    print(f"done, {_load()}")


if __name__ == "__main__":  # Dask's worker processes import this script again
    main()
