"""``hetmesh sweep``: the runs of a study file on a Dask cluster (:func:`hetmesh.sweep`)."""

from __future__ import annotations

import argparse
import logging
import re
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path

from rich.console import Console

from ..errors import OutputError
from .mesh import check_writable_dir
from .progress import result_console

__all__ = ["add_parser", "run", "sweep_progress", "worker_count"]

log = logging.getLogger(__name__)


def worker_count(text: str) -> int:
    """argparse type of ``--workers`` (here and in ``hetmesh reproduce``): an integer >= 1."""
    value = int(text)
    if value < 1:
        raise ValueError(text)
    return value


worker_count.__name__ = "worker count"


def add_parser(subparsers, parents: list[argparse.ArgumentParser]) -> argparse.ArgumentParser:
    p = subparsers.add_parser(
        "sweep", parents=parents,
        help="run a study file's meshing runs on a Dask cluster (local or remote)",
        description="Run every run of a study file (a grid and/or explicit runs over models, "
                    "thresholds, methods, sampling and meshing options, optionally with FEA "
                    "probes; see docs/sweep.md) on a local Dask cluster or a running "
                    "scheduler, and write DIR/results.parquet, DIR/results.csv (one row per "
                    "run) and DIR/summary.png. A failing run is a row with its error; a run "
                    "whose worker dies is redone on another; started again over the same DIR, "
                    "a sweep redoes only the runs not found there.",
    )
    p.add_argument("study", type=Path, metavar="STUDY", help="study file (TOML)")
    where = p.add_mutually_exclusive_group()
    where.add_argument("--workers", "-j", type=worker_count, default=None, metavar="N",
                       help="worker processes of the local Dask cluster (default: one per core)")
    where.add_argument("--scheduler", metavar="ADDRESS", default=None,
                       help="address of a running Dask scheduler (tcp://host:8786) or its "
                            "scheduler file (.json), e.g. from dask-jobqueue or "
                            "dask-kubernetes; the workers need hetmesh installed, and a "
                            "shared --out if the study writes meshes")
    where.add_argument("--serial", action="store_true",
                       help="run in this process, one run after the other (no Dask)")
    p.add_argument("--out", "-o", type=Path, default=None, metavar="DIR",
                   help="output directory, created if missing (default: ./sweep-<study name>)")
    p.add_argument("--no-resume", action="store_true",
                   help="run every run again, even those found done in DIR")
    p.add_argument("--quiet", "-q", action="store_true",
                   help="no progress display and no summary; errors only")
    p.set_defaults(run=run)
    return p


@contextmanager
def sweep_progress(total: int, *, quiet: bool = False,
                   label: str = "sweep") -> Iterator[Callable | None]:
    """Yield a ``progress(Counts)`` callback showing runs done, running and failed and the
    Dask dashboard's address on a rich bar (stderr); logged instead when stderr is not a
    terminal, None when ``quiet``."""
    if quiet:
        yield None
        return
    console = Console(stderr=True)

    def text(c) -> str:
        parts = [f"{label}: {c.done}/{c.total} done", f"{c.running} running",
                 f"{c.failed} failed"]
        if c.cached:
            parts.append(f"{c.cached} found done")
        if c.dashboard:
            parts.append(f"dashboard {c.dashboard}")
        return ", ".join(parts)

    if not console.is_terminal:
        last: list = []

        def log_callback(c) -> None:
            state = (c.done, c.failed, c.dashboard)
            if state != (last[0] if last else None):
                last[:] = [state]
                log.info("%s", text(c))

        yield log_callback
        return
    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        Progress,
        SpinnerColumn,
        TextColumn,
        TimeElapsedColumn,
    )

    columns = (SpinnerColumn(), BarColumn(), MofNCompleteColumn(),
               TextColumn("{task.description}", markup=False), TimeElapsedColumn())
    with Progress(*columns, console=console, transient=True) as bar:
        task = bar.add_task(label, total=total)

        def callback(c) -> None:
            bar.update(task, completed=c.done, total=c.total, description=text(c))

        yield callback


def run(args: argparse.Namespace) -> int:
    from ..study import load_study, sweep

    study = load_study(args.study)  # a bad study fails before anything is written
    out: Path = args.out if args.out is not None else \
        Path("sweep-" + re.sub(r"[^A-Za-z0-9_.-]+", "_", study.name).strip("._"))
    if out.exists() and not out.is_dir():
        raise OutputError(f"--out {out} is not a directory")
    if out.exists():
        check_writable_dir(out, f"--out {out}")
    with sweep_progress(len(study.specs), quiet=args.quiet) as progress:
        table = sweep(study, workers=args.workers, scheduler=args.scheduler, out=out,
                      resume=not args.no_resume, serial=args.serial, progress=progress)
    if not args.quiet:
        console = result_console()
        console.print(summary_table(table))
        failed = int((table["status"] != "ok").sum())
        cached = int(table.attrs.get("cached", 0))
        console.print(f"{len(table)} runs ({failed} failed, {cached} found done), "
                      f"{table.attrs.get('seconds', 0.0):.1f} s")
        console.print(f"wrote {out / 'results.parquet'}, {out / 'results.csv'}, "
                      f"{out / 'summary.png'}")
    return 0


def summary_table(table):
    """A rich table of a sweep's rows: model, method, delta_0, elements, q, delta_max, time,
    and the error of a failed run."""
    from rich import box
    from rich.table import Table

    out = Table(title=f"hetmesh sweep {table.attrs.get('study', '')}", title_justify="left",
                box=box.SIMPLE_HEAD, pad_edge=False)
    for col in ("model", "method", "δ0", "Ne", "q_min", "q_avg", "δ_max", "s"):
        out.add_column(col, justify="left" if col in ("model", "method") else "right",
                       no_wrap=col in ("model", "method"))
    for r in table.itertuples(index=False):
        if r.status != "ok":
            out.add_row(r.model, r.method, f"{r.threshold:g}", f"{r.status}: {r.error}")
            continue
        out.add_row(r.model, r.method, f"{r.threshold:g}", f"{int(r.n_elements)}",
                    f"{r.q_min:.3f}", f"{r.q_avg:.3f}", f"{r.delta_max:.4f}",
                    f"{r.seconds:.2f}")
    return out
