"""The result store of a session: its one HDF5 file, created or opened, written and closed.

:class:`SessionFile` is what :class:`~mirrorlab.core.session.Session` keeps its file in; it knows
the layout (``docs/session-format.md``) and nothing of devices or algorithms. It writes the root
attributes and ``/config`` (recipe and provenance) of a new file, the groups that describe
instruments and controllers, result runs (provenance first, ``status`` last), other groups
(:meth:`~SessionFile.write_group`) and ``/log``; it switches the file to SWMR mode for a recording
(the :class:`~mirrorlab.core.store.recorder.Recorder` then writes alone) and for a run that other
processes read (:meth:`~SessionFile.shared_for_reading`). It also defines session time: its
:attr:`~SessionFile.clock` starts at the file's ``clock_origin_utc``, and its event bus feeds ``/log``.

A new file is a *draft* until it holds something (see :meth:`~SessionFile.commit`).
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import platform
import re
import socket
import sys
import uuid
from collections.abc import Iterator, Mapping, Sequence
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from ..algorithms import Algorithm, ResultRef, RunOutcome
from ..clock import SessionClock, parse_utc, utc_now_iso
from ..errors import SessionError, SessionExistsError
from ..events import EventBus
from ..params import to_jsonable
from ..streams import StreamRouter, StreamSpec
from ..version import distribution_version as _version
from ..version import mirrorlab_version
from . import files, schema
from .lock import WriterLock
from .reader import Reader
from .recorder import Recorder
from .schema import LIBVER

_PACKAGES = ("numpy", "scipy", "h5py", "pluggy", "pyserial", "opencv-python-headless", "textual", "rich")


def output_unit(declared: str, units: Mapping[str, str]) -> str:
    """A declared output unit with each ``{input}`` replaced by that input's unit when it is known.

    >>> output_unit("{values}/s", {"values": "mm"}), output_unit("{values}/s", {})
    ('mm/s', '{values}/s')
    """
    return re.sub(r"\{(\w+)\}", lambda m: units.get(m[1]) or m[0], declared)


class SessionFile(Reader):
    """One open session file: :meth:`create` or :meth:`open` it; everything written goes through here."""

    def __init__(self, path: Path, file: h5py.File, writable: bool, crashed: bool = False,
                 draft: Path | None = None, recovered: str = "", lock: WriterLock | None = None) -> None:
        super().__init__(path, file, crashed, recovered)
        self.writable = writable
        self._lock = lock  # the writer lock of a writable file, released by close()
        #: Created here (not opened): closing it without a status closes it ``closed``.
        self.created = draft is not None
        self._draft = draft  # the file as created, until commit()
        self.closed = False
        #: The recorder while recording (the file is then in SWMR mode and only it writes).
        self.recorder: Recorder | None = None
        self._shared = 0  # depth of shared_for_reading()
        origin = schema.attr_str(file, "clock_origin_utc")
        # Schema 1 files have no stored origin: each opening restarts at 0, as it did then.
        self.clock = SessionClock(parse_utc(origin) if origin else None)
        #: The session's events; what is pending goes to ``/log`` (:meth:`write_log`).
        self.events = EventBus(self.clock)

    # -- opening -----------------------------------------------------------------------------------
    @classmethod
    def create(cls, path: Path, *, operator: str, description: str, recipe: Mapping[str, Any],
               plugins: Mapping[str, Any], overwrite: bool) -> SessionFile:
        """A new file (status ``open``) with its root attributes, groups, ``/log`` and ``/config``
        (``recipe`` and the provenance, ``plugins`` the installed plugins); see ``Session.create``."""
        if path.is_dir():
            raise SessionError(f"{path} is a folder; give a file name such as {path / 'session.h5'}")
        lock = WriterLock.acquire(path)  # before anything else: a live writer's file is never replaced
        try:
            return cls._create(path, lock, operator=operator, description=description, recipe=recipe,
                               plugins=plugins, overwrite=overwrite)
        except BaseException:
            lock.release()
            raise

    @classmethod
    def _create(cls, path: Path, lock: WriterLock, *, operator: str, description: str, recipe: Mapping[str, Any],
                plugins: Mapping[str, Any], overwrite: bool) -> SessionFile:
        if path.exists() and not overwrite:
            raise SessionExistsError(path)
        # The new file is a draft until it holds something (see commit): written beside an existing
        # file, so that a start that fails neither leaves a file behind nor destroys the old one.
        # A new path gets the draft once its header is flushed: a process killed while HDF5 creates
        # the file leaves a hidden draft, never a file at `path` that nothing can open.
        new = not path.exists()
        draft = path.with_name(f".{path.name}.{uuid.uuid4().hex[:8]}.draft")
        f = files.open_writable(draft, "w-", shown=path)
        try:
            created = utc_now_iso()
            f.attrs.update({
                "mirrorlab_schema": schema.SCHEMA_VERSION,
                "mirrorlab_version": mirrorlab_version(),
                "session_id": str(uuid.uuid4()),
                "created_utc": created,
                "clock_origin_utc": created,  # session time 0 of /log, streams and controllers
                "operator": operator,
                "description": description,
                "status": "open",
            })
            for name in schema.GROUPS:
                f.create_group(name)
            schema.create_log(f)
            _write_config(f, recipe, plugins)
            f.flush()
            if new:
                _move_new(draft, path)
                draft = path
        except BaseException:
            f.close()
            draft.unlink(missing_ok=True)
            raise
        return cls(path, f, True, draft=draft, lock=lock)

    @classmethod
    def open(cls, path: Path, writable: bool) -> SessionFile:
        """An existing session file, read-only unless ``writable`` (see ``Session.open``): writable,
        it is first locked against other writers (:class:`~.lock.WriterLock`).

        A file a killed process left flagged open for write is opened all the same (its flags
        cleared in place when that is needed to read or write it: :attr:`recovered` says so),
        except a recording that did not finish, which must be closed first, and a file that a live
        process is writing.
        """
        lock = WriterLock.acquire(path) if writable and path.is_file() else None  # else open_readonly says why
        notes: list[str] = []
        try:
            f, crashed = files.open_readonly(path, notes)
            try:
                with files.reading(path):
                    is_session = "mirrorlab_schema" in f.attrs
                    status = schema.attr_str(f, "status")
            except SessionError:
                f.close()
                raise
            if not is_session:
                f.close()
                raise SessionError(f"{path} is an HDF5 file but not a mirrorlab session (no mirrorlab_schema)")
            if writable:
                f.close()
                if crashed:
                    writer = files.writer_of(path)
                    if writer:
                        raise SessionError(f"{path} is being recorded or analysed right now by {writer}; "
                                           "wait until it has finished before writing to it")
                    if status == "open":
                        raise SessionError(f"{path} was left open by a recording that did not finish; run "
                                           f"`mirrorlab session close {path} --aborted` before writing to it")
                    notes.append(files.clear_open_flags(path))  # an analysis killed while it was shared
                    crashed = False
                f = files.open_writable(path)
        except BaseException:
            if lock is not None:
                lock.release()
            raise
        store = cls(path, f, writable, crashed, recovered=" ".join(notes), lock=lock)
        if notes:
            store.events.emit("warning", "session", "open_flag_cleared", store.recovered)
        return store

    # -- writing -----------------------------------------------------------------------------------
    def require_writable(self, what: str) -> None:
        """Raise :class:`SessionError` unless ``what`` may be written now (not read-only, not recording)."""
        if not self.writable:
            raise SessionError(f"{self.path} is open read-only; open it with writable=True to {what}")
        if self.recorder is not None and what != "record":
            raise SessionError(f"cannot {what} while recording (the file's layout is fixed); stop first")

    def commit(self) -> None:
        """The new file now holds something worth keeping: put it at its path (see :meth:`create`)."""
        if self._draft is not None and self._draft != self.path:
            os.replace(self._draft, self.path)  # the open HDF5 file follows its inode
        self._draft = None

    def flush(self) -> None:
        self.file.flush()

    def write_log(self) -> None:
        """Append the pending events to ``/log``."""
        events = self.events.take_pending()
        if events and self.writable:
            schema.append(self.file["log"], schema.log_rows(events))

    def write_group(self, path: str, arrays: Mapping[str, Any], attrs: Mapping[str, Any] | None = None) -> None:
        """Write arrays into a new group (e.g. ``calibration/cam`` or ``truth/markers``); dicts, lists
        and tuples among ``attrs`` are stored as JSON. A group is never overwritten."""
        self.require_writable(f"write {path}")
        if path.strip("/") in self.file:
            raise SessionError(f"{path} already exists in {self.path}; groups are never overwritten")
        self.commit()
        g = self.file.create_group(path.strip("/"))
        for name, value in arrays.items():
            g.create_dataset(name, data=np.asarray(value))
        for key, value in (attrs or {}).items():
            if isinstance(value, (dict, list, tuple)):
                schema.set_json(g, key, value)
            else:
                g.attrs[key] = value
        self.file.flush()

    def write_instrument(self, label: str, meta: Mapping[str, Any], simulated: bool, settings: Mapping[str, Any],
                         simulator: Mapping[str, Any] | None) -> None:
        """``/instruments/<label>``: its plugin, version, port, identity, ``settings`` and the
        ``simulator`` options of a served simulator (``meta``: ``Instrument.metadata()``)."""
        g = self.file["instruments"].create_group(label)
        g.attrs["plugin"] = meta["plugin"]
        g.attrs["version"] = meta["version"]
        g.attrs["port"] = meta["port"]
        g.attrs["simulated"] = bool(simulated)
        schema.set_json(g, "settings", to_jsonable(settings))
        schema.set_json(g, "identity", meta["identity"])
        g.attrs["firmware"] = meta["identity"].get("firmware", "")
        if simulator is not None:
            schema.set_json(g, "simulator", simulator)
        self.file.flush()  # a process killed while setting up keeps the instruments it had described

    def write_controller(self, label: str, cls: type, settings: Mapping[str, Any], inputs: Mapping[str, str],
                         instruments: Mapping[str, str]) -> None:
        """``/controllers/<label>``: the controller class's name, version and description, its
        ``settings`` and bindings."""
        self.commit()
        g = self.file.require_group("controllers").create_group(label)
        g.attrs.update({"plugin": cls.name, "version": cls.version, "description": cls.description})  # type: ignore[attr-defined]
        schema.set_json(g, "settings", to_jsonable(settings))
        schema.set_json(g, "inputs", dict(inputs))
        schema.set_json(g, "instruments", dict(instruments))
        self.file.flush()

    # -- recording ---------------------------------------------------------------------------------
    def start_recording(self, streams: Sequence[tuple[str, str, StreamSpec]], router: StreamRouter) -> list[tuple[str, str]]:
        """Declare ``streams`` (``(group, source, spec)``, group ``instruments`` or ``controllers``),
        switch to SWMR mode and start the recorder on ``router``'s queue. Returns the recorded
        ``(source, stream)`` pairs."""
        paths: dict[tuple[str, str], str] = {}
        for group, source, spec in streams:
            schema.create_stream(self.file[group][source], spec)
            paths[(source, spec.name)] = f"{group}/{source}/{spec.name}"
        self.write_log()
        self.file.flush()
        self.commit()
        recorder = Recorder(self.file, router, self.events, paths, path=self.path)
        recorder.prepare()  # a disk too full to record raises here, before SWMR
        try:
            self.file.swmr_mode = True  # from here on no object or attribute may be created
        except BaseException:
            recorder.spare.unlink(missing_ok=True)
            raise
        files.write_lock(self.path)  # tells `session check/close` a live writer has the file
        self.recorder = recorder
        recorder.start()
        return list(paths)

    def stop_recording(self) -> Recorder:
        """Stop the recorder (it writes what is queued) and reopen the file without SWMR, so that
        attributes, results and groups can be written again. Returns the recorder; raises its error."""
        recorder, self.recorder = self.recorder, None
        if recorder is None:
            raise SessionError("not recording")
        try:
            recorder.stop()
        finally:
            self.file.close()
            self.file = h5py.File(self.path, "a", libver=LIBVER)
            files.remove_lock(self.path)
        return recorder

    def write_recording_stats(self, reconnects: Mapping[str, int], controllers: Sequence[str],
                              stats: Mapping[str, Mapping[str, int]]) -> None:
        """After a recording: each recorded instrument's ``reconnects`` (label -> count) and each
        recorded stream's ``dropped`` samples (``stats`` as ``Session.stop_recording`` returns them)."""
        for group, sources in (("instruments", list(reconnects)), ("controllers", list(controllers))):
            for source in sources:
                g = self.file[group][source]
                if group == "instruments":
                    g.attrs["reconnects"] = reconnects[source]
                for name in g:
                    if isinstance(g[name], h5py.Group):
                        g[name].attrs["dropped"] = stats.get(f"{source}/{name}", {}).get("dropped", 0)

    @contextlib.contextmanager
    def shared_for_reading(self, required: bool = True) -> Iterator[None]:
        """Let other processes read the file (SWMR) during the block; nothing is written meanwhile.

        Everything is flushed, the file switches to SWMR mode (as while recording, so readers open it
        with :func:`~mirrorlab.core.store.files.open_readonly`), and is reopened writable after.
        HDF5 refuses SWMR mode while an object written in a format older than HDF5 1.10 is open
        (one added to the file by another program): that raises :class:`SessionError` or, with
        ``required=False``, runs the block unshared.
        """
        self.require_writable("share the file for reading")
        if self._shared:  # already shared by an enclosing block
            yield
            return
        self.write_log()
        self.commit()
        self.file.flush()
        try:
            self.file.swmr_mode = True
        except RuntimeError as exc:  # h5py's error for "Unable to start swmr writing (...)"
            if required:
                raise SessionError(f"{self.path} cannot be shared with other processes while it is open here "
                                   f"({exc}); close what holds its datasets open, or run without workers") from exc
            yield
            return
        files.write_lock(self.path)
        self._shared += 1
        try:
            yield
        finally:
            self._shared -= 1
            self.file.close()
            self.file = files.open_writable(self.path)
            files.remove_lock(self.path)

    # -- results -----------------------------------------------------------------------------------
    def write_result(self, cls: type[Algorithm], label: str, started: str, outcome: RunOutcome,
                     sources: Mapping[str, str], digests: Mapping[str, Any], units: Mapping[str, str],
                     executor: Mapping[str, Any] | None) -> ResultRef:
        """Store one run as a new ``/results/<algorithm>/<run-id>`` (never overwritten): its
        provenance, flushed, then its outputs with the ``unit`` (:func:`output_unit` of the inputs'
        ``units``) and ``description`` of their ports, flushed, then ``status`` (a run whose writing
        was interrupted has none: ``incomplete``). ``executor``: its provenance, if one computed it."""
        group = self.file.require_group(f"results/{cls.name}")
        run_id = f"run-{len(group) + 1:04d}"
        while run_id in group:  # never overwrite
            run_id = f"run-{int(run_id[4:]) + 1:04d}"
        g = group.create_group(run_id)
        g.attrs.update({"algorithm": cls.name, "plugin_version": cls.version, "label": label,
                        "started_utc": started})
        schema.set_json(g, "parameters", to_jsonable(outcome.params))
        schema.set_json(g, "inputs", sources)
        schema.set_json(g, "input_sha256", digests)
        if executor is not None:
            schema.set_json(g, "executor", executor)
        self.file.flush()  # the run's provenance is on disk before its outputs
        ports = {p.name: p for p in cls.outputs}
        try:
            for name, value in outcome.outputs.items():
                ds = g.create_dataset(name, data=value)
                ds.attrs["unit"] = output_unit(ports[name].unit, units)
                ds.attrs["description"] = ports[name].description
            g.attrs.update({"finished_utc": utc_now_iso(), "error": outcome.error})
            if outcome.traceback:
                g.attrs["traceback"] = outcome.traceback
            self.file.flush()  # everything of the run is on disk before the status says so
            g.attrs["status"] = outcome.status
            self.file.flush()  # and the status too, before anyone is told the run is stored
        except OSError as exc:  # a full disk: the run stays without status, read as "incomplete"
            self.events.emit("error", cls.name, "result_incomplete",
                             f"{g.name}: writing the run failed, it is left without status (incomplete)")
            raise files.os_error(self.path, exc, "write to") from exc
        return ResultRef(cls.name, run_id, outcome.status, outcome.error, label)

    # -- closing -----------------------------------------------------------------------------------
    def finish(self, status: str) -> None:
        """Write the pending events and ``status``; a ``closed`` draft is kept (see :meth:`commit`)."""
        self.write_log()
        self.file.attrs["status"] = status
        if status == "closed":
            self.commit()

    def close(self) -> None:
        """Close the file; a draft (a new file that never held anything) is deleted."""
        self.closed = True
        try:
            self.file.close()
            if self._draft is not None:  # a start that failed before the file held anything
                self._draft.unlink(missing_ok=True)
        finally:
            if self._lock is not None:
                self._lock.release()


def _move_new(draft: Path, path: Path) -> None:
    """Rename the file at ``draft`` to ``path``, unless ``path`` exists (:class:`SessionExistsError`);
    an open HDF5 file follows its inode."""
    try:
        os.link(draft, path)  # atomic, and never replaces a file created meanwhile
    except FileExistsError:
        raise SessionExistsError(path) from None
    except OSError:  # a file system without hard links (FAT): the next best, checked then renamed
        if path.exists():
            raise SessionExistsError(path) from None
        os.rename(draft, path)
        return
    draft.unlink()


def _write_config(f: h5py.File, recipe: Mapping[str, Any], plugins: Mapping[str, Any]) -> None:
    config = f["config"]
    text = recipe.get("text", "")
    config.create_dataset("recipe", data=text, dtype=schema.STR)
    config.attrs["recipe_path"] = str(recipe.get("path", ""))
    config.attrs["recipe_hash"] = "sha256:" + hashlib.sha256(
        (text + json.dumps(recipe.get("overrides", []))).encode()).hexdigest()
    schema.set_json(config, "overrides", list(recipe.get("overrides", [])))
    schema.set_json(config, "recipe_effective", recipe.get("effective", {}))
    provenance = {
        "python": sys.version,
        "platform": platform.platform(),
        "host": socket.gethostname(),
        "hdf5": h5py.version.hdf5_version,
        "packages": {p: _version(p) for p in _PACKAGES},
        "mirrorlab": mirrorlab_version(),
        "plugins": dict(plugins),
    }
    config.create_dataset("provenance", data=json.dumps(provenance, indent=1, sort_keys=True), dtype=schema.STR)
