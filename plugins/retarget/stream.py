"""The paper's filter (spec §7): input module → compute module → output module, at a fixed rate.

* :class:`Compute` is the compute module: one call per input pose (``lm``: one warm-started
  solve; ``paper``: K per-joint Newton sweeps), keeping the previous frame's angles as state. It
  has no threads and no clock, so it can also run inside a controller loop. Its multistart
  fallback (spec §6) runs on the frame that needs it (``fallback_delay=0``, the batch result) or
  in a worker process (:mod:`.fallback`) whose result is adopted on a later frame: a fixed number
  of frames later (deterministic) or as soon as it is ready (``fallback_delay=None``, real time).
* :class:`RetargetFilter` wires the three modules. :meth:`~RetargetFilter.run` in deterministic
  mode processes every input frame exactly once, in order (tests, batch); in real-time mode
  (``realtime=True``) an input thread overwrites a single-slot input buffer every period (latest
  value wins), a compute thread solves the newest input, and an output thread publishes the
  output buffer every period to the sinks.
* Sinks: :class:`MemorySink`, :class:`CSVSink`, :class:`SessionSink` (written when the run ends).

Units: mm, rad, s; ``f`` mm². Latencies are wall-clock seconds from an input's arrival in the
input buffer to its publication (deterministic mode: the compute time).
"""

from __future__ import annotations

import csv
import os
import threading
import time
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .approximate import Tracker, input_chain, unwrap_to
from .chain import Tree, as_base
from .correspondence import correspondence_pairs
from .errors import InputChainError, RetargetError
from .fallback import FallbackWorker
from .objective import Arms, Objective

__all__ = ["Compute", "FrameResult", "RetargetFilter", "FilterStats", "Sink", "MemorySink", "CSVSink", "SessionSink",
           "poses", "compute_for"]

FloatArray = NDArray[np.float64]

#: A background multistart is adopted only when it lowers f by more than this fraction: the same
#: minimum reached from another start differs by round-off, not a different basin.
ADOPT_GAIN = 1e-9


@dataclass(frozen=True)
class FrameResult:
    """One output of the filter: source frame index and time (s), angles (rad), f (mm²), per-pair
    residuals (mm), iterations, whether the multistart ran (or, in the background, started) on this
    frame, whether a background multistart's result was adopted on this frame, the flag and the
    latency (s)."""

    index: int
    time: float
    q: FloatArray
    f: float
    residuals: FloatArray
    iterations: int
    restarted: bool
    adopted: bool
    flagged: bool
    latency: float


class Compute:
    """The compute module: per-frame retargeting with state (previous angles).

    Parameters
    ----------
    chain : Tree
        Output chain (base ``None``: on the input's root joint, identity rotation).
    input_lengths : array_like
        Input arm lengths (mm) for the static correspondence, e.g. medians of a calibration
        window or :func:`~.approximate.input_chain` ``.lengths``.
    method : {"lm", "paper"}
    sweeps : int
        ``paper``: per-joint Newton sweeps per input update (spec §7 default K = 3).
    input_parents, leaf_map, distance, base, q0, max_iter, multistart, n_starts, jump_factor, seed
        As in :func:`~.approximate.approximate`.
    flag_above : float
        Flag outputs with f above this (mm²).
    fallback_delay : int or None
        Where the multistart runs. 0: on the frame that needs it, before that frame is returned
        (the batch result, but a multistart frame takes 20–40 ms). Otherwise in a worker process
        (:class:`~.fallback.FallbackWorker`): the frame returns its warm-started solution and
        the multistart (of that frame's input, from the fixed starts and that solution) runs in
        the background; ``d > 0``: its result is taken exactly ``d`` frames later (waiting for it
        if needed: deterministic, for tests); ``None``: on the first frame after it finished
        (real time). A result that is better than the warm solution of its frame seeds one more
        solve of the current frame, which replaces the warm solution if f drops (``adopted``),
        unwrapped to the previous angles so that no angle jumps by 2π. One multistart runs at a
        time; a frame that needs one meanwhile defers it to the frame that takes the result.
    worker : callable
        ``worker(tracker)`` starts the background worker (default :class:`~.fallback.FallbackWorker`).
    """

    def __init__(self, chain: Tree, input_lengths: ArrayLike, method: str = "lm", *, sweeps: int = 3,
                 input_parents: ArrayLike | None = None, leaf_map: Sequence[int] | None = None,
                 distance: str = "segment", base: Any = None, q0: ArrayLike | None = None, max_iter: int = 20,
                 multistart: bool | None = None, n_starts: int = 8, jump_factor: float = 2.0, seed: int = 0,
                 flag_above: float = np.inf, fallback_delay: int | None = 0,
                 worker: Callable[[Tracker], FallbackWorker] = FallbackWorker) -> None:
        if fallback_delay is not None and not (isinstance(fallback_delay, int) and fallback_delay >= 0):
            raise RetargetError(f"fallback_delay must be a whole number of frames >= 0 or None, got {fallback_delay!r}")
        lengths = np.asarray(input_lengths, float).reshape(-1)
        parents = np.arange(lengths.size + 1) - 1 if input_parents is None else np.asarray(input_parents, int)
        self.chain = chain
        self.n_nodes = lengths.size + 1
        pairs = correspondence_pairs(parents, lengths, chain, leaf_map)
        self.objective = Objective(chain, pairs, parents, distance)
        use_ms = (method == "lm") if multistart is None else bool(multistart)
        self.tracker = Tracker(self.objective, method, sweeps if method == "paper" else None, max_iter, use_ms,
                               n_starts, jump_factor, None, seed)
        self.base = None if base is None else as_base(base)
        # validated once: a fixed base (given or the chain's), else identity on the input's root joint
        self._fixed_base = self.base if self.base is not None else chain.base
        self._identity = np.eye(3)
        self.q0 = np.zeros(chain.dof) if q0 is None else np.asarray(q0, float).reshape(chain.dof)
        self.flag_above = flag_above
        self.fallback_delay = fallback_delay
        #: The multistart runs in a worker process.
        self.background = fallback_delay != 0 and use_ms
        self._start_worker = worker
        self._worker: FallbackWorker | None = None
        self.reset()

    def reset(self) -> None:
        """Forget the previous frame (the next input starts from ``q0`` with a multistart)."""
        self.q = self.q0[None].copy()
        self.f = np.zeros(1)
        self.has = np.zeros(1, bool)
        self.frame = 0                                # frames since the reset
        if self._worker is not None and self._worker.busy:
            self._worker.result()                     # a stale multistart: discarded
        self._pending: tuple[int, float] | None = None   # frame and warm f of the running multistart
        self._deferred = False

    def open(self) -> None:
        """Start the background worker if ``fallback_delay`` asks for one (call it before a clock starts)."""
        if self.background and self._worker is None:
            self._worker = self._start_worker(self.tracker)

    def close(self) -> None:
        """Stop the background worker; a multistart still running is discarded."""
        if self._worker is not None:
            self._worker.close()
            self._worker = None
        self._pending, self._deferred = None, False

    def __enter__(self) -> Compute:
        self.open()
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __call__(self, joints: ArrayLike) -> tuple[FloatArray, float, FloatArray, int, bool, bool]:
        """Angles (dof,) rad, f mm², residuals (P,) mm, iterations, restart and adoption flags for one
        input pose (n+1, 3) mm.

        A pose with a missing joint gives NaN and makes the next valid pose restart.
        """
        X = np.asarray(joints, float)
        if X.shape != (self.n_nodes, 3):
            raise InputChainError(f"an input pose must have shape ({self.n_nodes}, 3) mm, got {X.shape}")
        self.frame += 1
        if not np.isfinite(X).all():
            self.has[:] = False
            return (np.full(self.chain.dof, np.nan), float("nan"), np.full(len(self.objective.pairs), np.nan), 0,
                    False, False)
        R, p = self._fixed_base if self._fixed_base is not None else (self._identity, X[0])
        arms = self.objective.arms(X[None])
        if self.background:
            q, f, iters, restarted, r, adopted = self._step_background(arms, R, p[None])
        else:
            q, f, iters, rs, r = self.tracker.step(self.q, self.f, self.has, arms, R, p[None])
            restarted, adopted = bool(rs[0]), False
        self.q, self.f, self.has = q, f, np.ones(1, bool)
        return q[0].copy(), float(f[0]), np.sqrt((r[0] * r[0]).sum(-1)), int(iters[0]), restarted, adopted

    def _step_background(self, arms: Arms, R: FloatArray, p: FloatArray) -> tuple[FloatArray, FloatArray,
                                                                                  NDArray[np.int64], bool,
                                                                                  FloatArray, bool]:
        """One frame with the multistart in the worker: the warm solution, or a better one seeded
        by a finished multistart; starts the multistart when this frame needs one."""
        self.open()
        worker, tracker, chain = self._worker, self.tracker, self.chain
        assert worker is not None
        ref = np.where(self.has[:, None], self.q, 0.0)
        sol = tracker.solve(self.q, arms, R, p)
        q, f, iters, r = unwrap_to(sol.q, ref, chain), sol.f, sol.iterations, sol.residuals
        due = self._pending is not None and (worker.ready() if self.fallback_delay is None
                                             else self.frame - self._pending[0] >= self.fallback_delay)
        adopted = False
        start = bool(tracker.triggers(f, self.f, self.has)[0])
        if due:
            assert self._pending is not None
            ms, f_warm = worker.result(), self._pending[1]
            self._pending = None
            if ms.f[0] < f_warm - ADOPT_GAIN * f_warm:      # the multistart beat the warm solution of its frame
                seeded = tracker.solve(unwrap_to(ms.q, ref, chain), arms, R, p)
                iters = iters + seeded.iterations
                if seeded.f[0] < f[0] - ADOPT_GAIN * f[0]:
                    q, f, r, adopted = unwrap_to(seeded.q, ref, chain), seeded.f, seeded.residuals, True
                    start = bool(tracker.triggers(f, self.f, self.has)[0])
            start |= self._deferred
            self._deferred = False
        submitted = start and self._pending is None
        if submitted:
            worker.submit(arms, R, p, q)
            self._pending = (self.frame, float(f[0]))
        elif start:
            self._deferred = True
        return q, f, iters, submitted, r, adopted


# ------------------------------------------------------------------------------------------------
# sinks
# ------------------------------------------------------------------------------------------------
class Sink(Protocol):
    """Where the output module publishes: ``write`` per result, ``close`` once at the end."""

    def write(self, result: FrameResult) -> None: ...

    def close(self) -> None: ...


@dataclass
class MemorySink:
    """Keeps every published result; :meth:`arrays` stacks them."""

    results: list[FrameResult] = field(default_factory=list)

    def write(self, result: FrameResult) -> None:
        self.results.append(result)

    def close(self) -> None:
        pass

    def arrays(self) -> dict[str, np.ndarray]:
        """``index`` (K,), ``time`` s, ``q`` (K, dof) rad, ``f`` mm², ``residuals`` (K, P) mm, ``iterations``,
        ``restarted``, ``adopted``, ``flagged``, ``latency`` s."""
        res = self.results
        out = {name: np.array([getattr(r, name) for r in res]) for name in
               ("index", "time", "f", "iterations", "restarted", "adopted", "flagged", "latency")}
        out["q"] = np.array([r.q for r in res]).reshape(len(res), -1)
        out["residuals"] = np.array([r.residuals for r in res]).reshape(len(res), -1)
        return out


class CSVSink:
    """One CSV row per published result: frame, time_s, q0_rad…, f_mm2, iterations, restarted, adopted, flagged,
    latency_s."""

    def __init__(self, path: os.PathLike[str] | str, dof: int) -> None:
        self.path = os.fspath(path)
        self._fh = open(self.path, "w", newline="")  # noqa: SIM115 - closed by close()
        self._w = csv.writer(self._fh)
        self._w.writerow(["frame", "time_s", *(f"q{k}_rad" for k in range(dof)), "f_mm2", "iterations",
                          "restarted", "adopted", "flagged", "latency_s"])

    def write(self, result: FrameResult) -> None:
        self._w.writerow([result.index, f"{result.time:.6f}", *(f"{x:.10g}" for x in result.q), f"{result.f:.10g}",
                          result.iterations, int(result.restarted), int(result.adopted), int(result.flagged),
                          f"{result.latency:.6g}"])

    def close(self) -> None:
        self._fh.close()


class SessionSink(MemorySink):
    """Collects the results and writes them into a session group when the run ends.

    Results go into a new group (never overwritten) after streaming, so a session that is
    recording (SWMR) is never written to from the filter.
    """

    def __init__(self, session: Any, group: str, attrs: dict[str, Any] | None = None) -> None:
        super().__init__()
        self.session, self.group, self.attrs = session, group, dict(attrs or {})

    def close(self) -> None:
        self.session.write_group(self.group, self.arrays(), {"units": "q rad, f mm2, residuals mm, time s",
                                                            **self.attrs})


# ------------------------------------------------------------------------------------------------
# the filter
# ------------------------------------------------------------------------------------------------
@dataclass
class FilterStats:
    """Counters of one run: frames read, computed, published, inputs overwritten before being
    computed (``dropped``), output ticks that missed their deadline, multistarts run or started
    (``restarts``), background multistart results adopted on a later frame (``late_adoptions``),
    latencies (s), wall time (s)."""

    frames_in: int = 0
    computed: int = 0
    published: int = 0
    dropped: int = 0
    missed_deadlines: int = 0
    restarts: int = 0
    late_adoptions: int = 0
    latencies: list[float] = field(default_factory=list)
    wall_time: float = 0.0

    def summary(self) -> dict[str, float]:
        lat = np.array(self.latencies) if self.latencies else np.zeros(1)
        return {"frames_in": self.frames_in, "computed": self.computed, "published": self.published,
                "dropped": self.dropped, "missed_deadlines": self.missed_deadlines, "restarts": self.restarts,
                "late_adoptions": self.late_adoptions,
                "latency_mean_ms": 1e3 * float(lat.mean()), "latency_p99_ms": 1e3 * float(np.percentile(lat, 99)),
                "latency_max_ms": 1e3 * float(lat.max()), "wall_time_s": self.wall_time}


class _Slot:
    """Single-slot buffer: the latest value wins; ``seq`` counts writes."""

    def __init__(self) -> None:
        self.cond = threading.Condition()
        self.value: Any = None
        self.seq = 0

    def put(self, value: Any) -> bool:
        """Store ``value``; True if an unread value was overwritten."""
        with self.cond:
            lost = self.value is not None
            self.value, self.seq = value, self.seq + 1
            self.cond.notify_all()
            return lost

    def take(self) -> Any:
        with self.cond:
            value, self.value = self.value, None
            return value


class RetargetFilter:
    """Input → compute → output at ``rate`` Hz (spec §7).

    Parameters
    ----------
    compute : Compute
        The compute module.
    rate : float
        Period of the input and output modules, Hz (e.g. the recording's frame rate).
    sinks : sequence of Sink
        Where the output module publishes.
    """

    def __init__(self, compute: Compute, rate: float, sinks: Sequence[Sink] = ()) -> None:
        if not rate > 0:
            raise RetargetError(f"the filter rate must be > 0 Hz, got {rate!r}")
        self.compute = compute
        self.rate = float(rate)
        self.sinks = list(sinks)
        self.stats = FilterStats()

    def _result(self, index: int, t: float, X: FloatArray, start: float) -> FrameResult:
        q, f, res, it, rs, adopted = self.compute(X)
        self.stats.computed += 1
        self.stats.restarts += rs
        self.stats.late_adoptions += adopted
        return FrameResult(index, float(t), q, f, res, it, rs, adopted, bool(f > self.compute.flag_above),
                           time.perf_counter() - start)

    def _publish(self, result: FrameResult) -> None:
        for sink in self.sinks:
            sink.write(result)
        self.stats.published += 1
        self.stats.latencies.append(result.latency)

    def run(self, frames: Iterable[tuple[float, ArrayLike]], realtime: bool = False) -> FilterStats:
        """Stream ``(time s, pose (n+1, 3) mm)`` frames through the filter and close the sinks.

        Deterministic mode (default): every frame is computed and published once, in order; a
        deadline counts as missed when the compute took longer than one period. Real-time mode:
        three threads at ``rate``; returns when the source is exhausted and the last result is
        published. The compute module's background worker (``fallback_delay`` ≠ 0) is started
        before the first frame and stopped at the end.
        """
        self.stats = FilterStats()
        t0 = time.perf_counter()
        try:
            self.compute.open()                 # a background worker starts before the clock
            t0 = time.perf_counter()
            if realtime:
                self._run_threads(frames)
            else:
                period = 1.0 / self.rate
                for k, (t, X) in enumerate(frames):
                    self.stats.frames_in += 1
                    result = self._result(k, t, np.asarray(X, float), time.perf_counter())
                    self.stats.missed_deadlines += result.latency > period
                    self._publish(result)
        finally:
            self.stats.wall_time = time.perf_counter() - t0
            self.compute.close()
            for sink in self.sinks:
                sink.close()
        return self.stats

    def _run_threads(self, frames: Iterable[tuple[float, ArrayLike]]) -> None:
        period = 1.0 / self.rate
        inbox, outbox = _Slot(), _Slot()
        input_done, compute_done = threading.Event(), threading.Event()
        errors: list[BaseException] = []
        start = time.perf_counter()

        def input_module() -> None:
            try:
                for k, (t, X) in enumerate(frames):
                    delay = start + k * period - time.perf_counter()
                    if delay > 0:
                        input_done.wait(delay)      # never set here: a plain, interruptible tick wait
                    self.stats.frames_in += 1
                    self.stats.dropped += inbox.put((k, t, np.asarray(X, float), time.perf_counter()))
            except BaseException as exc:  # reported by run()
                errors.append(exc)
            finally:
                input_done.set()
                with inbox.cond:
                    inbox.cond.notify_all()

        def compute_module() -> None:
            try:
                while True:
                    with inbox.cond:
                        while inbox.value is None and not input_done.is_set():
                            inbox.cond.wait()
                    item = inbox.take()
                    if item is None:
                        if input_done.is_set():
                            break
                        continue
                    k, t, X, arrived = item
                    result = self._result(k, t, X, arrived)
                    outbox.put(result)
            except BaseException as exc:
                errors.append(exc)
            finally:
                compute_done.set()

        def output_module() -> None:
            published_seq, seen_inputs, tick = 0, 0, 1
            while True:
                finished = compute_done.is_set()
                delay = start + tick * period - time.perf_counter()
                if delay > 0 and not finished:
                    compute_done.wait(delay)
                tick += 1
                result = outbox.take()
                if result is not None:
                    published_seq = outbox.seq
                    self._publish(result)
                elif inbox.seq > seen_inputs and not finished:
                    self.stats.missed_deadlines += 1   # an input arrived but no result by this tick
                seen_inputs = inbox.seq
                if finished and outbox.seq == published_seq and outbox.value is None:
                    break

        threads = [threading.Thread(target=fn, name=f"retarget-{fn.__name__}", daemon=True)
                   for fn in (input_module, compute_module, output_module)]
        for th in threads:
            th.start()
        for th in threads:
            th.join()
        if errors:
            raise errors[0]


def poses(joints: ArrayLike, time_s: ArrayLike) -> Iterable[tuple[float, FloatArray]]:
    """``(time, pose)`` frames of a recorded input (T, n + 1, 3) mm for :meth:`RetargetFilter.run`."""
    X = np.asarray(joints, float)
    return zip(np.asarray(time_s, float).tolist(), X, strict=True)


def compute_for(joints: ArrayLike, chain: Tree, method: str = "lm", **kwargs: Any) -> Compute:
    """A :class:`Compute` whose correspondence uses the median arm lengths of a recording (spec §8)."""
    ic = input_chain(joints, kwargs.get("input_parents"))
    return Compute(chain, ic.lengths, method, **kwargs)
