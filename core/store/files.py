"""Opening, checking and repairing session files, including files left by a crash or damaged.

A writer killed while it has the file open leaves the superblock marked "open for write": a plain
``h5py.File(path, "r")`` then fails. Killed in SWMR mode (recording, an algorithm running),
``swmr=True`` still opens it with everything flushed before the kill; killed in normal write mode
(setting up, previewing, writing results or a report, closing), nothing opens it until the flags
are cleared. :func:`clear_open_flags` clears them in place as HDF5's ``h5clear -s`` does, once no
live process has the file (:func:`writer_of`): :func:`open_readonly` does so for a file flagged
in normal mode, :func:`mark_status` (``session close``) for any flagged file. Everything flushed
before the kill is kept; the file keeps its inode and permissions.

Every other failure to open or read a file (truncated, bit-damaged, not HDF5, a folder, no
permission) becomes one typed error in plain words (:func:`os_error`, :func:`reading`), never
HDF5's multi-line message with its buffer addresses and open flags.
"""

from __future__ import annotations

import ctypes
import errno
import json
import os
import re
import socket
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from functools import cache
from pathlib import Path
from typing import Any

import h5py

from ..errors import DamagedFileError, MirrorlabError, SessionError
from . import integrity
from . import lock as writer_lock
from .integrity import READ_ERRORS
from .recorder import spare_path
from .schema import INCOMPLETE, LIBVER, SCHEMA_VERSION, STATUSES, attr_str, read_log, required_root_attrs, run_status

#: HDF5's message for a file whose superblock says a writer has it open (a live or killed writer).
OPEN_FOR_WRITE = "file is already open for write"
#: HDF5's message when a SWMR reader finds such a file flagged by a writer in normal (not SWMR) mode.
NOT_SWMR = "file is not already open for SWMR writing"
#: HDF5's private file-access property that ``h5clear -s`` sets (tools/src/h5clear/h5clear.c): an
#: open for read-write with it set to true zeroes the superblock's status flags.
CLEAR_STATUS_FLAGS = b"clear_status_flags"

#: Reads of metadata per object in SWMR mode before HDF5 gives up. HDF5's default (100) sleeps
#: with exponential backoff between attempts: a truncated or bit-damaged file then retries for
#: many minutes (measured: > 12 min). 20 attempts fail within milliseconds (30 already take 1 s),
#: yet still let a reader ride over a writer's half-written metadata.
SWMR_READ_ATTEMPTS = 20


_ADVICE = {
    errno.EACCES: "check the permissions of the file and its folder (`ls -l`) or use a folder you can write to",
    errno.EPERM: "check the permissions of the file and its folder (`ls -l`) or use a folder you can write to",
    errno.EROFS: "that disk is mounted read-only; use another folder",
    errno.ENOSPC: "the disk is full; free some space or use another disk",
    errno.EDQUOT: "your disk quota is used up; free some space or use another disk",
    errno.EMFILE: "this process has too many files open; close other sessions or raise the limit (`ulimit -n`)",
    errno.ENFILE: "the system has too many files open; close other programs and try again",
    errno.ENOENT: "check the path",
    errno.ENOTDIR: "a part of the path is a file, not a folder; check the path",
    errno.EISDIR: "that is a folder; give the path of a session file (.h5)",
}


def os_error(path: str | Path, exc: BaseException, action: str = "read") -> MirrorlabError:
    """The plain-words error for ``exc``, raised by h5py while trying to ``action`` ``path``.

    Operating-system failures (no permission, read-only disk, disk full...) become a
    :class:`SessionError` naming the cause and what to do; anything HDF5 could not make sense of
    becomes a :class:`DamagedFileError`. Never includes HDF5's open flags or buffer addresses.
    """
    code = getattr(exc, "errno", None)
    if isinstance(exc, OSError) and code in (errno.EAGAIN, errno.EWOULDBLOCK):  # HDF5's file lock
        return SessionError(f"cannot {action} {path}: it is open for writing in another process "
                            f"({writer_of(path) or 'HDF5 file lock held'}); wait until that process has "
                            "finished (or close the file there), then try again")
    if isinstance(exc, OSError) and code in _ADVICE:
        return SessionError(f"cannot {action} {path}: {os.strerror(code)}; {_ADVICE[code]}")
    text = str(exc)
    cut = re.search(r"truncated file: eof = (\d+).*stored_eof = (\d+)", text)
    if cut:
        return DamagedFileError(f"{path}: truncated or damaged HDF5 file: only {int(cut[1]):,} of its "
                                f"{int(cut[2]):,} bytes are there (cut off while copying or writing?); "
                                "copy it again from its source or restore it from a backup")
    if "file signature not found" in text:
        return DamagedFileError(f"{path}: not an HDF5 file, or a truncated or damaged HDF5 file (no HDF5 signature); "
                                "give a mirrorlab session file (.h5) or restore this one from a backup")
    if isinstance(exc, OSError) and code is not None:
        return SessionError(f"cannot {action} {path}: {os.strerror(code)}; check the path and the disk")
    return DamagedFileError(f"{path}: truncated or damaged HDF5 file ({_reason(exc)}); "
                            "restore it from a backup or copy it again from its source")


def _reason(exc: BaseException) -> str:
    """HDF5's reason without the call it failed in, its key = value details or its h5clear hint."""
    if isinstance(exc, UnicodeDecodeError):
        return "text that is not valid UTF-8"
    if isinstance(exc, json.JSONDecodeError):
        return "an attribute that is not valid JSON"
    text = str(exc.args[0]) if isinstance(exc, KeyError) and exc.args else str(exc)
    if "(" in text and text.rstrip().endswith(")"):
        text = text[text.index("(") + 1:text.rstrip().rindex(")")]
    text = re.split(r"[:,] \w+ = ", text)[0].split(" (may use")[0].strip()
    return text or type(exc).__name__


@contextmanager
def reading(path: str | Path) -> Iterator[None]:
    """Turn what h5py raises while reading ``path`` into one :class:`DamagedFileError`."""
    try:
        yield
    except MirrorlabError:
        raise
    except READ_ERRORS as exc:
        raise os_error(path, exc) from exc


def members(group: h5py.Group, name: str | None = None) -> list[tuple[str, Any]]:
    """``(name, object)`` of each member of ``group`` (or of its member ``name``; none if absent).

    Unlike ``Group.items()``, which gives ``None`` for an object HDF5 cannot open, this raises
    ``KeyError`` (one of :data:`READ_ERRORS`): a damaged file is reported, not read as empty.
    """
    if name is not None:
        if name not in group:
            return []
        group = group[name]
    return [(key, group[key]) for key in group]


def is_hdf5(path: str | Path) -> bool:
    """Whether ``path`` is a file in HDF5's format (by its signature, whatever its name), a session or not."""
    return Path(path).is_file() and h5py.is_hdf5(path)


def _require_file(path: Path) -> None:
    if path.is_dir():
        inside = sorted(p.name for p in path.glob("*.h5"))[:3]
        hint = f" (it holds {', '.join(inside)})" if inside else ""
        raise SessionError(f"{path} is a folder, not a session file; give the path of a .h5 file{hint}")
    if not path.exists():
        raise SessionError(f"no session file at {path}; check the path")


@cache
def _libhdf5() -> ctypes.CDLL:
    """The HDF5 library h5py itself uses, for the few calls h5py does not wrap.

    h5p's extension module links h5py's libhdf5 (bundled in ``h5py.libs`` or the one it was built
    against), so symbols looked up through it resolve in that library, never in another copy.
    """
    lib = ctypes.CDLL(h5py.h5p.__file__)
    lib.H5Pset_metadata_read_attempts.argtypes = [ctypes.c_int64, ctypes.c_uint]
    lib.H5Pset.argtypes = [ctypes.c_int64, ctypes.c_char_p, ctypes.c_void_p]
    lib.H5Fget_eoa.argtypes = [ctypes.c_int64, ctypes.POINTER(ctypes.c_uint64)]
    lib.H5Fincrement_filesize.argtypes = [ctypes.c_int64, ctypes.c_uint64]
    for name in ("H5Pset_metadata_read_attempts", "H5Pset", "H5Fget_eoa", "H5Fincrement_filesize"):
        getattr(lib, name).restype = ctypes.c_int
    return lib


def _open_swmr(path: Path) -> h5py.File:
    """``h5py.File(path, "r", swmr=True)`` with :data:`SWMR_READ_ATTEMPTS` (h5py has no option)."""
    fapl = h5py.h5p.create(h5py.h5p.FILE_ACCESS)
    fapl.set_libver_bounds(h5py.h5f.LIBVER_V110, h5py.h5f.LIBVER_V110)
    if _libhdf5().H5Pset_metadata_read_attempts(fapl.id, SWMR_READ_ATTEMPTS) < 0:
        raise SessionError(f"this HDF5 library refused {SWMR_READ_ATTEMPTS} metadata read attempts")
    fid = h5py.h5f.open(os.fsencode(path), h5py.h5f.ACC_RDONLY | h5py.h5f.ACC_SWMR_READ, fapl=fapl)
    return h5py.File(fid)


def open_readonly(path: str | Path, notes: list[str] | None = None) -> tuple[h5py.File, bool]:
    """Open a session file read-only; returns ``(file, crashed)``.

    ``crashed`` is True when the file is still marked open for write by a writer in SWMR mode that
    is gone (or still running): it is then opened in SWMR read mode, which works in both cases.
    A file marked open by a writer in normal mode cannot be read that way: if that writer is gone
    (:func:`writer_of`), its flags are cleared in place (:func:`clear_open_flags`) and what was
    done is appended to ``notes``; if it is alive, :class:`SessionError` says who has it. Only
    these errors get this treatment; a truncated, damaged or non-HDF5 file raises
    :class:`DamagedFileError` at once, other failures a :class:`SessionError` in plain words.
    """
    path = Path(path)
    _require_file(path)
    try:
        return h5py.File(path, "r"), False
    except OSError as exc:
        if OPEN_FOR_WRITE not in str(exc):
            raise os_error(path, exc) from exc
    try:
        return _open_swmr(path), True
    except READ_ERRORS as exc:
        if NOT_SWMR not in str(exc):
            raise os_error(path, exc) from exc
    note = clear_open_flags(path)
    if notes is not None:
        notes.append(note)
    try:
        return h5py.File(path, "r"), False
    except OSError as exc:
        raise os_error(path, exc) from exc


def clear_open_flags(path: str | Path) -> str:
    """Clear the "open for write" flags a killed writer left in ``path``'s superblock, in place, as
    ``h5clear -s`` does; returns the sentence that tells the user so.

    Refuses (:class:`SessionError`) while a process has the file (:func:`writer_of`), and HDF5's
    own lock makes the read-write open here fail while another process holds the file in normal
    mode. What the writer had flushed is kept: only the status flags change, and the end of file
    HDF5 keeps is extended to the file's size if it is shorter, so that closing truncates nothing.
    The file keeps its inode and permissions. A file HDF5 cannot read then raises
    :class:`DamagedFileError` as any damaged file does.
    """
    path = Path(path)
    writer = writer_of(path)
    if writer:
        raise SessionError(f"{path} is being written right now by {writer}; wait until it has finished")
    lib = _libhdf5()
    fapl = h5py.h5p.create(h5py.h5p.FILE_ACCESS)
    clear = ctypes.c_bool(True)
    if lib.H5Pset(fapl.id, CLEAR_STATUS_FLAGS, ctypes.byref(clear)) < 0:
        raise SessionError(f"{path} is flagged open for write, and this HDF5 library ({h5py.version.hdf5_version}) "
                           "cannot clear the flags; run `h5clear -s FILE` (Debian package hdf5-tools)")
    try:
        fid = h5py.h5f.open(os.fsencode(path), h5py.h5f.ACC_RDWR, fapl=fapl)
    except READ_ERRORS as exc:
        raise os_error(path, exc, "repair") from exc
    try:
        eoa = ctypes.c_uint64()
        if lib.H5Fget_eoa(fid.id, ctypes.byref(eoa)) >= 0 and eoa.value < path.stat().st_size:
            lib.H5Fincrement_filesize(fid.id, 0)  # EOA = max(EOA, EOF): keep bytes written past the stored end
    finally:
        fid.close()
    return (f"{path} was left open for writing by a process that ended; its open flag was cleared "
            "(everything that process had saved is kept)")


def writer_of(path: str | Path) -> str | None:
    """Which live process writes ``path`` or has it open (``"pid N on HOST"``, ``"pid N"``), or ``None``.

    The writer lock (:func:`live_writer`) names a mirrorlab writer of another process.
    Any other process of this machine that has the file open (as far as ``/proc`` shows this user)
    counts too: a writer in SWMR mode holds no lock, and a file system may not support HDF5's locks.
    """
    return live_writer(path) or _process_with(path)


def _process_with(path: str | Path) -> str | None:
    """Another process of this machine that has ``path`` open (``"pid N"``, as far as ``/proc`` shows
    this user), or ``None``."""
    try:
        target = os.stat(path)
    except OSError:
        return None
    me = str(os.getpid())
    for pid in filter(str.isdigit, _listdir("/proc")):
        if pid == me:
            continue
        for fd in _listdir(f"/proc/{pid}/fd"):
            try:
                st = os.stat(f"/proc/{pid}/fd/{fd}")
            except OSError:  # closed meanwhile, or not ours to see
                continue
            if (st.st_dev, st.st_ino) == (target.st_dev, target.st_ino):
                return f"pid {pid}"
    return None


def _listdir(folder: str) -> list[str]:
    try:
        return os.listdir(folder)
    except OSError:  # no /proc (not Linux), a process that ended, or one we may not inspect
        return []


def open_writable(path: str | Path, mode: str = "a", shown: str | Path | None = None) -> h5py.File:
    """``h5py.File(path, mode, libver=LIBVER)`` with plain errors (naming ``shown``, default ``path``:
    a draft's errors name the file it becomes).

    ``"w"`` creates (or truncates), ``"w-"`` creates and raises :class:`FileExistsError` if the file
    is there (the caller says what that means), ``"a"`` appends. Creating makes missing folders.
    """
    path = Path(path)
    shown = path if shown is None else shown
    creating = mode in ("w", "w-")
    if creating:
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
        except FileExistsError:  # a file stands where the path needs a folder
            raise os_error(shown, NotADirectoryError(errno.ENOTDIR, "not a directory"), "create") from None
        except OSError as exc:
            raise os_error(shown, exc, "create") from exc
    try:
        return h5py.File(path, mode, libver=LIBVER)
    except FileExistsError:
        raise
    except OSError as exc:
        raise os_error(shown, exc, "create" if creating else "write to") from exc


def lock_path(path: str | Path) -> Path:
    """The marker file a recording keeps next to its session file: ``<file>.recording``."""
    path = Path(path)
    return path.with_name(path.name + ".recording")


def write_lock(path: str | Path) -> None:
    """Mark ``path`` as being recorded by this process (host and pid)."""
    lock_path(path).write_text(json.dumps({"host": socket.gethostname(), "pid": os.getpid()}))


def remove_lock(path: str | Path) -> None:
    lock_path(path).unlink(missing_ok=True)


def live_writer(path: str | Path) -> str | None:
    """Who writes ``path`` right now (``"pid N (mirrorlab run, since HH:MM:SS)"``), or ``None`` if
    nobody does: the holder of its writer lock (:mod:`.lock`; a killed writer holds none)."""
    return writer_lock.holder(path)


@dataclass
class CheckReport:
    """What :func:`check` found."""

    path: str
    status: str = ""
    schema: int | None = None
    open_for_write: bool = False
    writer: str | None = None
    problems: list[str] = field(default_factory=list)
    streams: dict[str, dict[str, Any]] = field(default_factory=dict)
    #: What was done to open the file (its open flags cleared after a crash), for the user to know.
    notes: list[str] = field(default_factory=list)
    #: with ``check(data=True)``: whether the file has checksums to verify (``None``: not asked)
    checksums: bool | None = None

    @property
    def complete(self) -> bool:
        """Closed normally: not aborted, not open or flagged open for write, no problems found."""
        return self.status == "closed" and not self.open_for_write and not self.problems

    def as_dict(self) -> dict[str, Any]:
        return {"path": self.path, "status": self.status, "schema": self.schema,
                "open_for_write": self.open_for_write, "writer": self.writer, "complete": self.complete,
                "problems": self.problems, "streams": self.streams, "notes": self.notes, "checksums": self.checksums}


def check(path: str | Path, data: bool = False) -> CheckReport:
    """Check a session file: schema, status, crash flags, stream consistency, instruments that failed while
    recording, and that every object reads (:mod:`~mirrorlab.core.store.integrity`); with ``data``, also every
    chunk of the checksummed streams."""
    notes: list[str] = []
    f, crashed = open_readonly(path, notes)
    report = CheckReport(str(path), open_for_write=crashed, writer=live_writer(path), notes=notes)
    with f, reading(path):
        report.schema = int(f.attrs["mirrorlab_schema"]) if "mirrorlab_schema" in f.attrs else None
        missing = [a for a in required_root_attrs(report.schema) if a not in f.attrs]
        if missing:
            report.problems.append(f"missing root attributes: {', '.join(missing)} (not a mirrorlab session?)")
        if report.schema is not None and report.schema > SCHEMA_VERSION:
            report.problems.append(f"schema {report.schema} is newer than this mirrorlab ({SCHEMA_VERSION}); upgrade")
        report.status = attr_str(f, "status")
        if report.status not in STATUSES:
            report.problems.append(f"status {report.status!r} is none of {', '.join(STATUSES)} "
                                   "(a damaged file, or not written by mirrorlab)")
        if report.status == "aborted":
            report.problems.append("status is 'aborted': the recording did not finish as planned "
                                   "(everything recorded up to its end is kept)")
        if report.status == "open":
            if report.writer:
                report.problems.append(f"status is 'open': it is being recorded right now by {report.writer}")
            else:
                why = "the recording was killed" if crashed else "it was never closed"
                report.problems.append(f"status is 'open': the session is incomplete ({why}); "
                                       "run `mirrorlab session close FILE --aborted` to mark it")
        elif crashed:  # a session opened again to add results (an analysis), with the file in SWMR mode
            if report.writer:
                report.problems.append(f"results are being written right now by {report.writer}")
            else:
                report.problems.append("the process writing results into it was killed and the file is still "
                                       "flagged open for write; run `mirrorlab session close FILE` to repair it "
                                       "(everything written before that run is kept)")
        for label, inst in members(f, "instruments"):
            for name, g in members(inst):
                if not isinstance(g, h5py.Group) or "data" not in g:
                    continue
                n_data, n_time = g["data"].shape[0], g["time"].shape[0]
                report.streams[f"{label}/{name}"] = {"samples": min(n_data, n_time)}
                if n_data != n_time:
                    report.problems.append(f"stream {label}/{name}: {n_data} samples but {n_time} times "
                                           "(cut off by a crash; readers use the shorter length)")
        for algorithm, runs in members(f, "results"):
            for run_id, run in members(runs):
                if run_status(run) == INCOMPLETE:
                    report.problems.append(f"result /results/{algorithm}/{run_id} has no status: its writing "
                                           "was interrupted and its outputs may be partial; run it again")
        try:
            damaged = integrity.first_unreadable(f)
            if not damaged:
                report.problems += integrity.instrument_failures(read_log(f))
                if data:
                    report.checksums = integrity.has_checksums(f)
                    report.problems += integrity.checksum_failures(f)
        except READ_ERRORS as exc:  # inside an object whose ends read (e.g. the middle of /log)
            damaged = str(exc)
        if damaged:
            report.problems.append(f"damaged: {damaged}; restore the file from a backup (`mirrorlab session export` "
                                   "still reads the objects that are intact)")
    return report


def mark_status(path: str | Path, status: str, notes: list[str] | None = None) -> None:
    """Set the root ``status`` of a session that nobody writes, under its writer lock
    (:class:`~.lock.WriterBusyError` if a live process holds it): first clearing the open flags a
    killed writer left (in place: :func:`clear_open_flags`; what was done is appended to ``notes``),
    removing the spare a killed recording left, and cutting each stream's ``data`` and ``time`` to
    their common length (a crash may leave one longer)."""
    lock = writer_lock.WriterLock.acquire(path)
    try:
        writer = writer_of(path)
        if writer:
            raise SessionError(f"{path} is being written right now by {writer}; stop that recording first")
        f, crashed = open_readonly(path, notes)
        f.close()
        if crashed:
            note = clear_open_flags(path)
            if notes is not None:
                notes.append(note)
        remove_lock(path)
        spare_path(path).unlink(missing_ok=True)  # left by a killed recording
        with open_writable(path) as f:
            for group in ("instruments", "controllers"):
                for _, source in members(f, group):
                    for _, stream in members(source):
                        if isinstance(stream, h5py.Group) and "data" in stream and "time" in stream:
                            n = min(stream["data"].shape[0], stream["time"].shape[0])
                            for ds in (stream["data"], stream["time"]):
                                if ds.shape[0] > n:
                                    ds.resize(n, axis=0)
            f.attrs["status"] = status
    finally:
        lock.release()
