"""The CLI's terminal output: a rich progress bar behind the pipeline's
``progress(stage, fraction)`` callback, and the console results are printed on.

The bar goes to stderr (results go to stdout) and disappears when done. It is off with
``--quiet`` and when stderr is not a terminal; then stage changes are only logged (``-v``).
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Iterator
from contextlib import contextmanager

from rich.console import Console
from rich.progress import (
    BarColumn,
    Progress,
    SpinnerColumn,
    TaskProgressColumn,
    TextColumn,
    TimeElapsedColumn,
)

__all__ = ["ProgressCallback", "progress_reporter", "result_console"]

log = logging.getLogger(__name__)

ProgressCallback = Callable[[str, float | None], None]


def result_console() -> Console:
    """The console results go to (stdout): no markup or highlighting (paths and formulas
    print as they are), and long lines are not wrapped, so a written file's path can be
    copied or parsed from the output whatever the terminal's width (rich wraps at 80
    columns when stdout is not a terminal)."""
    return Console(highlight=False, markup=False, soft_wrap=True)


def _logging_callback(label: str) -> ProgressCallback:
    last: list[str] = []

    def callback(stage: str, fraction: float | None) -> None:
        if not last or last[0] != stage:
            last[:] = [stage]
            log.info("%s: %s", label, stage)

    return callback


@contextmanager
def progress_reporter(*, quiet: bool = False, label: str = "") -> Iterator[ProgressCallback | None]:
    """Yield a ``progress(stage, fraction)`` callback (``None`` when ``quiet``).

    ``fraction`` in [0, 1] shows a bar; ``None`` means "working, extent unknown" (a pulse).
    """
    if quiet:
        yield None
        return
    console = Console(stderr=True)
    if not console.is_terminal:
        yield _logging_callback(label)
        return
    columns = (SpinnerColumn(), TextColumn("{task.description}", markup=False), BarColumn(),
               TaskProgressColumn(), TimeElapsedColumn())
    with Progress(*columns, console=console, transient=True) as bar:
        task = bar.add_task(label, total=None)
        stage_now: list[str] = []

        def callback(stage: str, fraction: float | None) -> None:
            if not stage_now or stage_now[0] != stage:
                stage_now[:] = [stage]
                log.info("%s: %s", label, stage)
                bar.reset(task, description=f"{label}: {stage}" if label else stage, total=None)
            if fraction is not None:
                bar.update(task, total=1.0, completed=min(max(float(fraction), 0.0), 1.0))

        yield callback
