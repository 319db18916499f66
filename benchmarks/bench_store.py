"""Throughput and overhead of the HDF5 session store.

Run: ``python benchmarks/bench_store.py [--seconds 30] [--repeats 3]``

(a) **Append overhead.** The same blocks are written twice, interleaved, ``--repeats`` times:

* mirrorlab: ``schema.create_stream`` → file in SWMR mode → every block goes through
  ``StreamRouter.publish`` into the bounded recorder queue (timed: the device thread's cost) → the
  real :class:`~mirrorlab.core.store.recorder.Recorder` thread drains it (timed). Its batch cap is
  set to 1, 64 and 4096 blocks (live trickle, a backlog, its own cap) to cover the batch sizes
  it meets; grouping, concatenation, ``schema.append``, flushing and ``/log`` are its own code;
* raw h5py: the same datasets (same chunks and Fletcher-32 checksums, the session's ``libver``
  bounds, SWMR on), the same data from contiguous arrays, resized and written in exactly the
  recorder's batches, flushed every 0.5 s.

  Printed: median wall time of each and their ratio (goal ≤ 1.25×), for a scalar 1 kHz stream
  (10-sample blocks) and a 512×344 uint8 image stream (one frame per block).

(b) **Sustained recording through a real Session.** A benchmark-local, non-serial
:class:`~mirrorlab.core.devices.Instrument` (``BenchSource``, registered with
:meth:`~mirrorlab.core.registry.Registry.add_plugin`) emits 4 scalar streams at 1 kHz (10-sample
blocks every 10 ms) and one 512×344 uint8 image stream at 100 frames/s for ``--seconds``.
Printed: samples written per stream, drops (must be 0), achieved rates, recorder-queue depth and
CPU used (whole process, and the recorder and acquisition threads on Linux).

All files live in a temporary directory that is removed at the end. Exit code 0.
"""

from __future__ import annotations

import argparse
import os
import resource
import statistics
import tempfile
import threading
import time
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import h5py
import numpy as np
from mirrorlab.core import Parameter, ParameterSet, Session, StreamSpec, hookimpl
from mirrorlab.core.clock import SessionClock
from mirrorlab.core.devices import Identity, Instrument, Status
from mirrorlab.core.events import EventBus
from mirrorlab.core.registry import Registry
from mirrorlab.core.store import schema
from mirrorlab.core.store.recorder import Recorder
from mirrorlab.core.streams import StreamRouter

IMAGE_SHAPE = (344, 512)  # rows × columns: a 512×344 px frame
FLUSH_INTERVAL = 0.5  # the Recorder's default
LIBVER = getattr(schema, "LIBVER", "latest")  # the format bounds sessions are written with
CAPS = (1, 64, 4096)  # (a): blocks per recorder batch: live trickle, a backlog, the recorder's cap


# ---------------------------------------------------------------------------------------------
# (a) append overhead: mirrorlab's recorder path vs raw h5py
# ---------------------------------------------------------------------------------------------
class _BatchLog(Recorder):
    """The real Recorder, noting each batch's size (its ``batch_blocks`` cap is set per case)."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.batches: list[int] = []

    def _write(self, batch: list) -> None:
        self.batches.append(sum(len(b.times) for b in batch))
        super()._write(batch)


def _mirrorlab_append(path: Path, spec: StreamSpec, blocks: list[tuple[np.ndarray, np.ndarray]],
                      cap: int) -> tuple[float, float, float, list[int]]:
    """Publish every block (timed per block), then time the Recorder thread draining them."""
    f = h5py.File(path, "w", libver=LIBVER)
    schema.create_stream(f.require_group("instruments/bench"), spec)
    schema.create_log(f)
    f.flush()
    f.swmr_mode = True
    router = StreamRouter(queue_blocks=len(blocks))
    router.start_recording(["bench"])
    t = time.perf_counter()
    for times, values in blocks:
        router.publish("bench", spec.name, times, values)
    publish_us = 1e6 * (time.perf_counter() - t) / len(blocks)
    recorder = _BatchLog(f, router, EventBus(SessionClock()), {("bench", spec.name): f"instruments/bench/{spec.name}"},
                         path=path, flush_interval=FLUSH_INTERVAL, batch_blocks=cap)
    wall, cpu = time.perf_counter(), time.process_time()
    recorder.start()
    recorder.stop()  # writes everything queued, flushes, joins
    wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
    f.close()
    assert router.stats[("bench", spec.name)].dropped_samples == 0
    return wall, cpu, publish_us, recorder.batches


def _raw_append(path: Path, spec: StreamSpec, times: np.ndarray, values: np.ndarray,
                batches: list[int]) -> tuple[float, float]:
    """Raw h5py: same layout and data, written in the recorder's batches from contiguous arrays."""
    chunk = spec.chunk_samples()  # the same layout schema.create_stream makes
    with h5py.File(path, "w", libver=LIBVER) as f:
        g = f.create_group(f"instruments/bench/{spec.name}")
        data = g.create_dataset("data", shape=(0, *spec.shape), maxshape=(None, *spec.shape),
                                dtype=spec.dtype, chunks=(chunk, *spec.shape), fletcher32=True)
        tds = g.create_dataset("time", shape=(0,), maxshape=(None,), dtype="f8", chunks=(max(chunk, 1024),),
                               fletcher32=True)
        f.flush()
        f.swmr_mode = True
        wall, cpu = time.perf_counter(), time.process_time()
        pos, last_flush = 0, time.monotonic()
        for n in batches:
            data.resize(pos + n, axis=0)
            data[pos:pos + n] = values[pos:pos + n]
            tds.resize(pos + n, axis=0)
            tds[pos:pos + n] = times[pos:pos + n]
            pos += n
            if time.monotonic() - last_flush >= FLUSH_INTERVAL:
                f.flush()
                last_flush = time.monotonic()
        f.flush()
        wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
    return wall, cpu


def _blocks(spec: StreamSpec, n_blocks: int, per_block: int) -> list[tuple[np.ndarray, np.ndarray]]:
    rng = np.random.default_rng(0)
    out = []
    frames = rng.integers(0, 256, size=(8, per_block, *spec.shape), dtype=np.uint8) if spec.shape else None
    for k in range(n_blocks):
        t = (k * per_block + np.arange(per_block)) / spec.rate
        out.append((t, frames[k % 8] if spec.shape else np.sin(t) + rng.normal(0, 0.01, per_block)))
    return out


def bench_append(workdir: Path, repeats: int) -> list[dict[str, Any]]:
    cases = [
        ("scalar f8 1 kHz", StreamSpec("ch0", "f8", (), "V", 1000.0), 20_000, 10),  # 200 s of data
        ("image 512x344 u1", StreamSpec("frames", "u1", IMAGE_SHAPE, "grey", 100.0), 1_000, 1),  # 10 s
    ]
    rows = []
    for label, spec, n_blocks, per_block in cases:
        blocks = _blocks(spec, n_blocks, per_block)
        all_t = np.concatenate([t for t, _ in blocks])
        all_v = np.concatenate([np.asarray(v).reshape(-1, *spec.shape) for _, v in blocks])
        for cap in CAPS:
            ml_wall, ml_cpu, raw_wall, raw_cpu, pub = [], [], [], [], []
            for _ in range(repeats):  # interleaved, so drift of the machine hits both alike
                p = workdir / f"ml-{spec.name}.h5"
                w, c, us, batches = _mirrorlab_append(p, spec, blocks, cap)
                with h5py.File(p, "r") as f:
                    assert f[f"instruments/bench/{spec.name}/data"].shape[0] == len(all_t)
                p.unlink()
                ml_wall.append(w)
                ml_cpu.append(c)
                pub.append(us)
                p = workdir / f"raw-{spec.name}.h5"
                w, c = _raw_append(p, spec, all_t, all_v, batches)
                p.unlink()
                raw_wall.append(w)
                raw_cpu.append(c)
            rows.append({"case": label, "blocks": min(cap, n_blocks), "samples": len(all_t),
                         "MB": (all_v.nbytes + all_t.nbytes) / 1e6, "publish_us": statistics.median(pub),
                         "ml_wall": statistics.median(ml_wall), "raw_wall": statistics.median(raw_wall),
                         "ml_cpu": statistics.median(ml_cpu), "raw_cpu": statistics.median(raw_cpu)})
    return rows


# ---------------------------------------------------------------------------------------------
# (b) sustained recording through a Session
# ---------------------------------------------------------------------------------------------
class BenchSource(Instrument):
    """A synthetic, non-serial source: N scalar channels plus one image stream, clocked in software.

    Timestamps come from a sample counter (``t0 + i / rate``), as from a hardware sample clock;
    if the thread runs late it catches up by emitting the overdue blocks, so late ≠ lost.
    """

    name = "bench_source"
    version = "1.0.0"
    description = "benchmark source: scalar channels and an image stream"
    parameters = ParameterSet(
        Parameter("channels", int, 4, bounds=(1, 64), help="number of scalar streams"),
        Parameter("scalar_rate", float, 1000.0, unit="Hz", bounds=(1.0, 1e6), help="scalar sample rate"),
        Parameter("frame_rate", float, 100.0, unit="Hz", bounds=(0.0, 1e4), help="image frames per second"),
        Parameter("block", float, 0.01, unit="s", bounds=(0.001, 1.0), help="seconds of data per block"),
    )

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.max_lateness = 0.0
        rng = np.random.default_rng(1)
        self._frames = rng.integers(0, 256, size=(8, 1, *IMAGE_SHAPE), dtype=np.uint8)

    def connect(self) -> None:
        pass

    def identify(self) -> Identity:
        self.identity = Identity("BENCH", "mirrorlab", "bench_store", self.version, "0")
        return self.identity

    def apply_settings(self, settings: dict[str, Any]) -> None:
        pass

    def streams(self) -> list[StreamSpec]:
        s = self.settings
        specs = [StreamSpec(f"ch{i}", "f8", (), "V", s["scalar_rate"], f"synthetic channel {i}")
                 for i in range(s["channels"])]
        if s["frame_rate"] > 0:
            specs.append(StreamSpec("frames", "u1", IMAGE_SHAPE, "grey", s["frame_rate"], "synthetic frames"))
        return specs

    def acquire(self, emit: Any, stop: threading.Event) -> None:
        s = self.settings
        rate, fps, period = s["scalar_rate"], s["frame_rate"], s["block"]
        n = max(1, round(rate * period))
        t0, start = emit.now(), time.monotonic()
        sample = frame = tick = 0
        while not stop.is_set():
            tick += 1
            lateness = time.monotonic() - (start + tick * period)
            if lateness < 0:
                if stop.wait(-lateness):
                    return
            else:
                self.max_lateness = max(self.max_lateness, lateness)
            times = t0 + (sample + np.arange(n)) / rate
            for c in range(s["channels"]):
                emit(f"ch{c}", times, np.sin(2 * np.pi * (c + 1) * times))
            sample += n
            while fps > 0 and frame < tick * period * fps:  # frames due by the end of this tick
                emit("frames", [t0 + frame / fps], self._frames[frame % 8])
                frame += 1

    def read(self) -> dict[str, np.ndarray]:
        return {f"ch{c}": np.zeros(1) for c in range(self.settings["channels"])}

    def status(self) -> Status:
        return Status("RUNNING" if self.running else "IDLE", detail={"max_lateness_s": self.max_lateness})

    def close(self) -> None:
        pass


class _BenchPlugin:
    @hookimpl
    def mirrorlab_register_instruments(self) -> list[type[Instrument]]:
        return [BenchSource]


def bench_registry() -> Registry:
    """The built-ins plus this file's instrument (no entry points: only what is benchmarked)."""
    registry = Registry(entry_points=False)
    registry.add_plugin(_BenchPlugin(), "bench_store", "benchmarks/bench_store.py")
    return registry


def _thread_cpu() -> dict[str, float]:
    """CPU seconds of each live thread, by name (Linux /proc; empty elsewhere)."""
    tick = os.sysconf("SC_CLK_TCK") if hasattr(os, "sysconf") else 100
    out = {}
    for t in threading.enumerate():
        try:
            fields = Path(f"/proc/self/task/{t.native_id}/stat").read_text().rsplit(")", 1)[1].split()
        except (OSError, IndexError, TypeError):
            continue
        out[t.name] = (int(fields[11]) + int(fields[12])) / tick  # utime + stime
    return out


def bench_session(workdir: Path, seconds: float, settings: Mapping[str, Any]) -> dict[str, Any]:
    path = workdir / "session.h5"
    with Session.create(path, operator="bench", description="bench_store sustained recording",
                        registry=bench_registry()) as s:
        inst = s.add_instrument("src", "bench_source", settings=dict(settings))
        ru0, cpu0 = resource.getrusage(resource.RUSAGE_SELF), time.process_time()
        s.start_recording()
        wall0 = time.monotonic()
        max_queue, threads = 0, {}
        while (left := seconds - (time.monotonic() - wall0)) > 0:
            time.sleep(min(0.05, left))
            max_queue = max(max_queue, s.router.recorder_queue.qsize())
            threads = _thread_cpu()  # the last sample before stopping
        wall = time.monotonic() - wall0
        stats = s.stop_recording()
        cpu = time.process_time() - cpu0
        ru1 = resource.getrusage(resource.RUSAGE_SELF)
        lateness = inst.max_lateness
    with Session.open(path) as s:
        streams = {}
        for name in s.describe()["instruments"]["src"]["streams"]:
            d = s.stream("src", name)
            streams[name] = {"samples": len(d.times), "dropped": int(d.attrs["dropped"]),
                             "nominal": float(d.attrs["rate"]), "shape": d.data.shape[1:]}
        status = s.status
    return {"wall": wall, "cpu": cpu, "user": ru1.ru_utime - ru0.ru_utime, "sys": ru1.ru_stime - ru0.ru_stime,
            "maxrss_mb": ru1.ru_maxrss / 1024, "max_queue": max_queue, "queue_cap": 4096,
            "threads": {k: v for k, v in threads.items() if k == "recorder" or k.startswith("acquire")},
            "streams": streams, "stats": stats, "lateness": lateness, "status": status,
            "file_mb": path.stat().st_size / 1e6}


# ---------------------------------------------------------------------------------------------
def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seconds", type=float, default=30.0, help="duration of the sustained recording (b)")
    ap.add_argument("--repeats", type=int, default=3, help="interleaved repeats of each append case (a)")
    args = ap.parse_args()
    print(f"h5py {h5py.version.version}, HDF5 {h5py.version.hdf5_version}, numpy {np.__version__}, "
          f"{os.cpu_count()} CPUs")
    with tempfile.TemporaryDirectory(prefix="mirrorlab-bench-store-") as tmp:
        workdir = Path(tmp)

        print(f"\n(a) stream-append overhead: mirrorlab Recorder thread draining a StreamRouter queue vs raw "
              f"h5py\n    (same chunks, SWMR on, same batches, flush every {FLUSH_INTERVAL} s; median of "
              f"{args.repeats}; 'publish' is the device-thread cost per block)")
        print(f"{'case':<18}{'blocks/batch':>13}{'samples':>9}{'MB':>7}{'mirrorlab s':>12}{'raw s':>8}"
              f"{'ratio':>7}{'cpu ratio':>10}{'publish':>10}")
        for r in bench_append(workdir, args.repeats):
            ratio = r["ml_wall"] / r["raw_wall"]
            print(f"{r['case']:<18}{r['blocks']:>13}{r['samples']:>9}{r['MB']:>7.1f}{r['ml_wall']:>12.3f}"
                  f"{r['raw_wall']:>8.3f}{ratio:>6.2f}x{r['ml_cpu'] / max(r['raw_cpu'], 1e-9):>9.2f}x"
                  f"{r['publish_us']:>7.1f} us  {'ok' if ratio <= 1.25 else 'above goal'} (goal <= 1.25x)")

        settings = {"channels": 4, "scalar_rate": 1000.0, "frame_rate": 100.0, "block": 0.01}
        print(f"\n(b) sustained Session recording for {args.seconds:g} s: 4 x f8 @ 1 kHz (10 samples / 10 ms) "
              f"+ 512x344 u1 @ 100 fps")
        b = bench_session(workdir, args.seconds, settings)
        print(f"{'stream':<12}{'shape':>11}{'samples':>10}{'expected':>10}{'dropped':>9}{'rate Hz':>10}"
              f"{'nominal':>9}")
        for name, st in b["streams"].items():
            expected = st["nominal"] * b["wall"]
            shape = "x".join(map(str, st["shape"])) or "scalar"
            print(f"{name:<12}{shape:>11}{st['samples']:>10}{expected:>10.0f}{st['dropped']:>9}"
                  f"{st['samples'] / b['wall']:>10.1f}{st['nominal']:>9.0f}")
        drops = sum(st["dropped"] for st in b["streams"].values())
        written = sum(v["samples"] for v in b["stats"].values())
        print(f"drops: {drops} ({'ok' if drops == 0 else 'FAIL: must be 0'}); samples written {written}; "
              f"session status {b['status']!r}; file {b['file_mb']:.0f} MB "
              f"({b['file_mb'] / b['wall']:.1f} MB/s)")
        print(f"CPU: {100 * b['cpu'] / b['wall']:.1f} % of one core for the whole process "
              f"(user {b['user']:.2f} s, sys {b['sys']:.2f} s over {b['wall']:.2f} s)")
        for name, sec in sorted(b["threads"].items()):
            print(f"     thread {name!r}: {100 * sec / b['wall']:.1f} % of one core")
        print(f"recorder queue: max {b['max_queue']} of {b['queue_cap']} blocks; acquisition max lateness "
              f"{1000 * b['lateness']:.1f} ms; peak RSS {b['maxrss_mb']:.0f} MB")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
