"""The recorder: the one thread that writes samples into the session file while recording.

Device threads publish blocks to the router's bounded queue and never touch h5py (h5py serialises
every call behind one global lock, so one writer is also the fastest). The recorder drains the
queue, appends each block to its stream's ``data`` and ``time`` datasets, appends pending events
to ``/log`` and flushes at least every ``flush_interval`` seconds, so a reader in another process
(SWMR) and a file left by a crash both hold everything older than that.
"""

from __future__ import annotations

import threading
import time
from collections import defaultdict
from collections.abc import Mapping

import h5py
import numpy as np

from ..events import EventBus
from ..streams import Block, StreamRouter
from .schema import append, log_rows


class Recorder:
    """Drain ``router.recorder_queue`` into ``file`` (already in SWMR mode) from a thread.

    Parameters
    ----------
    file
        Open session file; every dataset written to must exist before SWMR started.
    router
        Source of the blocks.
    events
        Bus whose pending events go to ``/log``; a failure is reported on it as ``recorder_failed``.
    paths
        ``(source, stream)`` -> the stream's group in the file (``instruments/cam/frames``).
    flush_interval
        Seconds between flushes (≤ 1 s keeps the crash guarantee).
    """

    def __init__(self, file: h5py.File, router: StreamRouter, events: EventBus, paths: Mapping[tuple[str, str], str],
                 flush_interval: float = 0.5, batch_blocks: int = 4096) -> None:
        self.file = file
        self.filename = file.filename  # for the failure message: the file may be unusable by then
        self.paths = dict(paths)
        self.router = router
        self.events = events
        self.flush_interval = flush_interval
        self.batch_blocks = batch_blocks
        self.error: BaseException | None = None
        self.bytes_written = 0
        self.written: dict[tuple[str, str], int] = defaultdict(int)
        # Per stream: (data, time, length). Looking datasets up and asking h5py for shapes costs
        # more than writing small blocks, so both are cached for the recording's lifetime.
        self._handles: dict[tuple[str, str], list] = {}
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._loop, name="recorder", daemon=True)

    def start(self) -> None:
        self._thread.start()

    def stop(self) -> None:
        """Write everything still queued, flush, and end the thread."""
        self._stop.set()
        self._thread.join()
        if self.error is not None:
            raise self.error

    def _loop(self) -> None:
        last_flush = time.monotonic()
        q = self.router.recorder_queue
        try:
            while True:
                batch = q.take(self.batch_blocks, timeout=min(0.05, self.flush_interval))
                if batch:
                    self._write(batch)
                now = time.monotonic()
                stopping = self._stop.is_set() and q.empty()
                if now - last_flush >= self.flush_interval or stopping:
                    self._write_log()
                    self.file.flush()
                    last_flush = now
                if stopping:
                    return
        except BaseException as exc:  # surfaced by stop(); the file keeps what was flushed
            self.error = exc
            self.router.stop_recording()  # nothing more to queue: the blocks would only overflow
            self.events.emit("error", "recorder", "recorder_failed",
                             f"the recording stopped: writing {self.filename} failed ({exc}); "
                             "free disk space or check the disk, then record into a new session file",
                             error=f"{type(exc).__name__}: {exc}")

    def _write(self, batch: list[Block]) -> None:
        # Group blocks per stream so each dataset is resized once per batch.
        grouped: dict[tuple[str, str], list[Block]] = defaultdict(list)
        for block in batch:
            grouped[(block.instrument, block.stream)].append(block)
        for key, blocks in grouped.items():
            handle = self._handles.get(key)
            if handle is None:
                g = self.file[self.paths[key]]
                handle = self._handles[key] = [g["data"], g["time"], g["time"].shape[0], g["data"].shape[1:]]
            data, time_ds, n, shape = handle
            if len(blocks) == 1:  # the live case: write the block itself, no copy
                values, times = blocks[0].values.reshape(-1, *shape), blocks[0].times
            else:
                values = np.concatenate([b.values.reshape(-1, *shape) for b in blocks])
                times = np.concatenate([b.times for b in blocks])
            values = values.astype(data.dtype, copy=False)
            k = len(times)
            data.resize(n + k, axis=0)
            data[n:n + k] = values
            time_ds.resize(n + k, axis=0)
            time_ds[n:n + k] = times
            handle[2] = n + k
            self.written[key] += k
            self.bytes_written += values.nbytes + times.nbytes

    def _write_log(self) -> None:
        events = self.events.take_pending()
        if events:
            append(self.file["log"], log_rows(events))
