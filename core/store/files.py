"""Opening, checking and repairing session files, including files left by a crash or damaged.

A writer killed while in SWMR mode leaves the superblock marked "open for write": a plain
``h5py.File(path, "r")`` then fails, but ``swmr=True`` opens it with everything flushed before the
kill. h5py cannot clear those flags, so :func:`repair` copies the readable content into a fresh
file and atomically replaces the original.

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
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import h5py

from ..errors import DamagedFileError, MirrorlabError, SessionError
from . import lock as writer_lock
from .recorder import spare_path
from .schema import INCOMPLETE, LIBVER, SCHEMA_VERSION, STATUSES, attr_str, required_root_attrs, run_status

#: HDF5's message for a file whose superblock says a writer has it open (a live or killed writer).
OPEN_FOR_WRITE = "file is already open for write"

#: Reads of metadata per object in SWMR mode before HDF5 gives up. HDF5's default (100) sleeps
#: with exponential backoff between attempts: a truncated or bit-damaged file then retries for
#: many minutes (measured: > 12 min). 20 attempts fail within milliseconds (30 already take 1 s),
#: yet still let a reader ride over a writer's half-written metadata.
SWMR_READ_ATTEMPTS = 20

#: What h5py raises while reading a damaged file: OSError / RuntimeError from the library, KeyError
#: for an object it cannot open, ValueError (UnicodeDecodeError, JSONDecodeError) for garbled text.
READ_ERRORS = (OSError, RuntimeError, KeyError, ValueError)

_ADVICE = {
    errno.EACCES: "check the permissions of the file and its folder (`ls -l`) or use a folder you can write to",
    errno.EPERM: "check the permissions of the file and its folder (`ls -l`) or use a folder you can write to",
    errno.EROFS: "that disk is mounted read-only; use another folder",
    errno.ENOSPC: "the disk is full; free some space or use another disk",
    errno.EDQUOT: "your disk quota is used up; free some space or use another disk",
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


def _open_swmr(path: Path) -> h5py.File:
    """``h5py.File(path, "r", swmr=True)`` with :data:`SWMR_READ_ATTEMPTS` (h5py has no option)."""
    fapl = h5py.h5p.create(h5py.h5p.FILE_ACCESS)
    fapl.set_libver_bounds(h5py.h5f.LIBVER_V110, h5py.h5f.LIBVER_V110)
    # h5p's extension module links libhdf5, so the symbol resolves in the library h5py uses.
    setter = ctypes.CDLL(h5py.h5p.__file__).H5Pset_metadata_read_attempts
    setter.argtypes, setter.restype = [ctypes.c_int64, ctypes.c_uint], ctypes.c_int
    if setter(fapl.id, SWMR_READ_ATTEMPTS) < 0:
        raise SessionError(f"this HDF5 library refused {SWMR_READ_ATTEMPTS} metadata read attempts")
    fid = h5py.h5f.open(os.fsencode(path), h5py.h5f.ACC_RDONLY | h5py.h5f.ACC_SWMR_READ, fapl=fapl)
    return h5py.File(fid)


def open_readonly(path: str | Path) -> tuple[h5py.File, bool]:
    """Open a session file read-only; returns ``(file, crashed)``.

    ``crashed`` is True when the file is still marked open for write by a writer that is gone (or
    still running): it is then opened in SWMR read mode, which works in both cases. Only that
    error falls back to SWMR; a truncated, damaged or non-HDF5 file raises
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
        raise os_error(path, exc) from exc


def open_writable(path: str | Path, mode: str = "a") -> h5py.File:
    """``h5py.File(path, mode, libver=LIBVER)`` with plain errors.

    ``"w"`` creates (or truncates), ``"w-"`` creates and raises :class:`FileExistsError` if the file
    is there (the caller says what that means), ``"a"`` appends. Creating makes missing folders.
    """
    path = Path(path)
    creating = mode in ("w", "w-")
    if creating:
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
        except FileExistsError:  # a file stands where the path needs a folder
            raise os_error(path, NotADirectoryError(errno.ENOTDIR, "not a directory"), "create") from None
        except OSError as exc:
            raise os_error(path, exc, "create") from exc
    try:
        return h5py.File(path, mode, libver=LIBVER)
    except FileExistsError:
        raise
    except OSError as exc:
        raise os_error(path, exc, "create" if creating else "write to") from exc


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

    @property
    def complete(self) -> bool:
        """Closed normally: not aborted, not open or flagged open for write, no problems found."""
        return self.status == "closed" and not self.open_for_write and not self.problems

    def as_dict(self) -> dict[str, Any]:
        return {"path": self.path, "status": self.status, "schema": self.schema,
                "open_for_write": self.open_for_write, "writer": self.writer, "complete": self.complete,
                "problems": self.problems, "streams": self.streams}


def check(path: str | Path) -> CheckReport:
    """Check a session file: schema, status, crash flags, stream consistency."""
    f, crashed = open_readonly(path)
    report = CheckReport(str(path), open_for_write=crashed, writer=live_writer(path))
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
    return report


def repair(path: str | Path) -> None:
    """Rewrite a crashed SWMR file so that it can be opened for writing again.

    Copies every object and attribute readable through SWMR into a new file next to the original
    and replaces the original atomically; the original is untouched if anything fails.
    """
    path = Path(path)
    src = _open_swmr(path)
    fd, tmp_name = tempfile.mkstemp(prefix=path.name + ".", suffix=".repair", dir=path.parent)
    os.close(fd)
    try:
        with src, h5py.File(tmp_name, "w", libver=LIBVER) as dst:
            for key, value in src.attrs.items():
                dst.attrs[key] = value
            for name in src:
                _copy_trimmed(src, dst, name)
        os.replace(tmp_name, path)
    except BaseException:
        Path(tmp_name).unlink(missing_ok=True)
        raise


def _copy_trimmed(src: h5py.Group, dst: h5py.Group, name: str) -> None:
    """Copy ``src[name]``; stream groups are cut to the common length of ``data`` and ``time``."""
    obj = src[name]
    if isinstance(obj, h5py.Group) and "data" in obj and "time" in obj and \
            obj["data"].shape[0] != obj["time"].shape[0]:
        g = dst.create_group(name)
        for k, v in obj.attrs.items():
            g.attrs[k] = v
        n = min(obj["data"].shape[0], obj["time"].shape[0])
        for key in obj:
            ds = obj[key]
            new = g.create_dataset(key, data=ds[:n] if key in ("data", "time") else ds[()],
                                   maxshape=ds.maxshape, chunks=ds.chunks)
            for k, v in ds.attrs.items():
                new.attrs[k] = v
        return
    if isinstance(obj, h5py.Group):
        g = dst.create_group(name)
        for k, v in obj.attrs.items():
            g.attrs[k] = v
        for child in obj:
            _copy_trimmed(obj, g, child)
        return
    src.copy(obj, dst, name=name)


def mark_status(path: str | Path, status: str) -> None:
    """Set the root ``status`` of a session that nobody writes (repairing it if crashed), under its
    writer lock (:class:`~.lock.WriterBusyError` if a live process holds it)."""
    lock = writer_lock.WriterLock.acquire(path)
    try:
        f, crashed = open_readonly(path)
        f.close()
        if crashed:
            repair(path)
        remove_lock(path)
        spare_path(path).unlink(missing_ok=True)  # left by a killed recording
        with open_writable(path) as f:
            f.attrs["status"] = status
    finally:
        lock.release()
