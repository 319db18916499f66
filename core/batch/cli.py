"""``mirrorlab batch RECIPE INPUT... --out DIR [--workers N | --scheduler ADDRESS]``."""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn
from rich.table import Table

from ..cli.options import existing_path
from .cluster import dask_client, describe
from .options import add_cluster_options, count
from .runner import SUMMARY_NAME, BatchError, FileResult, run_batch, write_summary


def add(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("batch", help="run an analysis recipe on many session files on Dask workers",
                       description="Copy every input session into --out and run the analysis recipe on each "
                                   "copy as a Dask task (a local cluster, or a running scheduler); print a "
                                   f"summary table and write it to DIR/{SUMMARY_NAME}. Exit 1 if any file failed.")
    p.add_argument("recipe", type=existing_path, help="analysis recipe (TOML), e.g. sessions/rssr_analysis.toml")
    p.add_argument("inputs", nargs="+", type=existing_path, metavar="INPUT", help="session files (.h5); never modified")
    p.add_argument("--out", type=Path, required=True, metavar="DIR", help="folder for the processed copies")
    add_cluster_options(p)
    p.add_argument("--retries", type=count, default=1, metavar="N", help="retries of a failed file (default 1)")
    p.add_argument("--overwrite", action="store_true", help="replace copies already in --out")
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                   help="override a recipe value, e.g. steps.1.parameters.method=thesis (repeatable)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    stderr = Console(stderr=True)
    bar = Progress(TextColumn("batch"), BarColumn(), MofNCompleteColumn(), TextColumn("files"), TimeElapsedColumn(),
                   console=stderr, disable=args.no_progress or not sys.stderr.isatty())
    with dask_client(args.workers, args.scheduler) as client:
        provenance = {**describe(client), "mode": "batch"}
        with bar:
            task = bar.add_task("batch", total=len(args.inputs))

            results = run_batch(client, args.recipe, args.inputs, args.out, provenance, args.overrides,
                                args.retries, args.overwrite, lambda _: bar.advance(task))
    summary = args.out / SUMMARY_NAME
    write_summary(results, summary)
    print_table(results, provenance)
    print(f"summary: {summary}")
    failed = [r.source.name for r in results if r.status != "ok"]
    if failed:  # the table says why; the exit status and one error line say that something failed
        raise BatchError(f"{len(failed)} of {len(results)} files failed ({', '.join(failed)}); "
                         f"their errors are in the table and in {summary}")
    return 0


def print_table(results: list[FileResult], provenance: dict) -> None:
    """The summary on stdout: file, status, time, key figures (or the error)."""
    failed = sum(r.status != "ok" for r in results)
    table = Table(title=f"batch: {len(results) - failed} ok, {failed} failed, on {provenance['workers']} "
                        f"worker(s) of {provenance['scheduler']}")
    for column in ("file", "status", "time (s)", "key figures / error"):
        table.add_column(column, overflow="fold")
    for r in results:
        figures = ", ".join(f"{k} {v:.4g}" for k, v in r.figures.items()) if r.status == "ok" else r.error
        table.add_row(r.source.name, r.status, "" if math.isnan(r.seconds) else f"{r.seconds:.1f}", figures)
    Console(width=max(Console().width, 120), soft_wrap=False).print(table)
