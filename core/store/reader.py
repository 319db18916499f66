"""Reading a session file: the read API of :class:`~mirrorlab.core.session.Session`.

What a :class:`Reader` returns is plain data (numpy arrays and scalars, text, :class:`Node`,
:class:`StreamData`, :class:`ResultData`), never an h5py object, so that no code outside
``mirrorlab.core.store`` handles the HDF5 file. Paths are the file's (``/instruments/cam/frames/data``,
the leading ``/`` optional). A file being recorded (in SWMR mode, here or by another process) is
refreshed before a dataset is read, so a reader sees what the recorder has flushed.

    >>> import tempfile, pathlib
    >>> from mirrorlab.core import Session
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "read.h5"
    >>> with Session.create(path) as s:
    ...     s.write_group("truth/cam", {"xy": [[1.0, 2.0], [3.0, 4.0]]}, {"unit": "px", "labels": ["a", "b"]})
    >>> with Session.open(path) as s:
    ...     s.exists("/truth/cam/xy"), s.members("/truth/cam"), s.read("/truth/cam/xy", 1).tolist()
    ...     s.node("/truth/cam/xy").shape, s.attributes("/truth/cam")["unit"], s.json_attribute("/truth/cam", "labels")
    ...     sorted(s.truth("cam")), [n.path for n in s.tree("/truth")]
    (True, ['xy'], [3.0, 4.0])
    ((2, 2), 'px', ['a', 'b'])
    (['xy'], ['/truth/cam', '/truth/cam/xy'])
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TypeVar

import h5py
import numpy as np

from ..algorithms import ResultRef
from ..errors import SessionError
from . import files, schema
from .schema import attr_str, get_json, run_status


@dataclass(frozen=True)
class Node:
    """One group or dataset of a session file, as :meth:`Reader.tree` and :meth:`Reader.node` describe it.

    Attributes
    ----------
    path
        Absolute path in the file (``/instruments/cam/frames/data``).
    is_dataset
        A dataset (else a group).
    shape, dtype
        A dataset's shape and numpy type (``()`` and ``None`` for a group).
    unit
        A dataset's ``unit`` attribute; a recorded stream's ``data`` has its stream group's.
    attrs
        The names of its attributes, sorted.
    members
        A group's number of members (0 for a dataset).
    """

    path: str
    is_dataset: bool
    shape: tuple[int, ...] = ()
    dtype: np.dtype | None = None
    unit: str = ""
    attrs: tuple[str, ...] = ()
    members: int = 0

    @property
    def name(self) -> str:
        return self.path.rsplit("/", 1)[-1] or "/"


@dataclass
class StreamData:
    """A recorded stream: ``times`` (n,) s, ``data`` (n, *shape), and its attributes."""

    times: np.ndarray
    data: np.ndarray
    unit: str
    attrs: dict[str, Any]

    def __iter__(self) -> Iterator[np.ndarray]:  # allows ``times, data = session.stream(...)``
        return iter((self.times, self.data))


@dataclass
class ResultData:
    """A stored algorithm run: its outputs and provenance attributes."""

    ref: ResultRef
    outputs: dict[str, np.ndarray]
    attrs: dict[str, Any]


class StoredArray:
    """A dataset of the session file read on demand: an algorithm input that an executor reads whole
    or in parts (``array[a:b]``), or hands to workers by its ``path``. Valid while the file stays open."""

    def __init__(self, dataset: h5py.Dataset) -> None:
        self._dataset = dataset
        self.path: str = dataset.name
        self.shape: tuple[int, ...] = tuple(dataset.shape)
        self.dtype: np.dtype = dataset.dtype
        self.ndim: int = dataset.ndim

    def __getitem__(self, index: Any) -> Any:
        with files.reading(self._dataset.file.filename):
            return self._dataset[index]

    def __len__(self) -> int:
        return self.shape[0]


def _decoded(attrs: h5py.AttributeManager) -> dict[str, Any]:
    """Attributes with their text decoded (:func:`schema.text`), other values as stored."""
    return {k: (schema.text(v) if isinstance(v, (bytes, str)) else v) for k, v in attrs.items()}


def _node(obj: h5py.HLObject) -> Node:
    attrs = tuple(sorted(obj.attrs))
    if isinstance(obj, h5py.Dataset):
        unit = obj.attrs.get("unit", obj.parent.attrs.get("unit", "") if obj.name.endswith("/data") else "")
        return Node(obj.name, True, tuple(obj.shape), obj.dtype,
                    schema.text(unit) if isinstance(unit, (bytes, str)) else str(unit), attrs)
    return Node(obj.name, False, attrs=attrs, members=len(obj))


def walk(group: h5py.Group) -> list[Node]:
    """Every group and dataset under ``group``, in the file's order (parents before children)."""
    nodes: list[Node] = []
    group.visititems(lambda _, obj: nodes.append(_node(obj)))
    return nodes


def file_tree(path: str | Path) -> list[Node]:
    """:func:`walk` of a whole HDF5 file, session or not (opened read-only, through SWMR if a writer has it)."""
    f, _ = files.open_readonly(path)
    with f, files.reading(path):
        return walk(f)


def read_rows(path: str | Path, datasets: dict[str, str], start: int, stop: int) -> dict[str, np.ndarray]:
    """Rows ``[start, stop)`` of each dataset (name -> path in the file at ``path``), the file opened
    read-only here: how a worker process reads its chunk of a shared session file."""
    f, _ = files.open_readonly(path)
    with f, files.reading(path):
        return {name: f[dataset][start:stop] for name, dataset in datasets.items()}


def dataset_unit(dataset: h5py.Dataset) -> str:
    """The unit of a dataset: its own ``unit``, else its stream group's (``time_unit`` for ``time``)."""
    own = attr_str(dataset, "unit")
    if own or "unit" not in dataset.parent.attrs:
        return own
    return attr_str(dataset.parent, "time_unit" if dataset.name.endswith("/time") else "unit")


R = TypeVar("R", bound=type)


def _damage_reported(cls: R) -> R:
    """Every public method and property of ``cls`` (whose instances have ``path``) reports what h5py raises
    for a damaged object as one :class:`~mirrorlab.core.errors.DamagedFileError` naming the file
    (:func:`files.reading`), never HDF5's text: a damaged object header or chunk is met only when read."""
    def wrap(function: Callable[..., Any]) -> Callable[..., Any]:
        @functools.wraps(function)
        def reported(self: Any, *args: Any, **kwargs: Any) -> Any:
            with files.reading(self.path):
                return function(self, *args, **kwargs)
        return reported

    for name, member in list(vars(cls).items()):
        if name.startswith("_"):
            continue
        if isinstance(member, property) and member.fget is not None:
            setattr(cls, name, property(wrap(member.fget), doc=member.__doc__))
        elif callable(member):
            setattr(cls, name, wrap(member))
    return cls


@_damage_reported
class Reader:
    """Read access to an open session ``file`` at ``path`` (``crashed``: opened through SWMR after a
    crash; ``recovered``: what was done to open it, e.g. the open flags of a killed writer cleared);
    a damaged object raises :class:`~mirrorlab.core.errors.DamagedFileError` when read."""

    def __init__(self, path: Path, file: h5py.File, crashed: bool = False, recovered: str = "") -> None:
        self.path = path
        self.file = file
        self.crashed = crashed
        self.recovered = recovered

    # -- the file's objects ------------------------------------------------------------------------
    def _get(self, path: str, kind: type | None = None) -> Any:
        """The object at ``path`` (of ``kind``), or a :class:`SessionError` naming what is missing."""
        key = path.strip("/")
        obj = self.file if not key else self.file[key] if key in self.file else None
        if obj is None or (kind is not None and not isinstance(obj, kind)):
            what = "dataset " if kind is h5py.Dataset else "group " if kind is h5py.Group else ""
            raise SessionError(f"no {what}/{key} in {self.path}; `mirrorlab session tree {self.path}` lists them")
        return obj

    def _fresh(self, dataset: h5py.Dataset) -> h5py.Dataset:
        if self.crashed or self.file.swmr_mode:  # a writer may have flushed more since it was opened
            dataset.refresh()
        return dataset

    def exists(self, path: str) -> bool:
        """Whether the file holds a group or dataset at ``path``."""
        key = path.strip("/")
        return not key or key in self.file

    def node(self, path: str) -> Node:
        """What is at ``path``: group or dataset, shape, dtype, unit, attribute names."""
        return _node(self._get(path))

    def members(self, path: str = "/") -> list[str]:
        """The names of the members of the group at ``path`` (none if ``path`` is no group)."""
        key = path.strip("/")
        obj = self.file.get(key) if key else self.file
        return list(obj) if isinstance(obj, h5py.Group) else []

    def tree(self, path: str = "/") -> list[Node]:
        """Every group and dataset under the group at ``path``, parents before children."""
        return walk(self._get(path, h5py.Group))

    def read(self, path: str, index: Any = ()) -> Any:
        """The values of the dataset at ``path`` as numpy gives them: an array, or a scalar dataset's
        value (a number, or bytes for text). ``index`` reads a part, e.g. frame ``5`` of a stream's
        ``data`` or rows ``slice(0, 10)``."""
        return self._fresh(self._get(path, h5py.Dataset))[index]

    def read_group(self, path: str) -> dict[str, Any]:
        """Every dataset under the group at ``path``, read, by its path relative to it (``markers/positions``)."""
        group = self._get(path, h5py.Group)
        found: dict[str, Any] = {}
        group.visititems(lambda name, obj: found.__setitem__(name, self._fresh(obj)[()])
                         if isinstance(obj, h5py.Dataset) else None)
        return found

    def truth(self, name: str) -> dict[str, Any]:
        """The ground truth a simulator wrote under ``/truth/<name>``: :meth:`read_group` of it."""
        if not self.exists(f"truth/{name}"):
            raise SessionError(f"no /truth/{name} in {self.path}; the truth groups here: "
                               f"{', '.join(self.members('truth')) or 'none'} (simulated instruments write them)")
        return self.read_group(f"truth/{name}")

    def attributes(self, path: str = "/") -> dict[str, Any]:
        """The attributes of the group or dataset at ``path``: text decoded, other values as stored
        (JSON text too: :meth:`json_attribute` decodes it)."""
        return _decoded(self._get(path).attrs)

    def json_attribute(self, path: str, name: str, default: Any = None) -> Any:
        """Attribute ``name`` of ``path`` decoded from JSON (how settings, labels and provenance are
        stored), or ``default`` if it is absent."""
        return get_json(self._get(path), name, default)

    def unit_of(self, path: str) -> str:
        """The unit of the dataset at ``path`` (its own, or its stream's; see :func:`dataset_unit`)."""
        return dataset_unit(self._get(path, h5py.Dataset))

    def stored_array(self, path: str) -> StoredArray:
        """The dataset at ``path``, read on demand (see :class:`StoredArray`)."""
        return StoredArray(self._get(path, h5py.Dataset))

    # -- the session's parts -----------------------------------------------------------------------
    @property
    def status(self) -> str:
        return attr_str(self.file, "status")

    @property
    def session_id(self) -> str:
        return attr_str(self.file, "session_id")

    @property
    def attrs(self) -> dict[str, Any]:
        """The root attributes, numbers as Python numbers."""
        return {k: v.item() if hasattr(v, "item") else v for k, v in _decoded(self.file.attrs).items()}

    def results(self, algorithm: str | None = None) -> list[ResultRef]:
        """Stored runs, oldest first (of one algorithm, or all); a run without status is ``incomplete``."""
        out = []
        for name, group in files.members(self.file, "results"):
            if algorithm is not None and name != algorithm:
                continue
            for run_id, g in files.members(group):
                out.append(ResultRef(name, run_id, run_status(g), attr_str(g, "error"), attr_str(g, "label")))
        return out

    def result(self, ref: ResultRef | str) -> ResultData:
        """Read one stored run (by :class:`ResultRef` or path ``/results/<alg>/<run-id>``)."""
        path = ref.path if isinstance(ref, ResultRef) else ref
        if path.strip("/") not in self.file:
            raise SessionError(f"no result {path} in {self.path}")
        g = self.file[path]
        attrs = _decoded(g.attrs)
        for key in ("parameters", "inputs", "input_sha256"):
            attrs[key] = get_json(g, key, {})
        attrs["status"] = run_status(g)
        parts = path.strip("/").split("/")
        ref = ResultRef(parts[1], parts[2], attrs["status"], attrs.get("error", ""), attrs.get("label", ""))
        return ResultData(ref, {k: g[k][()] for k in g}, attrs)

    def stream(self, source: str, stream: str) -> StreamData:
        """A recorded stream of an instrument or a controller (times in session seconds); usable as
        ``times, data = ...``. ``data`` and ``time`` are cut to their common length (a crash may
        leave one longer)."""
        key = next((k for k in (f"instruments/{source}/{stream}", f"controllers/{source}/{stream}") if k in self.file),
                   None)
        if key is None:
            raise SessionError(f"no stream {source}/{stream} in {self.path}; "
                               "`mirrorlab session info FILE` lists the streams")
        g = self.file[key]
        data, time = self._fresh(g["data"]), self._fresh(g["time"])
        n = min(data.shape[0], time.shape[0])
        return StreamData(time[:n], data[:n], attr_str(g, "unit"), _decoded(g.attrs))

    def describe(self) -> dict[str, Any]:
        """JSON-ready summary: attributes, instruments and controllers with their streams, results, log size."""
        instruments = {label: {"plugin": attr_str(g, "plugin"), "version": attr_str(g, "version"),
                               "settings": get_json(g, "settings", {}),
                               "identity": get_json(g, "identity", {}), "streams": _streams(g)}
                       for label, g in files.members(self.file, "instruments")}
        controllers = {label: {"plugin": attr_str(g, "plugin"), "version": attr_str(g, "version"),
                               "settings": get_json(g, "settings", {}),
                               "inputs": get_json(g, "inputs", {}),
                               "instruments": get_json(g, "instruments", {}), "streams": _streams(g)}
                       for label, g in files.members(self.file, "controllers")}
        return {"path": str(self.path), "attributes": self.attrs, "crashed": self.crashed, "recovered": self.recovered,
                "writer": files.live_writer(self.path) if self.crashed else None,
                "instruments": instruments, "controllers": controllers, "groups": self._other_groups(),
                "results": [{"path": r.path, "status": r.status, "error": r.error, "label": r.label,
                             "outputs": {name: {"shape": list(ds.shape), "dtype": str(ds.dtype),
                                                "unit": attr_str(ds, "unit")}
                                         for name, ds in files.members(self.file, r.path)}}
                            for r in self.results()],
                "log_events": int(self.file["log"].shape[0]) if "log" in self.file else 0}

    def _other_groups(self) -> dict[str, dict[str, Any]]:
        """What sits outside config, instruments, results and log (/calibration, /truth, /report,
        /markers...): a top-level group that holds datasets, else each of its groups, with their
        numbers of datasets and groups and their ``description``."""
        summary = {}
        for name, top in files.members(self.file):
            if name in ("config", "instruments", "controllers", "results") or not isinstance(top, h5py.Group):
                continue
            children = files.members(top)
            holds_data = any(isinstance(obj, h5py.Dataset) for _, obj in children)
            parts = [(f"/{name}", top)] if holds_data else [(f"/{name}/{k}", g) for k, g in children]
            for path, g in parts:
                kinds = [isinstance(obj, h5py.Group) for _, obj in files.members(g)]
                summary[path] = {"datasets": kinds.count(False), "groups": kinds.count(True),
                                 "description": attr_str(g, "description")}
        return summary

    def log(self) -> list[dict[str, Any]]:
        """The stored structured events."""
        return schema.read_log(self.file)


def _streams(g: h5py.Group) -> dict[str, dict[str, Any]]:
    return {name: {"samples": int(min(sg["data"].shape[0], sg["time"].shape[0])),
                   "shape": list(sg["data"].shape[1:]), "dtype": str(sg["data"].dtype),
                   "unit": attr_str(sg, "unit")}
            for name, sg in files.members(g) if isinstance(sg, h5py.Group) and "data" in sg}
