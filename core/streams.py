"""Streams: how live samples travel from device threads to the recorder and to live consumers.

An instrument declares its streams (:class:`StreamSpec`) before recording starts, because the
HDF5 file's shape is fixed once SWMR writing begins. While recording, its acquisition thread calls
:meth:`StreamRouter.publish` with timestamped blocks of samples. The router

* puts each block on one **bounded** queue read by the single recorder thread (device threads
  never wait on disk; when the queue is full the block is dropped, counted and logged), and
* hands it to every :class:`Subscription` on that stream (the TUI's live views, a closed control
  loop between two instruments). Subscriptions are bounded ring buffers: a slow consumer loses its
  oldest samples (counted), never slows the device.
"""

from __future__ import annotations

import logging
import queue
import threading
from collections import deque
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
    """A bounded live view of one stream, filled by the router and read by any thread or task.

    ``latest`` is the most recent block; :meth:`drain` returns everything since the last call;
    :meth:`get` waits (for a closed loop in another thread). When more than ``maxlen`` blocks are
    waiting, the oldest are discarded and counted in ``dropped``.
    """

    def __init__(self, instrument: str, stream: str, maxlen: int = 1024) -> None:
        self.instrument = instrument
        self.stream = stream
        self.latest: Block | None = None
        self.dropped = 0
        self._blocks: deque[Block] = deque(maxlen=maxlen)
        self._cond = threading.Condition()

    def _push(self, block: Block) -> None:
        with self._cond:
            if len(self._blocks) == self._blocks.maxlen:
                self.dropped += 1
            self._blocks.append(block)
            self.latest = block
            self._cond.notify_all()

    def drain(self) -> list[Block]:
        """All blocks received since the previous drain, oldest first."""
        with self._cond:
            out = list(self._blocks)
            self._blocks.clear()
            return out

    def get(self, timeout: float | None = None) -> Block | None:
        """The oldest waiting block, waiting up to ``timeout`` s; ``None`` on timeout."""
        with self._cond:
            if not self._cond.wait_for(lambda: bool(self._blocks), timeout):
                return None
            return self._blocks.popleft()


@dataclass
class StreamStats:
    """Per-stream counters kept by the router (reported in the session log and ``status``)."""

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
    """

    def __init__(self, queue_blocks: int = 4096, on_overflow: Any = None) -> None:
        self.recorder_queue = BlockQueue(queue_blocks)
        self.stats: dict[tuple[str, str], StreamStats] = {}
        self._subs: dict[tuple[str, str], list[Subscription]] = {}
        self._lock = threading.Lock()
        self._on_overflow = on_overflow
        self.recording = False

    def subscribe(self, instrument: str, stream: str, maxlen: int = 1024) -> Subscription:
        sub = Subscription(instrument, stream, maxlen)
        with self._lock:
            self._subs.setdefault((instrument, stream), []).append(sub)
        return sub

    def unsubscribe(self, sub: Subscription) -> None:
        with self._lock:
            subs = self._subs.get((sub.instrument, sub.stream), [])
            if sub in subs:
                subs.remove(sub)

    def publish(self, instrument: str, stream: str, times: Any, values: Any) -> None:
        """Publish ``times`` (n,) s and ``values`` (n, *shape); never blocks."""
        block = Block(instrument, stream, np.atleast_1d(np.asarray(times, dtype="f8")), np.asarray(values))
        key = (instrument, stream)
        with self._lock:
            stats = self.stats.setdefault(key, StreamStats())
            subs = list(self._subs.get(key, ()))
        n = len(block.times)
        stats.blocks += 1
        stats.samples += n
        if self.recording:
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
