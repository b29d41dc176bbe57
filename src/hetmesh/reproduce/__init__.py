"""``hetmesh reproduce``: the paper's tables and figures, side by side with the paper and peers.

:func:`run` meshes the paper's models (the examples ``power_plate``, ``hft_ring``, ``blade``,
``hft_complex``, ``fgm_plate``) at the paper's thresholds, adaptively and uniformly, and
writes ``DIR/report.md`` with PNG figures under ``DIR/figures/``:

- Table 1, 3 and 5 analogs: Np, Ne, q_min, q_avg, delta_min, delta_avg, delta_max and wall
  time of the adaptive and the uniform mesh, the paper's values in adjacent columns labelled
  ``paper``; N_iso (:func:`hetmesh.density.n_iso`), Ne/N_iso and the adaptive/uniform element
  ratio beside the paper's;
- figures like the paper's Figs. 5, 8, 10, 11, 13 (meshes coloured by composition, interfaces
  and material discontinuities in red) and Figs. 6, 9 (delta histograms, adaptive against a
  uniform mesh of about the same element count);
- a peer section: Gmsh and Triangle meeting the same thresholds (:mod:`hetmesh.peers`) when
  they are installed (``pip install "hetmesh[peers]"``);
- a Table 7 analog when :mod:`hetmesh.fea` provides the case-4 study (``hetmesh.fea.study``);
- with ``three_d=True`` (``--3d``), a 3-D section (:mod:`hetmesh.reproduce.study3d`): the
  solids ``fgm_plate_3d`` and ``graded_cylinder``, adaptive against uniform tetrahedra at two
  thresholds, Gmsh's 3-D mesh as a peer, and the tetrahedra each needs for 0.5 % at the FEA
  probes.

Every number in the report is computed by that run, except the columns labelled as the paper's.

Examples
--------
>>> from hetmesh import reproduce
>>> report = reproduce.run("rep", cases=["power_plate"], quick=True)   # doctest: +SKIP
>>> report.path                                                         # doctest: +SKIP
PosixPath('rep/report.md')
"""

from __future__ import annotations

import logging
import math
import os
import platform
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from datetime import UTC, datetime
from pathlib import Path

from ..errors import HetmeshError, OptionError
from ..io.atomic import output_dir
from .paper import CASES, Case
from .runs import CaseRun, mesh_record

__all__ = ["run", "Report", "CASES", "plan", "fea_study_function", "split_cases"]

log = logging.getLogger(__name__)

Progress = Callable[[str, float | None], None]


@dataclass
class Report:
    """What :func:`run` measured and wrote: ``path`` of report.md, the figure files, one
    :class:`~hetmesh.reproduce.runs.CaseRun` per model and threshold, the peer versions
    (None: not installed), whether peers were run, the FEA study (or None), timings and the 3-D
    section (:class:`~hetmesh.reproduce.study3d.Section3D`, None when not run)."""

    path: Path
    quick: bool
    cases: list[str]
    runs: list[CaseRun]
    peer_versions: dict[str, str | None]
    peers_run: bool
    fea: object = None
    fea_error: str | None = None
    seconds: float = math.nan
    environment: dict = field(default_factory=dict)
    figures: list[Path] = field(default_factory=list)
    study3d: object = None


def split_cases(cases: Sequence[str] | None) -> tuple[list[str] | None, list[str]]:
    """``(2-D case names or None for all, 3-D solid names)`` of a case list: the names of
    :data:`~hetmesh.reproduce.study3d.CASES3D` are the 3-D section's."""
    from .study3d import CASES3D

    if not cases:
        return None, []
    names = [str(c).strip() for c in cases if str(c).strip()]
    solids = [n for n in names if n in CASES3D]
    planar = [n for n in names if n not in CASES3D]
    return (planar if planar or not solids else []), solids


def plan(cases: Sequence[str] | None = None, quick: bool = False) -> list[tuple[Case, float]]:
    """The ``(case, threshold)`` pairs of a report, in report order (the 2-D ones; names of
    3-D solids are skipped, see :func:`split_cases`).

    Raises
    ------
    OptionError
        If a case name is unknown.
    """
    from .study3d import CASES3D

    if cases:
        planar, solids = split_cases(cases)
        if solids and not planar:
            return []
        cases = planar
    names = list(CASES) if not cases else [str(c).strip() for c in cases if str(c).strip()]
    unknown = [n for n in names if n not in CASES]
    if unknown:
        raise OptionError(f"unknown case(s) {', '.join(map(repr, unknown))} "
                          f"(known: {', '.join(list(CASES) + list(CASES3D))})")
    if not names:
        raise OptionError(f"no case given (known: {', '.join(CASES)})")
    return [(CASES[n], t) for n in dict.fromkeys(names)
            for t in (CASES[n].quick if quick else CASES[n].thresholds)]


def fea_study_function():
    """``hetmesh.fea.study`` if the FEA package provides the case-4 study, else None."""
    try:
        from .. import fea
    except ImportError:
        return None
    func = getattr(fea, "study", None)
    return func if callable(func) else None


def _environment(command: str | None) -> dict:
    import numpy

    from ..version import __version__

    return {"hetmesh": __version__, "python": platform.python_version(),
            "numpy": numpy.__version__, "platform": platform.platform(),
            "cpus": os.cpu_count(),
            "date": datetime.now(UTC).strftime("%Y-%m-%d %H:%M UTC"),
            "command": command or ""}


def run(out: str | os.PathLike = "hetmesh-reproduce", *, cases: Sequence[str] | None = None,
        quick: bool = False, peers: bool | None = None, fea: bool | None = None,
        progress: Progress | None = None, command: str | None = None,
        workers: int | None = None, scheduler: str | None = None, client=None,
        three_d: bool = False) -> Report:
    """Mesh the paper's models and write ``out/report.md`` with its figures.

    Parameters
    ----------
    out : path
        Output directory (created if missing); figures go to ``out/figures``.
    cases : sequence of str, optional
        Model names among :data:`CASES` (default: all five, in the paper's order).
    quick : bool
        Coarse thresholds only (one per model) and, unless ``peers=True``, no peers.
    peers : bool, optional
        Run the Gmsh/Triangle section (default: not ``quick``). Peers not installed are
        reported as such.
    fea : bool, optional
        Run the Table 7 study if :mod:`hetmesh.fea` provides it (default: when ``fgm_plate``
        is among the cases).
    progress : callable ``(stage, fraction)``, optional
        Called before every step with the fraction of the steps done.
    command : str, optional
        The command line, quoted in the report.
    workers, scheduler, client : optional
        Run the models' records and the FEA study's meshes on a local Dask cluster of
        ``workers`` processes, on the scheduler at ``scheduler``, or on ``client``
        (:mod:`hetmesh.study.engine`); the same numbers as this process alone.
    three_d : bool
        Add the 3-D section (:mod:`hetmesh.reproduce.study3d`; also when ``cases`` names a
        3-D solid, and then only those solids): a few minutes with ``quick``, about
        15-20 minutes without on a 2-core machine. It runs in this process.

    Returns
    -------
    Report

    Raises
    ------
    OptionError
        Unknown case names.
    OutputError
        ``out`` cannot be created or written.
    """
    from .. import peers as peer_module
    from ..io.model import example_path, load_model
    from .report import render, write_report

    t_start = time.perf_counter()
    pairs = plan(cases, quick)
    planar, solids = split_cases(cases)
    three_d = bool(three_d or solids)
    out = output_dir(Path(out), "figures")
    names = list(dict.fromkeys(c.name for c, _ in pairs))
    run_peers = (not quick) if peers is None else bool(peers)
    versions = peer_module.available()
    installed = [p for p, v in versions.items() if v] if run_peers else []
    study = fea_study_function() if (fea is None and "fgm_plate" in names) or fea else None
    steps = len(pairs) * (1 + len(installed)) + (1 if study else 0) + (1 if three_d else 0)
    done = [0]

    def step(stage: str) -> None:
        if progress is not None:
            progress(stage, done[0] / steps)
        done[0] += 1

    models = {n: load_model(example_path(n)) for n in names}
    runs, figures = [], []
    with _engine(workers, scheduler, client) as dask_client:
        if dask_client is None:
            for case, threshold in pairs:
                step(f"{case.name} delta_0={threshold:g}: adaptive and uniform")
                record = mesh_record(out, case, threshold, models[case.name], quick,
                                      installed, step, figures)
                runs.append(record)
        else:
            runs = _distributed_records(dask_client, out, pairs, quick, installed, step)
            figures += [out / p for r in runs for p in (r.mesh_figure, r.histogram) if p]
        fea_result, fea_error = _fea_study(study, models, quick, progress, done, steps,
                                           dask_client)
    section3d = None
    if three_d:
        from .study3d import run3d

        base = done[0]

        def progress3d(stage: str, fraction: float | None) -> None:
            if progress is not None:
                progress(stage, (base + (fraction or 0.0)) / steps)

        section3d = run3d(quick=quick, peers=["gmsh"] if "gmsh" in installed else [],
                          cases=solids or None, progress=progress3d)
        done[0] += 1
    if progress is not None:
        progress("writing the report", 1.0)
    solid_names = [r.case for r in section3d.runs] if section3d is not None else []
    report = Report(path=out / "report.md", quick=quick,
                    cases=names + list(dict.fromkeys(solid_names)), runs=runs,
                    peer_versions=versions, peers_run=run_peers, fea=fea_result,
                    fea_error=fea_error, environment=_environment(command), figures=figures,
                    study3d=section3d)
    report.seconds = time.perf_counter() - t_start
    write_report(report.path, render(report))
    return report


def _fea_study(study, models: dict, quick: bool, progress, done: list, steps: int,
               client) -> tuple[object, str | None]:
    """The Table 7 study (on ``client`` if given): ``(result, error message)``."""
    from ..io.model import example_path, load_model

    if not study:
        return None, None
    if progress is not None:
        progress("fgm_plate: FEA study (Table 7)", done[0] / steps)
    base = done[0]
    done[0] += 1

    def study_progress(stage: str, fraction: float | None) -> None:
        if progress is not None:
            progress(f"fgm_plate FEA study: {stage}", (base + (fraction or 0.0)) / steps)

    extra = {} if client is None else {"client": client}
    try:
        fea_model = models.get("fgm_plate") or load_model(example_path("fgm_plate"))
        return study(fea_model, quick=quick, progress=study_progress, **extra), None
    except HetmeshError as exc:
        fea_error = str(exc).splitlines()[0]
        log.warning("FEA study failed: %s", fea_error)
        return None, fea_error


def _engine(workers, scheduler, client):
    """A context giving the Dask client to run on, or None (this process)."""
    import contextlib

    if client is not None:
        return contextlib.nullcontext(client)
    if workers is None and scheduler is None:
        return contextlib.nullcontext(None)
    from ..study.engine import open_client

    return open_client(workers=workers, scheduler=scheduler)


def _distributed_records(client, out: Path, pairs, quick: bool, installed: list[str],
                         step) -> list[CaseRun]:
    """:func:`~hetmesh.reproduce.runs.case_record` of every pair on ``client``, in report
    order; ``step`` is called once per model/threshold and peer, as records arrive."""
    import hashlib

    from ..study.engine import map_runs

    where = hashlib.sha1(str(out.resolve()).encode()).hexdigest()[:8]
    items = [(str(out), case.name, threshold, quick, installed) for case, threshold in pairs]
    errors: dict[int, str] = {}

    def on_result(i: int, record, error: str | None) -> None:
        case, threshold = pairs[i]
        for what in ["adaptive and uniform", *installed]:
            step(f"{case.name} delta_0={threshold:g}: {what}")
        if error is not None:
            errors[i] = error
            log.warning("%s at delta_0 = %g: %s", case.name, threshold, error)

    records = map_runs(_case_record_star, items,
                       [f"{where}-{c.name}-{t:g}-{'q' if quick else 'f'}-{'-'.join(installed)}"
                        for c, t in pairs],
                       client=client, on_result=on_result, prefix="hetmesh-reproduce")
    for i, error in errors.items():
        records[i] = CaseRun(pairs[i][0].name, pairs[i][1], error=error)
    return records


def _case_record_star(item: tuple) -> CaseRun:
    from .runs import case_record

    return case_record(*item)
