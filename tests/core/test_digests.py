"""Input digests (hash lists over blocks of rows) against a reference written from the documented
definition, for arrays of any dtype and shape, read whole, read from a dataset in pieces, or hashed
in chunks by different processes."""

from __future__ import annotations

import hashlib
from pathlib import Path

import h5py
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp
from mirrorlab.core import digests
from mirrorlab.core.batch.chunks import chunk_bounds


def reference(a: np.ndarray) -> str:
    """docs/session-format.md: SHA-256 of the SHA-256 digests of consecutive blocks of
    max(1, 65536 // row bytes) first-axis rows in C order; a 0-d array is one block."""
    data = np.ascontiguousarray(a).tobytes()
    if a.ndim == 0:
        return hashlib.sha256(hashlib.sha256(data).digest()).hexdigest()
    row = a.dtype.itemsize * int(np.prod(a.shape[1:]))
    size = max(1, 65536 // max(1, row)) * row
    blocks = [data[i:i + size] for i in range(0, len(data), size)] if size else []
    return hashlib.sha256(b"".join(hashlib.sha256(b).digest() for b in blocks)).hexdigest()


arrays = hnp.arrays(dtype=st.sampled_from([np.uint8, np.int16, np.float32, np.float64, np.bool_]),
                    shape=hnp.array_shapes(min_dims=0, max_dims=3, min_side=0, max_side=300))


@settings(max_examples=60, deadline=None)
@given(arrays)
def test_digest_is_the_documented_hash_list(a: np.ndarray) -> None:
    assert digests.array_digest(a) == reference(a)
    if a.ndim:  # strided views hash as their values in C order
        assert digests.array_digest(a[::-1]) == reference(a[::-1].copy())


@settings(max_examples=30, deadline=None)
@given(a=hnp.arrays(np.float64, st.tuples(st.integers(0, 3000), st.integers(1, 40))), chunk=st.integers(1, 9))
def test_blocks_hashed_apart_combine_to_the_digest(a: np.ndarray, chunk: int) -> None:
    """Chunks of whole blocks, hashed separately (as a chunked run's workers do), joined in order."""
    rows = digests.block_rows(a.dtype, a.shape)
    parts = [digests.block_digests(a[start:stop], rows) for start, stop in chunk_bounds(len(a), chunk * rows)]
    assert digests.combine(d for part in parts for d in part) == digests.array_digest(a)


@pytest.mark.parametrize("shape", [(1000, 3), (37, 344, 512), (5, 0), ()])
def test_a_dataset_read_in_pieces_has_the_arrays_digest(tmp_path: Path, shape: tuple[int, ...],
                                                        monkeypatch: pytest.MonkeyPatch) -> None:
    rng = np.random.default_rng(1)
    a = rng.integers(0, 255, shape).astype(np.uint8 if len(shape) == 3 else np.float64)
    monkeypatch.setattr(digests, "READ_BYTES", 200_000)  # a frame per read, or 8192 rows of 3 values
    with h5py.File(tmp_path / "a.h5", "w") as f:
        f["a"] = a
        assert digests.array_digest(f["a"]) == digests.array_digest(a) == reference(a)
        assert digests.input_entry(f["a"]) == {"sha256": reference(a), "dtype": a.dtype.str, "shape": list(shape),
                                               "block_rows": digests.block_rows(a.dtype, shape)}
