"""Finding damage in a session file: objects that cannot be read, stream chunks whose checksums do not
match, instruments that failed while recording.

:func:`mirrorlab.core.store.files.check` calls these after its structural checks. Opening a file reads
only its superblock and root group, so a damaged object header (of ``/log``, ``/config/recipe``, a
controller's group...) or damaged raw data goes unnoticed until something reads it: :func:`first_unreadable`
reads every group and attribute and the first and last element of every dataset, and
:func:`checksum_failures` reads every chunk of the datasets written with HDF5's Fletcher-32 filter
(recorded streams: :func:`mirrorlab.core.store.schema.create_stream`), so that a changed bit in the raw
data is reported instead of being exported.
"""

from __future__ import annotations

from typing import Any

import h5py

#: What h5py raises while reading a damaged file: OSError / RuntimeError from the library, KeyError
#: for an object it cannot open, ValueError (UnicodeDecodeError, JSONDecodeError) for garbled text.
READ_ERRORS = (OSError, RuntimeError, KeyError, ValueError)

#: Log kinds an instrument reports when it stops for good (core/devices/instrument.py).
FAILURE_KINDS = ("failed", "stop_timeout")


def _read_attributes(obj: h5py.HLObject) -> None:
    for name in obj.attrs:
        obj.attrs[name]


def _read_ends(ds: h5py.Dataset) -> None:
    """The first and last element (so the first and last chunk) of a dataset, or its whole value."""
    if ds.shape is None:        # an empty (null) dataset holds no value
        return
    if ds.ndim == 0:
        ds[()]
    elif ds.shape[0] > 0:
        ds[0]
        ds[-1]


def first_unreadable(f: h5py.File) -> str | None:
    """Path and reason of the first object of ``f`` (depth first, in name order) that cannot be read,
    or ``None`` if every group, attribute and dataset end reads.

    Examples
    --------
    >>> import io, numpy as np
    >>> with h5py.File(io.BytesIO(), "w") as f:
    ...     _ = f.create_dataset("a/b", data=np.arange(3))
    ...     first_unreadable(f) is None
    True
    """
    def visit(group: h5py.Group) -> str | None:
        try:
            _read_attributes(group)
            names = sorted(group)
        except READ_ERRORS as exc:
            return f"{group.name}: {exc}"
        for name in names:
            path = f"{group.name.rstrip('/')}/{name}"
            try:
                obj = group[name]
                _read_attributes(obj)
                if isinstance(obj, h5py.Dataset):
                    _read_ends(obj)
            except READ_ERRORS as exc:
                return f"{path}: {exc}"
            if isinstance(obj, h5py.Group):
                found = visit(obj)
                if found:
                    return found
        return None

    return visit(f)


def _checksummed(f: h5py.File) -> list[h5py.Dataset]:
    found: list[h5py.Dataset] = []
    f.visititems(lambda _, obj: found.append(obj) if isinstance(obj, h5py.Dataset) and obj.fletcher32 else None)
    return found


def has_checksums(f: h5py.File) -> bool:
    """Whether any dataset of ``f`` carries Fletcher-32 checksums (files written before they were added do not)."""
    return bool(_checksummed(f))


def checksum_failures(f: h5py.File) -> list[str]:
    """Every dataset written with Fletcher-32 checksums whose chunks do not all read back: one line each
    naming the dataset and the first bad chunk's samples (0-based, end exclusive)."""
    found: list[str] = []
    for ds in _checksummed(f):
        if ds.shape is None or 0 in ds.shape:
            continue
        for chunk in ds.iter_chunks():
            try:
                ds[chunk]
            except READ_ERRORS:
                rows = chunk[0]
                found.append(f"{ds.name}: samples {rows.start}-{rows.stop} do not match their checksum (changed "
                             "since they were written: the disk or a copy damaged them)")
                break
    return found


def instrument_failures(log: list[dict[str, Any]]) -> list[str]:
    """One line per instrument that stopped for good during the session, from the session's ``/log``
    entries (:func:`~mirrorlab.core.store.schema.read_log`): its ``failed`` or ``stop_timeout`` error, with
    the session time (s) and the reason."""
    return [f"instrument {e['source']} failed at {e['t']:.3f} s: {e['message']} (its streams end there)"
            for e in log if e["level"] == "error" and e["kind"] in FAILURE_KINDS]
