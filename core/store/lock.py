"""One writer per session file: the writer lock ``<file>.lock``.

Whatever opens a session file for writing (creating it, ``--overwrite``, recording, an analysis,
``session close``, the console) first takes the writer lock of its path: an exclusive
:func:`fcntl.flock` on ``<file>.lock``, which holds who took it (pid, host, command, start
time). The operating system releases the lock when the process ends, however it ends (kill -9
too), so a lock file left behind by a dead writer is simply taken over; one held by a live
writer makes the second writer fail with one line naming it (:class:`WriterBusyError`).
Readers (``session info/check/tree``, export, SWMR readers) never take it: they only ask
:func:`holder` who writes.
"""

from __future__ import annotations

import errno
import fcntl
import json
import os
import socket
import sys
import time
from pathlib import Path
from typing import Any

from ..errors import SessionError

#: How long a writer retries a lock held for a moment by a reader's :func:`holder` probe, s.
PROBE_GRACE = 0.2

#: What the lock records as the writing command (``mirrorlab run``); the CLI sets it, else the
#: program's name.
command = Path(sys.argv[0]).name if sys.argv and sys.argv[0] else "python"


#: The lock files this process holds: a holder asking who writes must not find itself (two
#: descriptors of one process exclude each other under flock).
_held: set[Path] = set()


class WriterBusyError(SessionError):
    """Another live process holds the session file's writer lock."""


def lock_file(path: str | Path) -> Path:
    """``<file>.lock``: the writer lock of session file ``path``."""
    path = Path(path)
    return path.with_name(path.name + ".lock")


def describe(info: dict[str, Any]) -> str:
    """``pid N (mirrorlab run, since HH:MM:SS)`` (``on HOST`` added for another host) from a lock's content."""
    started = time.localtime(float(info.get("started", 0.0)))
    since = time.strftime("%H:%M:%S" if started[:3] == time.localtime()[:3] else "%Y-%m-%d %H:%M:%S", started)
    host = str(info.get("host", ""))
    where = f" on {host}" if host and host != socket.gethostname() else ""
    return f"pid {info.get('pid', '?')}{where} ({info.get('command', '?')}, since {since})"


def busy_message(path: str | Path, info: dict[str, Any]) -> str:
    return f"{path} is being written by {describe(info)}; wait for it to finish or stop it"


def _read(fd: int) -> dict[str, Any]:
    try:
        info = json.loads(os.pread(fd, 4096, 0).decode() or "{}")
    except (OSError, ValueError):
        return {}
    return info if isinstance(info, dict) else {}


def holder(path: str | Path) -> str | None:
    """Who else holds the writer lock of ``path`` right now (see :func:`describe`), or ``None``.

    A lock file whose writer has died does not count (its lock went with it), nor one this process holds.
    """
    if lock_file(path).absolute() in _held:
        return None
    try:
        fd = os.open(lock_file(path), os.O_RDONLY | os.O_CLOEXEC)
    except OSError:
        return None
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
        except BlockingIOError:
            return describe(_read(fd))
        fcntl.flock(fd, fcntl.LOCK_UN)
        return None
    finally:
        os.close(fd)


class WriterLock:
    """The writer lock of one session file, held from :meth:`acquire` until :meth:`release`."""

    def __init__(self, path: Path, fd: int) -> None:
        self.path = path
        self._fd: int | None = fd

    @classmethod
    def acquire(cls, path: str | Path) -> WriterLock:
        """Take the writer lock of ``path`` (creating its folder if needed).

        Raises :class:`WriterBusyError` if a live process holds it, :class:`SessionError` if the
        lock file cannot be created (no permission, read-only disk...).
        """
        from .files import os_error  # files imports h5py; this module stays light

        path = Path(path)
        where = lock_file(path)
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
        except FileExistsError:  # a file stands where the path needs a folder
            raise os_error(path, NotADirectoryError(errno.ENOTDIR, "not a directory"), "create") from None
        except OSError as exc:
            raise os_error(path, exc, "create") from exc
        deadline = time.monotonic() + PROBE_GRACE
        while True:
            try:
                fd = os.open(where, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC, 0o644)
            except OSError as exc:  # said of the session file: it is what cannot be written there
                raise os_error(path, exc, "write to" if path.exists() else "create") from exc
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                info = _read(fd)
                os.close(fd)
                if time.monotonic() < deadline:  # perhaps a reader's probe (holder()): it lets go at once
                    time.sleep(0.01)
                    continue
                raise WriterBusyError(busy_message(path, info)) from None
            # The previous holder may have removed the file between our open and our lock: then
            # we hold a lock on a file nobody else will open; start again on the current one.
            try:
                same = os.fstat(fd).st_ino == os.stat(where).st_ino
            except FileNotFoundError:
                same = False
            if same:
                break
            os.close(fd)
        info = {"pid": os.getpid(), "host": socket.gethostname(), "command": command, "started": time.time()}
        os.ftruncate(fd, 0)
        os.pwrite(fd, json.dumps(info).encode(), 0)
        _held.add(where.absolute())
        return cls(path, fd)

    @property
    def held(self) -> bool:
        return self._fd is not None

    def release(self) -> None:
        """Remove the lock file and let the lock go (idempotent)."""
        if self._fd is None:
            return
        lock_file(self.path).unlink(missing_ok=True)  # while still locked: nobody takes it meanwhile
        os.close(self._fd)
        self._fd = None
        _held.discard(lock_file(self.path).absolute())
