"""SHA-256 hash lists of arrays: the input digests stored with every result run (``@input_sha256``).

An array's digest is the SHA-256 of the SHA-256 digests of its consecutive *blocks* of
:func:`block_rows` first-axis rows (the last block may be shorter), in order: a hash list. The
block length depends only on the array's dtype and row shape, so the digest is a function of the
values alone; but the blocks can be hashed apart, by whichever process already holds their rows
(the workers of a chunked run, :mod:`mirrorlab.core.batch.executors`), and combined in frame
order. A 0-d array is one row; an empty array has no blocks.

Pure functions; a dataset of a session file (any array-like that is not a numpy array, such as a
:class:`~mirrorlab.core.store.reader.StoredArray`) is read about :data:`READ_BYTES` at a time.
"""

from __future__ import annotations

import hashlib
from collections.abc import Iterable, Mapping
from typing import Any

import numpy as np

__all__ = ["BLOCK_BYTES", "READ_BYTES", "block_rows", "block_digests", "combine", "array_digest", "input_entry",
           "read_hashed"]

#: Bytes of rows per hashed block (at least one row): image rows are blocks of their own, so frames
#: can be cut into chunks anywhere; small rows are grouped so that hashing costs no more than reading.
BLOCK_BYTES = 64 * 2**10
#: Bytes of a dataset read at a time to hash it: memory stays bounded for a recording of any length.
READ_BYTES = 64 * 2**20


def block_rows(dtype: np.dtype, shape: tuple[int, ...]) -> int:
    """First-axis rows per hashed block of an array of ``dtype`` and ``shape``.

    >>> block_rows(np.dtype("u1"), (20000, 344, 512)), block_rows(np.dtype("<f8"), (10**6,))
    (1, 8192)
    """
    row = np.dtype(dtype).itemsize * int(np.prod(shape[1:], dtype=np.int64))
    return max(1, BLOCK_BYTES // max(1, row))


def block_digests(rows: np.ndarray, per_block: int) -> list[bytes]:
    """SHA-256 digests (32 bytes each) of consecutive blocks of ``per_block`` rows of ``rows``.

    ``rows`` must begin at a block boundary of its array (row ``k * per_block``); its last block
    may be short only if it is the array's last. A 0-d array is one block.

    >>> len(block_digests(np.zeros((10, 2)), 4)), len(block_digests(np.float64(1.0), 4))
    (3, 1)
    """
    data = np.ascontiguousarray(rows).reshape(-1).view(np.uint8).data  # a memoryview of the buffer itself: no copy
    if np.ndim(rows) == 0:
        return [hashlib.sha256(data).digest()]
    step = per_block * (data.nbytes // len(rows) if len(rows) else 0)
    return [hashlib.sha256(data[start:start + step]).digest() for start in range(0, data.nbytes, step or 1)]


def combine(digests: Iterable[bytes]) -> str:
    """Hex SHA-256 of the block digests, in order: the array's digest.

    >>> combine([])
    'e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855'
    """
    return hashlib.sha256(b"".join(digests)).hexdigest()


def array_digest(array: np.ndarray | Any) -> str:
    """Hex digest of an array's values in C order (its dtype and shape are stored beside it).

    Parameters
    ----------
    array
        Any array, or a dataset: an array-like with ``dtype``, ``shape``, ``ndim`` and slicing
        (read in whole blocks, about :data:`READ_BYTES` at a time).

    Examples
    --------
    Frames of 256 x 256 bytes are blocks of one frame: hashed in two pieces, they give the digest.

    >>> a = np.arange(6 * 256 * 256, dtype=np.uint8).reshape(6, 256, 256)
    >>> array_digest(a) == combine(block_digests(a[:4], 1) + block_digests(a[4:], 1))
    True
    """
    per_block = block_rows(array.dtype, array.shape)
    if isinstance(array, np.ndarray) or array.ndim == 0:
        return combine(block_digests(np.asarray(array[()]), per_block))
    row = max(1, array.dtype.itemsize * int(np.prod(array.shape[1:], dtype=np.int64)))
    step = per_block * max(1, READ_BYTES // (row * per_block))
    return combine(d for start in range(0, array.shape[0], step)
                   for d in block_digests(array[start:start + step], per_block))


def input_entry(array: np.ndarray | Any, digest: str | None = None) -> dict[str, object]:
    """The ``@input_sha256`` entry of one input: its digest (computed unless given), block length,
    dtype and shape.

    >>> input_entry(np.zeros(0))["block_rows"], input_entry(np.zeros(0))["shape"]
    (8192, [0])
    """
    return {"sha256": digest or array_digest(array), "block_rows": block_rows(array.dtype, array.shape),
            "dtype": array.dtype.str, "shape": list(array.shape)}


def read_hashed(inputs: Mapping[str, np.ndarray | Any]) -> tuple[dict[str, np.ndarray], dict[str, dict[str, object]]]:
    """Inputs with their datasets (array-likes other than numpy's) read whole, and each input's :func:`input_entry`.

    >>> arrays, entries = read_hashed({"a": np.zeros(3)})
    >>> entries["a"]["shape"], arrays["a"].tolist()
    ([3], [0.0, 0.0, 0.0])
    """
    arrays = {name: value if isinstance(value, np.ndarray) else value[()] for name, value in inputs.items()}
    return arrays, {name: input_entry(a) for name, a in arrays.items()}
