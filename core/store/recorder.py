"""The recorder: the one thread that writes samples into the session file while recording.

Device threads publish blocks to the router's bounded queue and never touch h5py (h5py serialises
every call behind one global lock, so one writer is also the fastest). The recorder drains the
queue, appends each block to its stream's ``data`` and ``time`` datasets, appends pending events
to ``/log`` and flushes at least every ``flush_interval`` seconds, so a reader in another process
(SWMR) and a file left by a crash both hold everything older than that.

A full disk ends a recording, never the process. Before each flush the recorder checks the free space
of the file's disk and stops cleanly below a reserve (:func:`reserve_bytes`). If the disk fills up
anyway (another program), HDF5's first failed write stops the writing: the recorder frees a spare
file it keeps beside the session (``<file>.spare``, :data:`SPARE_BYTES`), so that what is cached and
the datasets' lengths can still be written and the file closed (without that room, HDF5 cannot close
the file and the process dies at exit in HDF5). Both end the recording with a :class:`DiskFullError`.
"""

from __future__ import annotations

import contextlib
import errno
import os
import re
import shutil
import threading
import time
from collections import defaultdict
from collections.abc import Mapping
from pathlib import Path

import h5py
import numpy as np

from ..errors import SessionError
from ..events import EventBus
from ..streams import Block, StreamRouter
from .schema import append, log_rows

#: The least free space, bytes, a recording leaves on its disk (see :func:`reserve_bytes`); the
#: environment variable ``MIRRORLAB_DISK_RESERVE_MB`` sets another (0: none, write until the disk is full).
RESERVE_FLOOR = 50 << 20
#: Seconds of recording, at the rate written so far, that the reserve also covers.
RESERVE_SECONDS = 10.0
#: Bytes the spare file beside a recording holds: room for HDF5 to write its cached chunks (1 MiB
#: per dataset by default) and metadata when a full disk stopped it, and so to close the file.
SPARE_BYTES = 4 << 20
#: How HDF5 reports a full disk or quota: an errno in its message (it raises RuntimeError or OSError).
_FULL = re.compile(rf"errno = ({errno.ENOSPC}|{errno.EDQUOT})\b|No space left on device|Disk quota exceeded")


class DiskFullError(SessionError):
    """The disk of a session file is full, or below the recording's reserve: the recording stopped."""


def reserve_bytes(rate: float) -> int:
    """Free space, bytes, below which a recording stops: the larger of :data:`RESERVE_FLOOR` (or
    ``MIRRORLAB_DISK_RESERVE_MB``) and :data:`RESERVE_SECONDS` of data at ``rate`` bytes/s; 0 if
    ``MIRRORLAB_DISK_RESERVE_MB`` is 0 (write until the disk is full)."""
    text = os.environ.get("MIRRORLAB_DISK_RESERVE_MB", "").strip()
    try:
        floor = RESERVE_FLOOR if not text else int(float(text) * (1 << 20))
    except (ValueError, OverflowError):  # not a number, or inf
        floor = -1
    if floor < 0:
        raise SessionError(f"MIRRORLAB_DISK_RESERVE_MB={text!r}: give megabytes, e.g. 50 (0: no reserve)")
    return max(floor, int(RESERVE_SECONDS * rate)) if floor else 0


def spare_path(path: str | Path) -> Path:
    """``<file>.spare``: the room a recording keeps beside session file ``path`` (:data:`SPARE_BYTES`)."""
    path = Path(path)
    return path.with_name(path.name + ".spare")


def disk_full(exc: BaseException) -> bool:
    """Whether ``exc`` (from h5py or the OS) says the disk or the quota is full."""
    return getattr(exc, "errno", None) in (errno.ENOSPC, errno.EDQUOT) or bool(_FULL.search(str(exc)))


def _mb(n: float) -> str:
    return f"{n / (1 << 20):.1f} MB"


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
                 *, path: str | Path, flush_interval: float = 0.5, batch_blocks: int = 4096) -> None:
        self.file = file
        # the session's path, not file.filename: a new session is written under its draft's name until
        # its header is flushed, and HDF5 keeps the name it opened (for messages and the spare beside it)
        self.filename = str(path)
        self.paths = dict(paths)
        self.router = router
        self.events = events
        self.flush_interval = flush_interval
        self.batch_blocks = batch_blocks
        self.error: BaseException | None = None
        self.bytes_written = 0
        self.folder = Path(self.filename).parent
        self.spare = spare_path(self.filename)
        self._started = time.monotonic()
        self.written: dict[tuple[str, str], int] = defaultdict(int)
        # Per stream: [data, time, length, sample shape, length at the last flush]. Looking datasets up
        # and asking h5py for shapes costs more than writing small blocks, so both are cached for the
        # recording's lifetime.
        self._handles: dict[tuple[str, str], list] = {}
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._loop, name="recorder", daemon=True)

    def prepare(self) -> None:
        """Before the file switches to SWMR: check the reserve and set the spare aside, or raise
        :class:`DiskFullError` (nothing is recorded then)."""
        self._check_space()
        try:
            fd = os.open(self.spare, os.O_WRONLY | os.O_CREAT | os.O_TRUNC | os.O_CLOEXEC, 0o644)
            try:
                os.posix_fallocate(fd, 0, SPARE_BYTES)
            finally:
                os.close(fd)
        except OSError as exc:
            self.spare.unlink(missing_ok=True)
            if disk_full(exc):
                raise self._full(f"not even {_mb(SPARE_BYTES)} free to start") from exc
            raise

    def start(self) -> None:
        self._started = time.monotonic()
        self._thread.start()

    def stop(self) -> None:
        """Write everything still queued, flush, and end the thread."""
        self._stop.set()
        self._thread.join()
        self.spare.unlink(missing_ok=True)
        if self.error is not None:
            raise self.error

    @property
    def samples(self) -> int:
        """Samples written so far, every stream."""
        return sum(self.written.values())

    def _full(self, why: str) -> DiskFullError:
        after = time.monotonic() - self._started
        ended = (f"the recording stopped after {after:.1f} s; everything written until then "
                 f"({self.samples} samples in {len(self.paths)} streams) is kept in {self.filename}"
                 if self._thread.is_alive() else f"nothing was recorded into {self.filename}")
        return DiskFullError(f"the disk of {self.folder} is full ({why}): {ended}; free some space or record to "
                             "another disk")

    def _check_space(self) -> None:
        """Raise :class:`DiskFullError` if the free space is below :func:`reserve_bytes`."""
        free = shutil.disk_usage(self.folder).free
        reserve = reserve_bytes(self.bytes_written / max(time.monotonic() - self._started, 1e-3))
        if free < reserve:
            raise self._full(f"{_mb(free)} free, below the reserve of {_mb(reserve)} kept free while recording; "
                             "MIRRORLAB_DISK_RESERVE_MB sets it")

    def _keep_what_was_flushed(self) -> None:
        """After HDF5 failed to write on a full disk: free the spare, cut every stream to its length at
        the last flush (later samples may be lengths without data: HDF5 drops chunks it failed to
        write) and flush, so that the file can be closed."""
        self.spare.unlink(missing_ok=True)
        for key, handle in self._handles.items():
            data, time_ds, n, _, flushed = handle
            for ds in (data, time_ds):
                ds.resize(flushed, axis=0)
            self.written[key] -= n - flushed
            handle[2] = flushed
        self.file.flush()

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
                    for handle in self._handles.values():  # on disk: what a full disk keeps
                        handle[4] = handle[2]
                    last_flush = now
                    if not stopping:
                        self._check_space()
                if stopping:
                    return
        except BaseException as exc:  # surfaced by stop(); the file keeps what was flushed
            self.error = exc
            self.router.stop_recording()  # nothing more to queue: the blocks would only overflow
            if disk_full(exc):  # HDF5 could not write: nothing more is written but what closes the file
                with contextlib.suppress(Exception):  # else the spare was too small: the file keeps its last flush
                    self._keep_what_was_flushed()
                self.error = self._full("no space left")
            message = str(self.error) if isinstance(self.error, DiskFullError) else (
                f"the recording stopped: writing {self.filename} failed ({exc}); "
                "free disk space or check the disk, then record into a new session file")
            self.events.emit("error", "recorder", "recorder_failed", message, error=f"{type(exc).__name__}: {exc}")

    def _write(self, batch: list[Block]) -> None:
        # Group blocks per stream so each dataset is resized once per batch.
        grouped: dict[tuple[str, str], list[Block]] = defaultdict(list)
        for block in batch:
            grouped[(block.instrument, block.stream)].append(block)
        for key, blocks in grouped.items():
            handle = self._handles.get(key)
            if handle is None:
                g = self.file[self.paths[key]]
                data, time_ds = _appended(g, "data"), _appended(g, "time")
                n = time_ds.shape[0]
                handle = self._handles[key] = [data, time_ds, n, data.shape[1:], n]
            data, time_ds, n, shape, _ = handle
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


#: Chunks each recorded dataset keeps in HDF5's chunk cache: the one being filled and the one before.
CACHED_CHUNKS = 2


def _appended(group: h5py.Group, name: str) -> h5py.Dataset:
    """``group[name]`` opened with a chunk cache of :data:`CACHED_CHUNKS` of its own chunks, full ones
    evicted first. HDF5's default (1 MiB per dataset, evicting by recency) keeps chunks that appends
    never touch again, and the process grows for as long as it records (measured on a plain h5py
    append loop, 16 datasets: +116 MiB over 600 k appends; with a cache of a few chunks it levels off
    after the first seconds). The chunk being filled stays cached, so appends never re-read it."""
    chunk = group[name].chunks
    item = group[name].dtype.itemsize
    dapl = h5py.h5p.create(h5py.h5p.DATASET_ACCESS)
    dapl.set_chunk_cache(11, CACHED_CHUNKS * item * int(np.prod(chunk or (1,))), 1.0)
    return h5py.Dataset(h5py.h5d.open(group.id, name.encode(), dapl=dapl))
