"""Opening, checking and repairing session files, including files left by a crash.

A writer killed while in SWMR mode leaves the superblock marked "open for write": a plain
``h5py.File(path, "r")`` then fails, but ``swmr=True`` opens it with everything flushed before the
kill. h5py cannot clear those flags, so :func:`repair` copies the readable content into a fresh
file and atomically replaces the original.
"""

from __future__ import annotations

import json
import os
import socket
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import h5py

from ..errors import SessionError
from .schema import LIBVER, ROOT_ATTRS, SCHEMA_VERSION, attr_str


def open_readonly(path: str | Path) -> tuple[h5py.File, bool]:
    """Open a session file read-only; returns ``(file, crashed)``.

    ``crashed`` is True when the file is still marked open for write by a writer that is gone (or
    still running): it is then opened in SWMR read mode, which works in both cases.
    """
    path = Path(path)
    if not path.exists():
        raise SessionError(f"no session file at {path}; check the path")
    try:
        return h5py.File(path, "r"), False
    except OSError as exc:
        try:
            return h5py.File(path, "r", libver=LIBVER, swmr=True), True
        except OSError:
            raise SessionError(f"{path} is not a readable HDF5 session file: {exc}") from exc


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
    """Who is recording ``path`` right now (``"pid N on HOST"``), or ``None`` if nobody is.

    A marker left by a killed writer does not count. A writer on another host cannot be checked
    and is assumed alive (the safe answer: never repair under a live writer).
    """
    try:
        info = json.loads(lock_path(path).read_text())
    except (OSError, ValueError):
        return None
    pid, host = int(info.get("pid", -1)), str(info.get("host", ""))
    if host == socket.gethostname():
        try:
            os.kill(pid, 0)
        except ProcessLookupError:
            return None
        except PermissionError:
            pass  # exists, owned by someone else
    return f"pid {pid} on {host}"


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
        return self.status in ("closed", "aborted") and not self.open_for_write and not self.problems

    def as_dict(self) -> dict[str, Any]:
        return {"path": self.path, "status": self.status, "schema": self.schema,
                "open_for_write": self.open_for_write, "writer": self.writer, "complete": self.complete,
                "problems": self.problems, "streams": self.streams}


def check(path: str | Path) -> CheckReport:
    """Check a session file: schema, status, crash flags, stream consistency."""
    f, crashed = open_readonly(path)
    report = CheckReport(str(path), open_for_write=crashed, writer=live_writer(path))
    with f:
        missing = [a for a in ROOT_ATTRS if a not in f.attrs]
        if missing:
            report.problems.append(f"missing root attributes: {', '.join(missing)} (not a mirrorlab session?)")
        report.schema = int(f.attrs["mirrorlab_schema"]) if "mirrorlab_schema" in f.attrs else None
        if report.schema is not None and report.schema > SCHEMA_VERSION:
            report.problems.append(f"schema {report.schema} is newer than this mirrorlab ({SCHEMA_VERSION}); upgrade")
        report.status = attr_str(f, "status")
        if report.status == "open":
            if report.writer:
                report.problems.append(f"status is 'open': it is being recorded right now by {report.writer}")
            else:
                why = "the recording was killed" if crashed else "it was never closed"
                report.problems.append(f"status is 'open': the session is incomplete ({why}); "
                                       "run `mirrorlab session close FILE --aborted` to mark it")
        for label, inst in f.get("instruments", {}).items():
            for name, g in inst.items():
                if not isinstance(g, h5py.Group) or "data" not in g:
                    continue
                n_data, n_time = g["data"].shape[0], g["time"].shape[0]
                report.streams[f"{label}/{name}"] = {"samples": min(n_data, n_time)}
                if n_data != n_time:
                    report.problems.append(f"stream {label}/{name}: {n_data} samples but {n_time} times "
                                           "(cut off by a crash; readers use the shorter length)")
    return report


def repair(path: str | Path) -> None:
    """Rewrite a crashed SWMR file so that it can be opened for writing again.

    Copies every object and attribute readable through SWMR into a new file next to the original
    and replaces the original atomically; the original is untouched if anything fails.
    """
    path = Path(path)
    src = h5py.File(path, "r", libver=LIBVER, swmr=True)
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
    """Set the root ``status`` of a session that is not being recorded (repairing it if crashed)."""
    writer = live_writer(path)
    if writer:
        raise SessionError(f"{path} is being recorded by {writer}; stop that recording first")
    f, crashed = open_readonly(path)
    f.close()
    if crashed:
        repair(path)
    remove_lock(path)
    with h5py.File(path, "a", libver=LIBVER) as f:
        f.attrs["status"] = status
