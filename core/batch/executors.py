"""What a session runs its algorithms with (:attr:`Session.executor <mirrorlab.core.session.Session.executor>`).

:class:`Executor` runs in this process and only says where in the provenance (a batch task on a
worker). :class:`ChunkedExecutor` splits the frames of a frame-wise algorithm (detection, pairing
without continuity) into chunks run as Dask tasks; each task reads its frames from the session
file itself, read-only while the file is shared in SWMR mode, and the outputs are merged in frame
order (:func:`~mirrorlab.core.batch.chunks.merge_frames`), equal bit for bit to one run on all
frames. Everything else (tracking, anything sequential) runs in this process as before.

An executor also returns each input's digest entry for the run's provenance
(:mod:`mirrorlab.core.digests`). The workers of a chunked run hash the blocks of the frames they
read, so this process never reads a recording that its workers read.
"""

from __future__ import annotations

from collections.abc import Mapping
from concurrent.futures import ThreadPoolExecutor
from typing import TYPE_CHECKING, Any

from ..algorithms import Algorithm, InputDigests, RunContext, RunOutcome, execute
from ..digests import block_digests, block_rows, combine, input_entry, read_hashed
from ..store.reader import StoredArray, read_rows
from .chunks import chunk_bounds, merge_frames

if TYPE_CHECKING:
    from distributed import Client

    from ..session import Session

#: Frames per chunk by default: ~180 MB of 344 x 512 frames, a few seconds of detection.
CHUNK_FRAMES = 1000


class Executor:
    """Runs algorithms in this process, noting ``provenance`` (JSON-able) with every result."""

    def __init__(self, provenance: Mapping[str, Any]) -> None:
        self.provenance = dict(provenance)

    def __call__(self, session: Session, cls: type[Algorithm], inputs: Mapping[str, Any],
                 params: Mapping[str, Any], context: RunContext) -> tuple[RunOutcome, InputDigests]:
        arrays, digests = read_hashed(inputs)
        return execute(cls, arrays, params, context), digests


def run_chunk(path: str, cls: type[Algorithm], datasets: Mapping[str, str], arrays: Mapping[str, Any],
              params: Mapping[str, Any], start: int, stop: int,
              hashed: Mapping[str, int]) -> tuple[RunOutcome, dict[str, list[bytes]]]:
    """One Dask task: frames ``[start, stop)`` of ``datasets`` (paths in the session file at ``path``),
    read here read-only, plus ``arrays``, through :func:`~mirrorlab.core.algorithms.execute`.

    Also returns the block digests of the frames of each dataset in ``hashed`` (name -> rows per
    block; ``start`` is on a block boundary), hashed while they are in memory here.
    """
    frames = read_rows(path, dict(datasets), start, stop)
    blocks = {name: block_digests(frames[name], rows) for name, rows in hashed.items()}
    return execute(cls, {**arrays, **frames}, params), blocks


class ChunkedExecutor(Executor):
    """Runs frame-wise algorithms in chunks of ``chunk_frames`` frames on the workers of ``client``.

    An algorithm that is not frame-wise for its parameters, or whose frame inputs are not
    datasets of the session, or that has at most ``chunk_frames`` frames, runs in this process.
    """

    def __init__(self, client: Client, provenance: Mapping[str, Any], chunk_frames: int = CHUNK_FRAMES) -> None:
        if chunk_frames < 1:
            raise ValueError(f"chunk_frames {chunk_frames}: must be at least 1")
        super().__init__({**provenance, "chunk_frames": chunk_frames})
        self.client = client
        self.chunk_frames = chunk_frames
        #: ``(algorithm, chunks)`` of each run split into chunks, in order.
        self.chunked: list[tuple[str, int]] = []

    def __call__(self, session: Session, cls: type[Algorithm], inputs: Mapping[str, Any],
                 params: Mapping[str, Any], context: RunContext) -> tuple[RunOutcome, InputDigests]:
        values = cls.parameters.validate(dict(params), where=f"{cls.name}.parameters")
        split = [n for n in cls.frame_wise(values) if isinstance(inputs.get(n), StoredArray)]
        lengths = {inputs[n].shape[0] if inputs[n].ndim else 0 for n in split}
        frames = lengths.pop() if len(lengths) == 1 else 0  # differing lengths: the algorithm reports them
        if not split or frames <= self.chunk_frames:
            return super().__call__(session, cls, inputs, values, context)
        datasets = {n: inputs[n].path for n in split}
        arrays, digests = read_hashed({n: v for n, v in inputs.items() if n not in split})
        # Chunks that start on block boundaries are hashed by the workers that read them (image
        # rows are blocks of their own); any other frame input is hashed here meanwhile.
        rows = {n: block_rows(inputs[n].dtype, inputs[n].shape) for n in split}
        hashed = {n: r for n, r in rows.items() if self.chunk_frames % r == 0}
        bounds = chunk_bounds(frames, self.chunk_frames)
        from distributed import as_completed

        with session.shared_for_reading(), ThreadPoolExecutor(max_workers=1) as pool:
            here = pool.submit(lambda: {n: input_entry(inputs[n]) for n in split if n not in hashed})
            futures = {self.client.submit(run_chunk, str(session.path), cls, datasets, arrays, values, a, b,
                                          hashed, pure=False): (a, b) for a, b in bounds}
            done, results = 0, {}
            # each chunk's outputs are fetched when it ends, while the others still run
            for future, result in as_completed(futures, with_results=True):
                a, b = futures[future]
                results[a] = result
                done += b - a
                context.progress(done, frames, f"{cls.name}: frames in chunks")
            parts = [results[a] for a, _ in bounds]
            digests.update(here.result())
        digests.update({n: input_entry(inputs[n], combine(d for _, blocks in parts for d in blocks[n]))
                        for n in hashed})
        for (a, b), (part, _) in zip(bounds, parts):
            if part.status != "ok":
                return RunOutcome({}, values, "failed", f"frames {a}-{b - 1}: {part.error}", part.traceback), digests
        try:
            merged = merge_frames([p.outputs for p, _ in parts], cls.frame_fill)
        except ValueError as exc:
            return RunOutcome({}, values, "failed", str(exc)), digests
        self.chunked.append((cls.name, len(bounds)))
        return RunOutcome(merged, values, "ok"), digests
