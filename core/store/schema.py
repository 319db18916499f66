"""Session file schema v2 (reads v1): names, attribute helpers, stream and log datasets.

See ``docs/session-format.md`` for the full description. All functions here take open
:class:`h5py.File` / :class:`h5py.Group` objects and do no I/O policy of their own.
"""

from __future__ import annotations

import json
from typing import Any

import h5py
import numpy as np

from ..events import Event
from ..streams import StreamSpec

#: Schema 2 (over 1): root ``clock_origin_utc``, ``/controllers``, result runs with ``status``
#: written last, ``label``, ``input_sha256`` and ``unit``/``description`` on every output.
SCHEMA_VERSION = 2
#: HDF5 format bounds: SWMR needs at least the 1.10 format; capping it there keeps session files
#: readable by HDF5 1.10 tools (Debian's h5dump) and by every h5py since 2.10.
LIBVER = ("v110", "v110")
STATUSES = ("open", "closed", "aborted")
ROOT_ATTRS = ("mirrorlab_schema", "mirrorlab_version", "session_id", "created_utc", "operator",
              "description", "status", "clock_origin_utc")
#: Root attributes that schema 1 files lack.
NEW_IN_2 = ("clock_origin_utc",)
#: Top-level groups every session file has from its creation (``/log`` is a dataset).
GROUPS = ("config", "instruments", "controllers", "calibration", "results", "truth")
#: Top-level groups the built-in plugins' steps add when they run (documented in session-format.md).
PLUGIN_GROUPS = {
    "markers": "kinematics `import_markers`: /markers/<name> marker sets",
    "report": "pipeline `report` (/report, /report-2, ...) and mechanisms steps (/report/<name>): summaries",
    "retarget": "retarget `retarget` step: /retarget/<name> retargeted motions",
}
#: ``status`` of a stored algorithm run. It is written after everything else of the run.
RUN_STATUSES = ("ok", "failed", "cancelled")
#: What readers report for a run group without ``status``: its writing was interrupted.
INCOMPLETE = "incomplete"

#: One row of ``/log``. Fixed-size fields: SWMR cannot grow variable-length data safely.
LOG_DTYPE = np.dtype([
    ("t", "f8"),
    ("level", "S8"),
    ("source", "S64"),
    ("kind", "S32"),
    ("message", "S512"),
    ("data", "S1024"),
])

STR = h5py.string_dtype("utf-8")


def set_json(obj: h5py.HLObject, name: str, value: Any) -> None:
    """Store ``value`` as a JSON string attribute."""
    obj.attrs[name] = json.dumps(value, default=str, sort_keys=True)


def get_json(obj: h5py.HLObject, name: str, default: Any = None) -> Any:
    raw = obj.attrs.get(name)
    if raw is None:
        return default
    return json.loads(raw.decode() if isinstance(raw, bytes) else raw)


def text(raw: bytes | str) -> str:
    """An attribute's text: UTF-8, with U+FFFD for bytes that are not UTF-8.

    A name written by another tool in Latin-1 is shown, not taken for damage. h5py gives such bytes
    of a variable-length string as lone surrogates (``surrogateescape``), which would reach a
    terminal as the same invalid bytes; they are replaced as well.
    """
    if isinstance(raw, str):
        raw = raw.encode("utf-8", "surrogateescape")
    return raw.decode("utf-8", "replace")


def attr_str(obj: h5py.HLObject, name: str, default: str = "") -> str:
    raw = obj.attrs.get(name, default)
    return text(raw) if isinstance(raw, (bytes, str)) else str(raw)


def required_root_attrs(version: int | None) -> tuple[str, ...]:
    """The root attributes a file of schema ``version`` must have (``None``: the current schema)."""
    if version is not None and version < 2:
        return tuple(a for a in ROOT_ATTRS if a not in NEW_IN_2)
    return ROOT_ATTRS


def run_status(run: h5py.Group) -> str:
    """``status`` of a stored algorithm run, or :data:`INCOMPLETE` if it was never written."""
    return attr_str(run, "status", INCOMPLETE)


def create_stream(group: h5py.Group, spec: StreamSpec) -> h5py.Group:
    """Create (or check) ``<group>/<stream>/{data,time}``: chunked, resizable along time."""
    if spec.name in group:
        g = group[spec.name]
        have = (g["data"].dtype, g["data"].shape[1:])
        want = (np.dtype(spec.dtype), tuple(spec.shape))
        if have != want:
            raise ValueError(f"stream {group.name}/{spec.name} exists with dtype/shape {have}, "
                             f"the instrument now declares {want}; record into a new session")
        return g
    g = group.create_group(spec.name)
    chunk = spec.chunk_samples()
    # Fletcher-32 checksums per chunk: a bit changed on disk or in a copy fails the read instead of
    # being exported (``mirrorlab session check --data`` reads them all)
    g.create_dataset("data", shape=(0, *spec.shape), maxshape=(None, *spec.shape), dtype=spec.dtype,
                     chunks=(chunk, *spec.shape), fletcher32=True)
    g.create_dataset("time", shape=(0,), maxshape=(None,), dtype="f8", chunks=(max(chunk, 1024),), fletcher32=True)
    g.attrs["unit"] = spec.unit
    g.attrs["time_unit"] = "s"
    g.attrs["rate"] = float(spec.rate) if spec.rate else np.nan
    g.attrs["description"] = spec.description
    return g


def append(ds: h5py.Dataset, values: np.ndarray) -> None:
    """Append ``values`` along axis 0 of a resizable dataset."""
    n = len(values)
    if n == 0:
        return
    old = ds.shape[0]
    ds.resize(old + n, axis=0)
    ds[old:old + n] = values


def create_log(f: h5py.File) -> h5py.Dataset:
    if "log" in f:
        return f["log"]
    return f.create_dataset("log", shape=(0,), maxshape=(None,), dtype=LOG_DTYPE, chunks=(256,))


def _clip(text: str, size: int) -> bytes:
    raw = text.encode("utf-8")
    if len(raw) <= size:
        return raw
    return raw[:size - 3].decode("utf-8", errors="ignore").encode("utf-8") + b"..."


def log_rows(events: list[Event]) -> np.ndarray:
    rows = np.zeros(len(events), dtype=LOG_DTYPE)
    for i, e in enumerate(events):
        rows[i] = (e.t, e.level.encode(), _clip(e.source, 64), _clip(e.kind, 32), _clip(e.message, 512),
                   _clip(e.data_json(), 1024))
    return rows


def read_log(f: h5py.File) -> list[dict[str, Any]]:
    if "log" not in f:
        return []
    return [{"t": float(r["t"]), "level": r["level"].decode(), "source": r["source"].decode(),
             "kind": r["kind"].decode(), "message": r["message"].decode("utf-8", "replace"),
             "data": _loads(r["data"].decode("utf-8", "replace"))} for r in f["log"][()]]


def _loads(text: str) -> Any:
    try:
        return json.loads(text or "{}")
    except json.JSONDecodeError:  # clipped to the field size
        return {"truncated": text}
