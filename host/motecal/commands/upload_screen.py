"""``motecal upload``'s screen: progress as plain lines or rich progress bars."""
from __future__ import annotations

import sys

from ..upload.link import NullProgress


class PlainProgress(NullProgress):
    """Plain lines (no TTY): one per message and one per event."""

    def __init__(self, out=None, steps: bool = True):
        self.out = out or sys.stdout
        self.steps = steps

    def note(self, text: str) -> None:
        print(text, file=self.out, flush=True)

    def step(self, text: str) -> None:
        if self.steps:
            self.note("  " + text)


class RichProgress(PlainProgress):
    """A progress bar per phase on a terminal (rich); events above it."""

    def __init__(self):
        from rich.console import Console
        from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn
        self.console = Console()
        self.progress = Progress(TextColumn("{task.description}"), BarColumn(),
                                 MofNCompleteColumn(), TextColumn("{task.fields[detail]}"),
                                 console=self.console, transient=False)
        self.progress.start()
        self._task = None

    def note(self, text: str) -> None:
        self.progress.console.print(text, highlight=False, markup=False)

    def task(self, name: str, total: int) -> None:
        self._task = self.progress.add_task(name, total=total, detail="")

    def step(self, text: str) -> None:
        if self._task is None:
            self.note("  " + text)
        else:
            self.progress.update(self._task, advance=1, detail=text)

    def close(self) -> None:
        self.progress.stop()


def make_progress():
    return RichProgress() if sys.stdout.isatty() else PlainProgress()
