"""Parameter sweeps and studies, on Dask: from a laptop to a cluster with the same call.

A study file (TOML, ``docs/sweep.md``) lists meshing runs: models, thresholds, methods,
sampling and any :func:`hetmesh.generate` option, as a grid and/or explicit runs, with an
optional FEA step and mesh files. :func:`sweep` runs them on a Dask cluster (a local one by
default, or any scheduler by address), one row per run, and writes the table (Parquet and
CSV) and a summary PNG::

    table = hetmesh.sweep("examples/studies/sweep.toml", out="results")      # local cluster
    table = hetmesh.sweep(study, client=Client("tcp://head:8786"))     # a running cluster
    table[["model", "threshold", "n_elements", "q_avg", "seconds"]]

Runs are plain functions of plain data (:func:`run_one` on :attr:`Study.specs`), so they
also run under :mod:`concurrent.futures`, Ray or any executor. A failing run is a row with
its message; a run whose worker is killed is redone elsewhere; a sweep started again over
the same output directory redoes only the runs it does not find there, by content key
(model file, options, hetmesh version).
"""

from __future__ import annotations

import logging
import os
import time
from collections.abc import Callable, Mapping
from pathlib import Path

from ..errors import OptionError
from ..io.atomic import output_dir
from .engine import LOST, Counts, dashboard_link, map_runs, open_client
from .keys import content_key, text_digest
from .run import BASE_COLUMNS, failed_row, run_one
from .schema import METHODS, RUN_KEYS, Study, load_study, parse_study
from .table import plot_summary, read_records, rows_to_frame, write_record, write_table

__all__ = ["sweep", "Study", "load_study", "parse_study", "run_one", "rows_to_frame",
           "map_runs", "open_client", "Counts", "content_key", "text_digest", "METHODS",
           "RUN_KEYS", "BASE_COLUMNS"]

log = logging.getLogger(__name__)


def _as_study(study) -> Study:
    if isinstance(study, Study):
        return study
    if isinstance(study, Mapping):
        return parse_study(study)
    if isinstance(study, (str, os.PathLike)):
        return load_study(study)
    raise OptionError(f"study: expected a Study, a study file's path or a dict, "
                      f"got {type(study).__name__}")


def sweep(study, client=None, *, workers: int | None = None, scheduler: str | None = None,
          out: str | os.PathLike | None = None, resume: bool = True, serial: bool = False,
          progress: Callable[[Counts], None] | None = None):
    """Run every run of a study; returns the table (a :class:`pandas.DataFrame`).

    Parameters
    ----------
    study : Study, path or dict
        A study (:func:`load_study`), a study file, or a parsed one (:func:`parse_study`).
    client : dask.distributed.Client or concurrent.futures.Executor, optional
        Where to run (left open). Default: a local Dask cluster of ``workers`` processes,
        or a client of ``scheduler``, closed at the end.
    workers : int, optional
        Size of the default local cluster (default: one worker per core).
    scheduler : str, optional
        Address of a running Dask scheduler (``tcp://host:8786`` or a scheduler file).
    out : path, optional
        Output directory (created if missing): ``runs/<key>.json`` per finished run,
        ``results.parquet``, ``results.csv``, ``summary.png`` and, if the study asks for
        them, ``meshes/``. Without it nothing is written and nothing resumed.
    resume : bool
        Take the runs found in ``out/runs/`` (same content key) instead of running them
        again (default). False: run everything.
    serial : bool
        Run in this process, one after the other (no Dask).
    progress : callable ``(Counts)``, optional
        Called at the start and after every run.

    Returns
    -------
    pandas.DataFrame
        One row per run, in study order (columns: ``docs/sweep.md``). ``status`` is
        ``"ok"``, ``"failed"`` (``error`` has the message) or ``"lost"`` (its worker died on
        every try; a restarted sweep runs it again).

    Raises
    ------
    OptionError
        A bad study file, or bad ``workers``/``scheduler``.
    OutputError
        ``out`` cannot be created or written.

    Examples
    --------
    >>> t = hetmesh.sweep("examples/studies/sweep.toml", workers=2,  # doctest: +SKIP
    ...                   out="sweep-out")
    >>> t.groupby("model")["n_elements"].max()                                 # doctest: +SKIP
    """
    if client is not None and (workers is not None or scheduler is not None or serial):
        raise OptionError("sweep: give a client, or workers/scheduler/serial, not both")
    study = _as_study(study)
    out_dir = output_dir(Path(out)) if out is not None else None
    specs = study.specs
    counts = Counts(total=len(specs))
    rows: dict[str, dict] = {}
    if out_dir is not None and resume:
        rows.update(read_records(out_dir, [s["key"] for s in specs]))
        for s in specs:  # the study's order, not the record's
            if s["key"] in rows:
                rows[s["key"]]["index"] = s["index"]
        counts.cached = counts.done = len(rows)
        counts.failed = sum(r["status"] != "ok" for r in rows.values())
        if rows:
            log.info("%d of %d runs found done in %s", len(rows), len(specs), out_dir)
    todo = [s for s in specs if s["key"] not in rows]

    def on_result(i: int, row: dict | None, error: str | None) -> None:
        spec = todo[i]
        if row is None:
            status = LOST if error and error.startswith(LOST) else "failed"
            row = failed_row(spec, error or "no result", status=status)
        rows[spec["key"]] = row
        counts.done += 1
        counts.failed += row["status"] != "ok"
        if out_dir is not None and row["status"] != LOST:
            write_record(out_dir, row)
        if row["status"] != "ok":
            log.warning("run %d (%s, %s, delta_0 = %g) %s: %s", spec["index"], spec["model"],
                        spec["method"], spec["threshold"], row["status"], row["error"])

    def on_progress(running: int, pending: int) -> None:
        counts.running = running
        if progress is not None:
            progress(counts)

    t0 = time.perf_counter()
    args = (str(out_dir) if out_dir is not None else None,)
    if not todo:
        on_progress(0, 0)
    elif serial or client is not None:
        if client is not None and hasattr(client, "scheduler_info"):  # a Dask client
            counts.dashboard = dashboard_link(client)
        map_runs(run_one, todo, [s["key"] for s in todo], client=None if serial else client,
                 args=args, on_result=on_result, on_progress=on_progress,
                 costs=[s.get("cost", 0.0) for s in todo])
    else:
        with open_client(workers=workers, scheduler=scheduler) as dask_client:
            counts.dashboard = dashboard_link(dask_client, local=scheduler is None)
            map_runs(run_one, todo, [s["key"] for s in todo], client=dask_client, args=args,
                     on_result=on_result, on_progress=on_progress,
                     costs=[s.get("cost", 0.0) for s in todo])
    counts.running = 0
    if progress is not None:
        progress(counts)
    frame = rows_to_frame(rows[s["key"]] for s in specs)
    frame.attrs.update({"study": study.name, "seconds": time.perf_counter() - t0,
                        "cached": counts.cached})
    if out_dir is not None:
        write_table(frame, out_dir)
        plot_summary(frame, out_dir / "summary.png", title=f"study {study.name}: "
                     f"{len(frame)} runs, {int((frame['status'] != 'ok').sum())} failed")
    return frame
