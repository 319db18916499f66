"""Streams: how live samples travel from device threads to the recorder and to live consumers.

An instrument declares its streams (:class:`StreamSpec`) before recording starts, because the
HDF5 file's shape is fixed once SWMR writing begins. While recording, its acquisition thread calls
:meth:`StreamRouter.publish` with timestamped blocks of samples. The router

* puts each block on one **bounded** queue read by the single recorder thread (device threads
  never wait on disk; when the queue is full the block is dropped, counted and logged), and
* hands it to every :class:`Subscription` on that stream (the TUI's live views, a controller
  closing a loop between two instruments). Subscriptions are bounded by bytes: a slow consumer
  loses its oldest blocks (counted), never slows the device.

Instruments publish whenever they acquire (preview, alignment, a control loop); only the sources
being recorded reach the recorder's queue.
"""

from __future__ import annotations

import logging
import queue
import threading
from collections import deque
from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class StreamSpec:
    """Declaration of one stream of samples.

    Parameters
    ----------
    name
        Stream name, unique within its instrument (``"frames"``, ``"azimuth"``).
    dtype
        numpy dtype string of one sample's values (``"f8"``, ``"u1"``).
    shape
        Shape of one sample (``()`` for a scalar, ``(344, 512)`` for an image).
    unit
        Unit of the values (``"mm"``, ``"rad"``, ``"grey"``...).
    rate
        Nominal sample rate in Hz (``None`` if irregular); used to size HDF5 chunks.
    description
        One line for ``mirrorlab session info`` and the TUI.
    """

    name: str
    dtype: str = "f8"
    shape: tuple[int, ...] = ()
    unit: str = ""
    rate: float | None = None
    description: str = ""

    @property
    def sample_nbytes(self) -> int:
        return int(np.dtype(self.dtype).itemsize * int(np.prod(self.shape, dtype=np.int64)))

    def chunk_samples(self, target_bytes: int = 1 << 20) -> int:
        """Samples per HDF5 chunk: about ``target_bytes`` per chunk and at most one second of data,
        so a chunk is complete (and flushed) at least once a second at the nominal rate."""
        by_size = max(1, target_bytes // max(1, self.sample_nbytes))
        by_rate = max(1, int(self.rate)) if self.rate else by_size
        return int(min(by_size, by_rate, 65536))


@dataclass
class Block:
    """Timestamped samples of one stream: ``times`` (n,) s of session time, ``values`` (n, *shape)."""

    instrument: str
    stream: str
    times: np.ndarray
    values: np.ndarray

    @property
    def nbytes(self) -> int:
        return int(self.times.nbytes + self.values.nbytes)


class BlockQueue:
    """The bounded queue between device threads and the recorder.

    ``put_nowait`` never blocks (a full queue raises :class:`queue.Full`); the recorder takes
    whole batches with :meth:`take`. Built on :class:`collections.deque`, whose ``append`` and
    ``popleft`` are atomic, so a block costs well under a microsecond to pass — a
    :class:`queue.Queue` costs more per block than writing a small block to HDF5.
    """

    def __init__(self, maxsize: int) -> None:
        self.maxsize = maxsize
        self._items: deque[Block] = deque()
        self._ready = threading.Event()

    def put_nowait(self, block: Block) -> None:
        # len() then append() may overshoot by the number of concurrent producers: still bounded.
        if len(self._items) >= self.maxsize:
            raise queue.Full
        self._items.append(block)
        self._ready.set()

    def take(self, limit: int, timeout: float) -> list[Block]:
        """Up to ``limit`` blocks, oldest first, waiting up to ``timeout`` s for the first."""
        if not self._items:
            self._ready.clear()
            if not self._items and not self._ready.wait(timeout):
                return []
        items, popleft = self._items, self._items.popleft
        return [popleft() for _ in range(min(limit, len(items)))]

    def qsize(self) -> int:
        return len(self._items)

    def empty(self) -> bool:
        return not self._items


class Subscription:
    """A bounded live view of one or more streams, filled by the router and read by any thread.

    ``latest`` is the most recent block; :meth:`drain` returns everything since the last call;
    :meth:`get` waits (for a closed loop in another thread). The blocks waiting are bounded by
    their size: when they would hold more than ``max_bytes``, the oldest are discarded and counted
    in ``dropped`` (blocks) — a slow reader loses old data, never memory or the device's pace.
    ``discarded`` counts the samples never read: those dropped so, and those still waiting at :meth:`close`.
    Use it as a context manager, or :meth:`close` it, to stop receiving; the session closes the
    ones it handed out when it closes.
    """

    def __init__(self, keys: list[tuple[str, str]], max_bytes: int = 64 << 20,
                 on_close: Any = None) -> None:
        if max_bytes <= 0:
            raise ValueError(f"max_bytes must be > 0, not {max_bytes}")
        self.keys = list(keys)
        self.max_bytes = max_bytes
        self.latest: Block | None = None
        self.dropped = 0
        self.discarded = 0
        self.closed = False
        self._blocks: deque[Block] = deque()
        self._bytes = 0
        self._cond = threading.Condition()
        self._on_close = on_close

    @property
    def instrument(self) -> str:
        return self.keys[0][0]

    @property
    def stream(self) -> str:
        return self.keys[0][1]

    @property
    def nbytes(self) -> int:
        """Bytes of the blocks waiting to be read."""
        return self._bytes

    def _push(self, block: Block) -> None:
        size = block.nbytes
        with self._cond:
            if self.closed:  # published while being unsubscribed
                return
            self._blocks.append(block)
            self._bytes += size
            while self._bytes > self.max_bytes and len(self._blocks) > 1:
                old = self._blocks.popleft()
                self._bytes -= old.nbytes
                self.dropped += 1
                self.discarded += len(old.times)
            self.latest = block
            self._cond.notify_all()

    def drain(self) -> list[Block]:
        """All blocks received since the previous drain, oldest first."""
        with self._cond:
            out = list(self._blocks)
            self._blocks.clear()
            self._bytes = 0
            return out

    def get(self, timeout: float | None = None) -> Block | None:
        """The oldest waiting block, waiting up to ``timeout`` s; ``None`` on timeout or once closed."""
        with self._cond:
            if not self._cond.wait_for(lambda: bool(self._blocks) or self.closed, timeout) or not self._blocks:
                return None
            block = self._blocks.popleft()
            self._bytes -= block.nbytes
            return block

    def close(self) -> None:
        """Stop receiving blocks, release the waiting ones and wake a waiting :meth:`get` (idempotent)."""
        with self._cond:
            if self.closed:
                return
            self.closed = True
            self.discarded += sum(len(b.times) for b in self._blocks)
            self._blocks.clear()
            self._bytes = 0
            self._cond.notify_all()
        if self._on_close is not None:
            self._on_close(self)

    def __enter__(self) -> Subscription:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


@dataclass
class StreamStats:
    """Per-stream counters of the current recording (reset when a recording starts)."""

    samples: int = 0
    blocks: int = 0
    dropped_samples: int = 0
    overflows: int = 0


class StreamRouter:
    """Routes published blocks to the recorder queue and to subscriptions.

    Parameters
    ----------
    queue_blocks
        Capacity of the recorder queue in blocks. A full queue drops the new block and counts it.
    on_overflow
        Called (from the device thread) as ``on_overflow(block, total_dropped)`` the first time and
        then every 100th time a stream overflows, so overflows are logged without flooding.

    Only the blocks of the sources in :attr:`recorded` (instrument or controller labels) go to the
    recorder queue; every block reaches the subscriptions and updates :attr:`last_time`.
    """

    def __init__(self, queue_blocks: int = 4096, on_overflow: Any = None) -> None:
        self.recorder_queue = BlockQueue(queue_blocks)
        #: Counters of the current (or last) recording, per (source, stream).
        self.stats: dict[tuple[str, str], StreamStats] = {}
        #: Session time of the newest sample published per source, s.
        self.last_time: dict[str, float] = {}
        self.recorded: frozenset[str] = frozenset()
        self._subs: dict[tuple[str, str], list[Subscription]] = {}
        self._lock = threading.Lock()
        self._on_overflow = on_overflow

    def start_recording(self, sources: Iterable[str]) -> None:
        """Queue the blocks of ``sources`` for the recorder from now on, with fresh counters."""
        with self._lock:
            self.stats = {}
            self.recorded = frozenset(sources)

    def stop_recording(self) -> None:
        """Queue nothing more (the counters stay readable until the next recording)."""
        self.recorded = frozenset()

    def subscribe(self, keys: Iterable[tuple[str, str]], max_bytes: int = 64 << 20) -> Subscription:
        """A :class:`Subscription` to the ``(source, stream)`` pairs ``keys``."""
        sub = Subscription(list(keys), max_bytes, on_close=self.unsubscribe)
        with self._lock:
            for key in sub.keys:
                self._subs.setdefault(key, []).append(sub)
        return sub

    def unsubscribe(self, sub: Subscription) -> None:
        with self._lock:
            for key in sub.keys:
                subs = self._subs.get(key, [])
                if sub in subs:
                    subs.remove(sub)
        sub.close()

    def close_all(self) -> None:
        """Close every subscription (when the session closes)."""
        with self._lock:
            subs = {id(sub): sub for subs in self._subs.values() for sub in subs}
            self._subs = {}
        for sub in subs.values():
            sub.close()

    def counts(self) -> dict[str, tuple[int, int]]:
        """Per source: (samples, dropped samples) of the current recording."""
        out: dict[str, tuple[int, int]] = {}
        with self._lock:
            items = list(self.stats.items())
        for (source, _), st in items:
            samples, dropped = out.get(source, (0, 0))
            out[source] = (samples + st.samples, dropped + st.dropped_samples)
        return out

    def publish(self, instrument: str, stream: str, times: Any, values: Any) -> None:
        """Publish ``times`` (n,) s and ``values`` (n, *shape); never blocks."""
        block = Block(instrument, stream, np.atleast_1d(np.asarray(times, dtype="f8")), np.asarray(values))
        key = (instrument, stream)
        n = len(block.times)
        if n:
            self.last_time[instrument] = float(block.times[-1])
        with self._lock:
            subs = list(self._subs.get(key, ()))
            recording = instrument in self.recorded
            stats = self.stats.setdefault(key, StreamStats()) if recording else None
        if stats is not None:
            stats.blocks += 1
            stats.samples += n
            try:
                self.recorder_queue.put_nowait(block)
            except queue.Full:
                stats.dropped_samples += n
                stats.overflows += 1
                if self._on_overflow is not None and stats.overflows % 100 == 1:
                    self._on_overflow(block, stats.dropped_samples)
                else:
                    log.debug("recorder queue full: dropped %d samples of %s/%s", n, instrument, stream)
        for sub in subs:
            sub._push(block)


@dataclass
class Emitter:
    """What an instrument's acquisition thread is handed: ``emit(stream, times, values)``.

    It binds the instrument's label and the session clock so driver code never deals with either.
    """

    instrument: str
    router: StreamRouter
    clock: Any
    streams: dict[str, StreamSpec] = field(default_factory=dict)

    def __call__(self, stream: str, times: Any, values: Any) -> None:
        if stream not in self.streams:
            raise KeyError(f"instrument {self.instrument!r} has no declared stream {stream!r}; "
                           f"declare it in streams() (declared: {', '.join(self.streams) or 'none'})")
        self.router.publish(self.instrument, stream, times, values)

    def now(self) -> float:
        """Session time in seconds."""
        return self.clock.now()
