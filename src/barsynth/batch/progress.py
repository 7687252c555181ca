"""A batch's progress on a terminal: a bar with items done, items per second and the time left (rich).

Shown only when the stream is a terminal; its ETA counts only the items rendered in this run
(items a resume keeps are already done when the bar starts). rich rather than our own line
(models' ``_Progress`` in cli.py): its speed estimate and ETA over a sliding window are what a
batch of hours needs.
"""

from __future__ import annotations

import sys
from typing import Any

__all__ = ["BatchProgress"]


class BatchProgress:
    """``with BatchProgress() as progress: run_batch(..., progress=progress)``: a live bar on a
    terminal (``terminal`` forces it either way), nothing elsewhere."""

    def __init__(self, stream: Any = None, *, terminal: bool | None = None, label: str = "rendering"):
        from rich.console import Console

        self.console = Console(file=sys.stderr if stream is None else stream,
                               force_terminal=terminal, highlight=False)
        self.on = self.console.is_terminal if terminal is None else terminal
        self.label = label
        self.bar: Any = None
        self.task: Any = None

    def __enter__(self) -> BatchProgress:
        if self.on:
            from rich.progress import (
                BarColumn,
                MofNCompleteColumn,
                Progress,
                TextColumn,
                TimeElapsedColumn,
                TimeRemainingColumn,
            )

            self.bar = Progress(TextColumn("barsynth: {task.description}"), BarColumn(), MofNCompleteColumn(),
                                TextColumn("{task.fields[rate]}"), TimeElapsedColumn(), TextColumn("left"),
                                TimeRemainingColumn(), console=self.console, transient=True)
            self.bar.__enter__()
        return self

    def __call__(self, done: int, total: int) -> None:
        """``done`` of ``total`` items finished (run_batch's ``progress``)."""
        if self.bar is None:
            return
        if self.task is None:  # the first call: the items kept by a resume are done already
            self.task = self.bar.add_task(self.label, total=total, completed=done, rate="")
            self.first = done
            return
        task = self.bar.tasks[0]
        rendered = done - self.first
        rate = f"{rendered / task.elapsed:.2f} items/s" if task.elapsed and rendered else ""
        self.bar.update(self.task, completed=done, total=total, rate=rate)

    def __exit__(self, *exc: Any) -> None:
        if self.bar is not None:
            self.bar.__exit__(*exc)
