"""Batch re-processing: one Dask task per session file, retried, then summarised.

Each task copies its input into the output folder (the input is never modified), runs the
analysis recipe on the copy (:func:`~mirrorlab.core.recipes.run_analysis`) with an
:class:`~mirrorlab.core.batch.executors.Executor` that notes the scheduler and worker count in
every result's provenance, and returns its key figures. What the recipe prints (a report) goes to
``<copy>.txt`` beside the copy. A task that raises is retried by Dask (``retries``), afterwards
the file is reported as failed with its error while the others go on.
"""

from __future__ import annotations

import csv
import shutil
import time
from collections.abc import Callable, Mapping, Sequence
from contextlib import redirect_stdout
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ..errors import MirrorlabError, Problem, SessionExistsError, ValidationError
from ..recipes import check_outputs, load_recipe, run_analysis
from ..session import Session
from .executors import Executor

if TYPE_CHECKING:
    from distributed import Client

SUMMARY_NAME = "batch-summary.csv"


@dataclass
class FileResult:
    """The outcome of one input: ``status`` ``ok`` or ``failed``, wall time (s), key figures."""

    source: Path
    output: Path
    status: str
    seconds: float = float("nan")
    error: str = ""
    figures: dict[str, float] = field(default_factory=dict)


class BatchError(MirrorlabError):
    """Some files of a batch failed (each one's error is in the summary)."""


class BatchFileError(MirrorlabError):
    """One input failed in its batch task (kept picklable for Dask: message and seconds)."""

    def __init__(self, message: str, seconds: float) -> None:
        super().__init__(message, seconds)
        self.seconds = seconds

    def __str__(self) -> str:
        return str(self.args[0])


def key_figures(path: Path) -> dict[str, float]:
    """Results ok / failed, and the numeric scalar attributes of ``/report`` (e.g. ``calibration_rms_mm``)."""
    with Session.open(path) as s:
        refs = s.results()
        figures = {"results_ok": float(sum(r.status == "ok" for r in refs)),
                   "results_failed": float(sum(r.status != "ok" for r in refs))}
        if s.exists("/report") and not s.node("/report").is_dataset:
            for key, value in s.attributes("/report").items():
                if np.ndim(value) == 0 and isinstance(value, (int, float, np.integer, np.floating)) \
                        and not isinstance(value, (bool, np.bool_)):
                    figures[key] = float(value)
    return figures


def process_file(recipe: str, overrides: Sequence[str], source: str, output: str,
                 provenance: Mapping[str, Any]) -> FileResult:
    """One batch task: copy ``source`` to ``output``, run the analysis recipe there, return its figures.

    Raises :class:`BatchFileError` (so that Dask retries) with the first error met.
    """
    start = time.perf_counter()
    out = Path(output)
    try:
        with Session.open(source):  # not a session: the error names the input, not its copy
            pass
        shutil.copyfile(source, out)  # a retry starts again from the untouched input
        plan = load_recipe(recipe, overrides, analysis=True)
        with out.with_suffix(".txt").open("w") as log, redirect_stdout(log):
            run_analysis(plan, out, executor=Executor(provenance))
        figures = key_figures(out)
    except Exception as exc:
        message = str(exc) if isinstance(exc, MirrorlabError) else f"{type(exc).__name__}: {exc}"
        raise BatchFileError(message, time.perf_counter() - start) from None
    return FileResult(Path(source), out, "ok", time.perf_counter() - start, figures=figures)


def plan_outputs(inputs: Sequence[Path], out_dir: Path, overwrite: bool = False) -> list[Path]:
    """Where each input's copy goes: ``out_dir/<name>``; names must differ and never be the input itself."""
    problems: list[Problem] = []
    seen: dict[str, Path] = {}
    outputs = [out_dir / p.name for p in inputs]
    for source, target in zip(inputs, outputs):
        if target.name in seen:
            problems.append(Problem(str(source), f"has the same name as {seen[target.name]}; their copies "
                                    f"would collide in {out_dir}: rename one"))
        seen[target.name] = source
        if target.exists() and target.resolve() == source.resolve():
            problems.append(Problem(str(source), f"is already in {out_dir}; give another --out (inputs are "
                                    "never modified)"))
    if problems:
        raise ValidationError(problems)
    if not overwrite:
        for target in outputs:
            if target.exists():
                raise SessionExistsError(target, "add --overwrite to replace the copies, or choose another --out")
    return outputs


def run_batch(client: Client, recipe: Path, inputs: Sequence[Path], out_dir: Path, provenance: Mapping[str, Any],
              overrides: Sequence[str] = (), retries: int = 1, overwrite: bool = False,
              on_done: Callable[[FileResult], None] | None = None) -> list[FileResult]:
    """Run ``recipe`` on a copy of every input as Dask tasks; results in input order.

    The recipe is validated here first (a bad recipe fails before anything is copied).
    ``on_done`` is called as each file finishes, in completion order.
    """
    from distributed import as_completed

    plan = load_recipe(recipe, overrides, analysis=True)
    out_dir.mkdir(parents=True, exist_ok=True)
    outputs = plan_outputs(inputs, out_dir, overwrite)
    for output in outputs[:1]:  # every copy is in out_dir: what the recipe writes must be there or beside it
        check_outputs(plan, output, overwrite)
    futures = {client.submit(process_file, str(recipe.resolve()), list(overrides), str(src.resolve()),
                             str(dst.resolve()), dict(provenance), retries=retries, pure=False): i
               for i, (src, dst) in enumerate(zip(inputs, outputs))}
    results: list[FileResult | None] = [None] * len(inputs)
    for future in as_completed(futures):
        i = futures[future]
        if future.status == "finished":
            result = future.result()
        else:
            exc = future.exception()
            result = FileResult(inputs[i], outputs[i], "failed", getattr(exc, "seconds", float("nan")),
                                str(exc) or type(exc).__name__)
        result.source = inputs[i]
        results[i] = result
        if on_done is not None:
            on_done(result)
    return [r for r in results if r is not None]


def write_summary(results: Sequence[FileResult], path: Path) -> None:
    """The summary as CSV: file, status, seconds, output, each key figure, error."""
    names = sorted({k for r in results for k in r.figures})
    with path.open("w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(["file", "status", "seconds", "output", *names, "error"])
        for r in results:
            writer.writerow([str(r.source), r.status, f"{r.seconds:.3f}", str(r.output),
                             *(f"{r.figures[k]:.6g}" if k in r.figures else "" for k in names), r.error])
