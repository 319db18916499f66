"""A rich progress bar on stderr driven by a session's progress events."""

from __future__ import annotations

import contextlib
import sys
from collections.abc import Iterator
from typing import Any

from rich.console import Console
from rich.progress import BarColumn, Progress, TaskID, TextColumn, TimeElapsedColumn

from ..events import Event


@contextlib.contextmanager
def progress_bar(enabled: bool = True) -> Iterator[Any]:
    """Yield a subscriber for :class:`~mirrorlab.core.events.EventBus` that draws progress bars.

    Warnings and errors are printed above the bars, except failed algorithm runs (the command
    raises those as its error, printed once). Disabled (``enabled=False`` or stderr not
    a terminal) it prints only warnings and errors.
    """
    console = Console(stderr=True)
    show = enabled and sys.stderr.isatty()
    bars = Progress(TextColumn("{task.description:<12}"), BarColumn(), TextColumn("{task.percentage:>5.1f}%"),
                    TimeElapsedColumn(), console=console, disable=not show, transient=False)
    tasks: dict[str, TaskID] = {}

    def on_event(event: Event) -> None:
        if event.kind == "progress":
            total = event.data.get("total")
            if event.source not in tasks:
                tasks[event.source] = bars.add_task(event.source, total=total)
            bars.update(tasks[event.source], completed=event.data.get("done", 0), total=total)
        elif event.level in ("warning", "error") and event.kind not in ("result_written", "recorder_failed"):
            # a failed run or recording is reported by the command that asked for it (once, as its error)
            console.print(f"[{'yellow' if event.level == 'warning' else 'red'}]{event.level}[/]: "
                          f"{event.source}: {event.message}", highlight=False, soft_wrap=True)

    with bars:
        yield on_event
