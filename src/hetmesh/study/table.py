"""The results of a sweep: per-run records, the table (Parquet and CSV) and the summary PNG.

Layout of a sweep's output directory::

    runs/<key>.json      one finished run's row, written as soon as the run is done
    results.parquet      the table: one row per run of the study, in study order
    results.csv          the same table
    summary.png          elements against delta_0 per model, and the time of every run
    meshes/...           mesh files, if the study asks for them

Every file is written atomically (:mod:`hetmesh.io.atomic`): an interrupted sweep leaves
complete files or none. ``runs/`` is what a restarted sweep reads to skip the runs done.
"""

from __future__ import annotations

import json
import logging
import math
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from ..io.atomic import atomic_path, atomic_write
from ..io.jsondoc import jsonable
from .run import BASE_COLUMNS

__all__ = ["rows_to_frame", "write_record", "read_records", "write_table", "plot_summary",
           "INT_COLUMNS", "CACHED_STATUSES"]

log = logging.getLogger(__name__)

#: integer columns (nullable: empty for a failed run)
INT_COLUMNS = ("index", "seed", "n_points", "n_elements")
#: rows kept in ``runs/`` and not redone by a restarted sweep: finished runs, and runs that
#: failed inside the run function (the same inputs fail the same way); a run lost with its
#: worker after every retry (``status = "lost"``) is not kept, so a restart tries it again
CACHED_STATUSES = ("ok", "failed")


def rows_to_frame(rows: Iterable[Mapping[str, Any]]):
    """A :class:`pandas.DataFrame` of rows (:func:`hetmesh.study.run_one`), sorted by
    ``index``; the columns of :data:`~hetmesh.study.run.BASE_COLUMNS` first, then the FEA
    columns in sorted order.

    >>> rows_to_frame([]).shape[0]
    0
    """
    import pandas as pd

    rows = sorted((dict(r) for r in rows), key=lambda r: (r.get("index", 0), r.get("key", "")))
    extra = sorted({k for r in rows for k in r} - set(BASE_COLUMNS))
    columns = list(BASE_COLUMNS) + extra
    data = {c: [r.get(c) for r in rows] for c in columns}
    frame = pd.DataFrame({c: _column(c, v) for c, v in data.items()}, columns=columns)
    return frame


def _column(name: str, values: list):
    import pandas as pd

    if name in INT_COLUMNS:
        return pd.array([None if _missing(v) else int(v) for v in values], dtype="Int64")
    strings = ("key", "model", "method", "sampling", "status", "error", "method_used",
               "timings", "options", "mesh_file", "model_file", "worker", "hetmesh_version")
    if name in strings:
        return pd.array(["" if v is None else str(v) for v in values], dtype=object)
    return np.array([math.nan if _missing(v) else float(v) for v in values], dtype=np.float64)


def _missing(v) -> bool:
    return v is None or (isinstance(v, float) and math.isnan(v))


def write_record(out: Path, row: Mapping[str, Any]) -> Path:
    """Write one run's row to ``out/runs/<key>.json`` (atomically)."""
    directory = Path(out) / "runs"
    directory.mkdir(parents=True, exist_ok=True)
    path = directory / f"{row['key']}.json"
    with atomic_write(path) as f:
        json.dump(jsonable(dict(row), infinity_as_string=False), f, sort_keys=True)
    return path


def read_records(out: Path, keys: Iterable[str]) -> dict[str, dict]:
    """The rows of ``keys`` found in ``out/runs/`` with a status of :data:`CACHED_STATUSES`;
    unreadable records are ignored (with a warning) and the run is redone."""
    found: dict[str, dict] = {}
    directory = Path(out) / "runs"
    if not directory.is_dir():
        return found
    for key in keys:
        path = directory / f"{key}.json"
        if not path.is_file():
            continue
        try:
            row = json.loads(path.read_text(encoding="utf-8"))
        except (OSError, ValueError) as exc:
            log.warning("ignoring the unreadable record %s (%s); the run is done again", path, exc)
            continue
        if isinstance(row, dict) and row.get("key") == key and \
                row.get("status") in CACHED_STATUSES:
            found[key] = row
    return found


def write_table(frame, out: Path, *, stem: str = "results") -> tuple[Path, Path]:
    """Write ``frame`` to ``out/<stem>.parquet`` and ``out/<stem>.csv``, atomically."""
    out = Path(out)
    parquet, csv = out / f"{stem}.parquet", out / f"{stem}.csv"
    with atomic_path(parquet) as tmp:
        frame.to_parquet(tmp, index=False, engine="pyarrow")
    with atomic_path(csv) as tmp:
        frame.to_csv(tmp, index=False, float_format="%.17g")
    return parquet, csv


def plot_summary(frame, path: Path, *, title: str = "") -> Path:
    """The summary figure: elements against delta_0 per model (and method), log-log; and
    the wall time of every run (failed runs in grey), in study order."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(11, 4.5))
    FigureCanvasAgg(fig)
    ax1, ax2 = fig.subplots(1, 2)
    ok = frame[frame["status"] == "ok"]
    models = list(dict.fromkeys(frame["model"]))
    colours = {m: f"C{i % 10}" for i, m in enumerate(models)}
    styles = ["o-", "s--", "^-.", "d:"]
    methods = list(dict.fromkeys(frame["method"]))
    for (model, method), group in ok.groupby(["model", "method"], sort=False):
        g = group.sort_values("threshold")
        label = model if len(methods) == 1 else f"{model} ({method})"
        ax1.plot(g["threshold"], g["n_elements"].astype(float),
                 styles[methods.index(method) % len(styles)], color=colours[model], label=label)
    ax1.set_xscale("log")
    ax1.set_yscale("log")
    ax1.set_xlabel("delta_0")
    ax1.set_ylabel("elements Ne")
    ax1.set_title("Elements against delta_0")
    if len(ok):
        ax1.legend(fontsize=8)
    x = np.arange(len(frame))
    secs = frame["seconds"].to_numpy(dtype=float)
    cols = [colours[m] if s == "ok" else "0.7" for m, s in zip(frame["model"], frame["status"])]
    ax2.bar(x, np.nan_to_num(secs), color=cols)
    ax2.set_xlabel("run (study order; grey: failed)")
    ax2.set_ylabel("wall time per run (s)")
    ax2.set_title("Time per run")
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=120)
    return Path(path)
