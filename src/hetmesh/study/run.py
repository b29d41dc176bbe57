"""One run of a study: a plain function of plain data.

:func:`run_one` takes a run as :func:`hetmesh.study.load_study` lists it (a dict of strings,
numbers and lists, the model file's text included) and returns its row (a flat dict of
strings, numbers and None). It never raises for a failing run: the row says ``status =
"failed"`` and carries the error's one-line message, so that a study goes on. Being a plain
function of picklable data, it runs the same in this process, a Dask worker, a
:class:`concurrent.futures.ProcessPoolExecutor` or a Ray task::

    from concurrent.futures import ProcessPoolExecutor
    study = hetmesh.study.load_study("sweep.toml")
    with ProcessPoolExecutor(2) as pool:
        rows = list(pool.map(hetmesh.study.run_one, study.specs))
    table = hetmesh.study.rows_to_frame(rows)
"""

from __future__ import annotations

import json
import logging
import math
import os
import socket
import time
import tomllib
from pathlib import Path
from typing import Any

__all__ = ["run_one", "STAT_COLUMNS", "BASE_COLUMNS", "failed_row", "mesh_file_name"]

log = logging.getLogger(__name__)

#: the mesh statistics of a row (:class:`hetmesh.MeshStats`)
STAT_COLUMNS = ("n_points", "n_elements", "q_min", "q_avg", "delta_min", "delta_avg",
                "delta_max", "angle_min", "delta_max_dense")

#: every row's columns, in table order; FEA probe columns (``fea.<probe>.<quantity>``) follow
BASE_COLUMNS = ("index", "key", "model", "method", "threshold", "sampling", "seed",
                "status", "error", *STAT_COLUMNS, "method_used", "seconds", "mesh_seconds",
                "fea_seconds", "timings", "options", "mesh_file", "model_file", "worker",
                "hetmesh_version")

#: the probe quantities a row records (:meth:`hetmesh.fea.FEAResult.report`)
PROBE_QUANTITIES = ("von_mises", "temperature")


def mesh_file_name(spec: dict) -> str:
    """The mesh file of a run, relative to the sweep's output directory."""
    return f"meshes/{spec['model']}_{spec['method']}_{spec['threshold']:g}_{spec['key']}." \
           f"{spec['mesh_format']}"


def _base_row(spec: dict) -> dict[str, Any]:
    from ..version import __version__

    opts = spec["options"]
    return {"index": int(spec.get("index", 0)), "key": spec["key"], "model": spec["model"],
            "method": spec["method"], "threshold": float(spec["threshold"]),
            "sampling": opts.get("sampling", "vertices"), "seed": opts.get("seed"),
            "status": "ok", "error": "", **{k: None for k in STAT_COLUMNS},
            "method_used": spec["method"], "seconds": math.nan, "mesh_seconds": math.nan,
            "fea_seconds": math.nan, "timings": "{}",
            "options": json.dumps(opts, sort_keys=True), "mesh_file": "",
            "model_file": spec.get("model_file", ""), "worker": _worker(),
            "hetmesh_version": __version__}


def _worker() -> str:
    return f"{socket.gethostname()}:{os.getpid()}"


def failed_row(spec: dict, message: str, status: str = "failed") -> dict[str, Any]:
    """The row of a run that did not finish, with its one-line error ``message``."""
    row = _base_row(spec)
    row["status"] = status
    row["error"] = " ".join(str(message).split())
    return row


def _model(spec: dict):
    from ..io.model import parse_model

    path = Path(spec["model_file"]) if spec.get("model_file") else None
    where = path.name if path else f"{spec['model']}.toml"
    data = tomllib.loads(spec["model_text"])
    return parse_model(data, where, source=path, default_name=spec["model"], check=False)


def _mesh(spec: dict, model):
    from ..meshing import generate, uniform

    opts = dict(spec["options"])
    if spec["method"] == "uniform":
        return uniform(model, spec["threshold"], **opts)
    return generate(model, spec["threshold"], method=spec["method"], **opts)


def _fea(spec: dict, model, mesh) -> dict[str, float]:
    from dataclasses import replace

    from ..errors import FEAError
    from ..fea import solve

    cfg = model.fea
    if cfg is None:
        raise FEAError(f"model {spec['model']!r} has no [fea] table, but the study asks for "
                       f"an FEA step")
    want = spec["fea"]
    if want.get("probes"):
        missing = [p for p in want["probes"] if p not in cfg.probes]
        if missing:
            raise FEAError(f"model {spec['model']!r} has no probe {missing[0]!r} "
                           f"(probes: {', '.join(cfg.probes) or 'none'})")
        cfg = replace(cfg, probes={k: cfg.probes[k] for k in want["probes"]})
    if want.get("order"):
        cfg = replace(cfg, order=int(want["order"]))
    result = solve(mesh, model, config=cfg)
    out = {"fea.von_mises_max": float(result.von_mises.max())}
    for name, values in result.probes.items():
        for q in PROBE_QUANTITIES:
            if q in values:
                out[f"fea.{name}.{q}"] = float(values[q])
    return out


def run_one(spec: dict, out: str | os.PathLike | None = None) -> dict[str, Any]:
    """Mesh (and, with an FEA step, solve) one run; returns its row.

    Parameters
    ----------
    spec : dict
        A run of :attr:`hetmesh.study.Study.specs` (plain data).
    out : path, optional
        The sweep's output directory: where the mesh file goes when the study asks for one
        (``meshes/<model>_<method>_<threshold>_<key>.<format>``, written atomically). On a
        cluster it must be a file system the workers share.

    Returns
    -------
    dict
        The row: the columns of :data:`BASE_COLUMNS` and ``fea.<probe>.<quantity>``. A run
        that fails has ``status = "failed"`` and ``error`` (one line); the function does not
        raise for it.

    Examples
    --------
    >>> study = hetmesh.study.load_study("examples/studies/sweep.toml")   # doctest: +SKIP
    >>> run_one(study.specs[0])["n_elements"]                     # doctest: +SKIP
    150
    """
    from ..errors import HetmeshError

    t0 = time.perf_counter()
    row = _base_row(spec)
    try:
        model = _model(spec)
        t1 = time.perf_counter()
        result = _mesh(spec, model)
        row["mesh_seconds"] = time.perf_counter() - t1
        row.update(result.stats.as_dict())
        row["method_used"] = str(result.options.get("method", spec["method"]))
        row["timings"] = json.dumps({k: round(float(v), 6) for k, v in result.timings.items()},
                                    sort_keys=True)
        if spec.get("fea"):
            t2 = time.perf_counter()
            row.update(_fea(spec, result.model, result.mesh))
            row["fea_seconds"] = time.perf_counter() - t2
        if spec.get("mesh_format") and out is not None:
            from ..io.export import write_mesh

            rel = mesh_file_name(spec)
            target = Path(out) / rel
            target.parent.mkdir(parents=True, exist_ok=True)
            write_mesh(result.mesh, target)
            row["mesh_file"] = rel
    except HetmeshError as exc:
        message = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        if exc.internal:
            message = f"internal error: {message}"
        row = {**failed_row(spec, message), "worker": row["worker"]}
    except Exception as exc:  # a bug or a system failure in this run: recorded, the study goes on
        row = failed_row(spec, f"internal error: {type(exc).__name__}: {exc}")
    row["seconds"] = time.perf_counter() - t0
    return row
