"""Case study 4 (paper Sec. 4.4, Table 7): probe accuracy per element, adaptive against uniform.

:func:`study` solves a model with an ``[fea]`` table on a fine uniform **reference** mesh, then
on a family of uniform meshes (edge ``h``) and a family of adaptive meshes
(:func:`hetmesh.generate` at thresholds ``delta_0``) of increasing size; for each it records the
elements, the von Mises stress at every probe and the largest relative error against the
reference, and finds the number of elements each family needs to bring every probe within
``tolerance`` (0.5 %) of the reference::

    model = hetmesh.load_model(hetmesh.example_path("fgm_plate"))
    s = hetmesh.fea.study(model, quick=True)          # ~10 s; the full study ~40 s
    s.needed            # {'uniform': 2589.0, 'adaptive': 745.0, 'reduction': 0.71, ...}

The module is ``probe_study`` rather than ``study`` so that importing it never replaces the
function ``hetmesh.fea.study`` by a module of the same name.
"""

from __future__ import annotations

import logging
import math
import re
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from ..errors import FEAError, HetmeshError

__all__ = ["study", "ProbeStudy", "StudyPlan", "PLANS", "TOLERANCE", "elements_needed",
           "h_for_elements", "probe_sets", "uniform_mesher", "measure"]

log = logging.getLogger(__name__)

#: the study's probe accuracy: every probe within 0.5 % of the reference
TOLERANCE = 0.005

Progress = Callable[[str, float | None], None]


@dataclass(frozen=True)
class StudyPlan:
    """The meshes of a study.

    ``reference_elements`` and ``uniform_elements`` are element counts of uniform meshes,
    turned into an edge ``h`` by :func:`h_for_elements` (the counts are met to a few per
    cent); ``thresholds`` are the adaptive meshes' ``delta_0``; with ``check`` the reference
    problem is also solved on a mesh of edge ``2 h_ref``, whose difference from the reference
    bounds the reference's own error (at convergence of first order or faster).
    """

    reference_elements: int
    uniform_elements: tuple[int, ...]
    thresholds: tuple[float, ...]
    check: bool = True


#: ``full``: reference ~57,000 elements (h = 0.2 mm on fgm_plate, ~15 s at order 2), 12 uniform
#: meshes of 250-11,000 elements and 8 adaptive ones (delta_0 0.4-0.035, ~13,000 elements);
#: ``quick``: reference ~19,000 elements (h = 0.35 mm), 6 uniform and 4 adaptive meshes.
PLANS = {
    "full": StudyPlan(57_000, (250, 350, 500, 700, 1000, 1400, 2000, 2800, 4000, 5600, 8000,
                               11_000), (0.4, 0.3, 0.2, 0.15, 0.1, 0.07, 0.05, 0.035)),
    "quick": StudyPlan(19_000, (250, 500, 1000, 2000, 4000, 8000), (0.3, 0.2, 0.15, 0.1)),
}


@dataclass(frozen=True, eq=False)
class ProbeStudy:
    """The result of :func:`study` (``docs/reproduce.md`` gives the contract).

    Attributes
    ----------
    reference : dict
        ``elements``, ``h``, ``von_mises`` (probe -> Pa), ``mesh_seconds``,
        ``solve_seconds``, and with a check mesh ``check`` (``elements``, ``h``,
        ``von_mises``, ``difference``: probe -> relative difference from the reference).
    meshes : list of dict
        In order (uniform by size, then adaptive): ``family`` ("uniform" or "adaptive"),
        ``param`` (``h`` or ``delta_0``), ``elements``, ``von_mises``, ``max_error`` (the
        largest relative error over the primary probes), ``errors`` (probe set -> largest
        relative error), ``mesh_seconds``, ``solve_seconds``; a mesh that failed has
        ``family``, ``param`` and ``error`` (the message) only.
    needed : dict
        For the primary probes: ``uniform`` and ``adaptive`` (elements for every probe within
        ``tolerance``, None if the family's finest mesh is not), ``uniform_exact`` and
        ``adaptive_exact`` (False: the family's coarsest mesh is within already, so the count
        is an upper bound), ``reduction`` (``1 - adaptive / uniform`` or None where the counts
        do not support one) and ``probes`` (the set's name).
    needed_by_set : dict
        The same for every probe set (``"P"``, ``"Q"``, ..., and ``"all"``).
    probe_sets : dict
        Set name -> probe names; a set is the probes whose names share a letter prefix.
    primary : str
        The set the Table 7 analog is about (``"P"`` when there are P probes).
    quick : bool
        A quick run (:data:`PLANS` ``["quick"]``): coarser reference, fewer meshes.
    order : int
        Element order of every solve.
    tolerance : float
    seconds : float
        Wall time of the study.
    note : str
        One line saying what was run.
    """

    reference: dict
    meshes: list
    needed: dict
    needed_by_set: dict
    probe_sets: dict
    primary: str
    quick: bool
    order: int
    tolerance: float = TOLERANCE
    seconds: float = math.nan
    note: str = ""

    @property
    def reduction(self) -> float | None:
        """``1 - adaptive / uniform`` for the primary probes (None if not supported)."""
        return self.needed.get("reduction")

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready."""
        return {"quick": self.quick, "order": self.order, "tolerance": self.tolerance,
                "primary": self.primary, "probe_sets": self.probe_sets,
                "reference": self.reference, "meshes": self.meshes, "needed": self.needed,
                "needed_by_set": self.needed_by_set, "seconds": self.seconds,
                "note": self.note}


# ------------------------------------------------------------------------------- helpers

def h_for_elements(area: float, n: float) -> float:
    """Edge of equilateral triangles tiling ``area`` with ``n`` elements:
    ``sqrt(4 A / (sqrt(3) n))``.

    >>> round(h_for_elements(998.94, 2307), 3)
    1.0
    """
    return math.sqrt(4.0 * area / (math.sqrt(3.0) * n))


def uniform_mesher(model) -> Callable[[float], Any]:
    """A function ``h -> Mesh``: uniform quality meshes of edge ~h of ``model`` (its
    feature-tree discontinuities embedded, :func:`hetmesh.tri.uniform.uniform_at`), sharing
    one prepared domain."""
    from ..mesh import Mesh
    from ..tri.discontinuity import embed_discontinuities
    from ..tri.pipeline import prepare
    from ..tri.uniform import uniform_at

    ctx, frame = prepare(embed_discontinuities(model), 0.1, None)

    def mesh(h: float) -> Mesh:
        ws, tris = uniform_at(ctx, float(h) / frame.scale, max_elements=10_000_000)
        return Mesh(frame.to_user(ws.P), tris)

    return mesh


def probe_sets(names: Sequence[str]) -> dict[str, list[str]]:
    """Probes grouped by the letters their names start with (``P1..P6`` -> ``"P"``), plus
    ``"all"`` when there is more than one group.

    >>> probe_sets(["P1", "P2", "Q1"])
    {'P': ['P1', 'P2'], 'Q': ['Q1'], 'all': ['P1', 'P2', 'Q1']}
    """
    sets: dict[str, list[str]] = {}
    for n in names:
        m = re.match(r"[^\W\d_]+", n)
        sets.setdefault(m.group(0) if m else n, []).append(n)
    if len(sets) > 1:
        sets["all"] = list(names)
    return sets


def _rel(vals: dict, ref: dict, names) -> dict[str, float]:
    """Relative difference from ``ref`` of every probe in ``names``."""
    return {k: abs(vals[k] - ref[k]) / abs(ref[k]) for k in names}


def elements_needed(elements: Sequence[float], errors: Sequence[float],
                    tol: float = TOLERANCE) -> tuple[float | None, bool]:
    """``(elements, exact)`` a family needs for an error below ``tol`` for good.

    The error must stay below ``tol`` on every finer mesh: the count is where it crosses
    ``tol`` between the last mesh above and the next one, by log-log interpolation (``exact``
    True); the coarsest mesh's count if every mesh is below already (an upper bound, ``exact``
    False); ``(None, False)`` if the finest mesh is still above.

    >>> elements_needed([100, 1000], [0.01, 0.001])   # doctest: +ELLIPSIS
    (200.0..., True)
    """
    order = np.argsort(elements, kind="stable")
    n = np.asarray(elements, float)[order]
    e = np.asarray(errors, float)[order]
    if not len(n):
        return None, False
    above = np.flatnonzero(~(e <= tol))
    if not len(above):
        return float(n[0]), False
    i = int(above[-1])
    if i == len(n) - 1:
        return None, False
    x0, x1 = math.log(n[i]), math.log(n[i + 1])
    y0, y1 = math.log(e[i]), math.log(max(e[i + 1], 1e-300))
    x = x0 + (math.log(tol) - y0) * (x1 - x0) / (y1 - y0)
    return float(math.exp(x)), True


def _needed(runs: list[dict], names: list[str], key: str, tol: float) -> dict:
    got = {}
    for fam in ("uniform", "adaptive"):
        ok = [r for r in runs if r["family"] == fam and "error" not in r]
        got[fam] = elements_needed([r["elements"] for r in ok], [r["errors"][key] for r in ok],
                                   tol)
    (u, ue), (a, ae) = got["uniform"], got["adaptive"]
    # a ratio only when the uniform count is a crossing and the adaptive one a crossing too,
    # or an upper bound below it (then the reduction is a lower bound)
    red = 1.0 - a / u if (u and a and ue and (ae or a <= u)) else None
    return {"probes": key, "names": names, "uniform": u, "uniform_exact": ue, "adaptive": a,
            "adaptive_exact": ae, "reduction": red,
            "reduction_is_lower_bound": bool(red is not None and not ae)}


def measure(model, cfg, kind: str, p: float, *, uniform_mesh=None) -> dict:
    """One mesh of a study and its probes: a plain function (the model, its FEA settings,
    ``kind`` "uniform" with edge ``p`` or "adaptive" with ``delta_0 = p``), so that it runs
    the same in this process and on a worker.

    Returns ``{"elements", "von_mises" (probe -> Pa), "mesh_seconds", "solve_seconds"}``, or
    ``{"error": message}`` if meshing or solving raised a :class:`HetmeshError`.
    ``uniform_mesh`` is a :func:`uniform_mesher` of ``model`` to reuse (default: a new one).
    """
    from ..tri.pipeline import generate
    from .analysis import solve

    t0 = time.perf_counter()
    try:
        if kind == "adaptive":
            mesh = generate(model, p).mesh
        else:
            mesh = (uniform_mesh or uniform_mesher(model))(p)
        t1 = time.perf_counter()
        r = solve(mesh, model, config=cfg)
    except HetmeshError as exc:
        return {"error": str(exc).splitlines()[0] if str(exc) else type(exc).__name__}
    vm = {k: float(v["von_mises"]) for k, v in r.probes.items()}
    return {"elements": int(mesh.n_elements), "von_mises": vm, "mesh_seconds": t1 - t0,
            "solve_seconds": time.perf_counter() - t1}


def _measure_item(item: tuple) -> dict:
    model, cfg, kind, p = item
    return measure(model, cfg, kind, p)


def _measure_on(client, model, cfg, jobs, steps, what, progress) -> list[dict]:
    """:func:`measure` of every job on ``client`` (a Dask client or an executor)."""
    import uuid

    from ..study.engine import map_runs

    token = uuid.uuid4().hex[:12]
    done = [0]
    errors: dict[int, str] = {}

    def on_result(i: int, value, error: str | None) -> None:
        done[0] += 1
        if error is not None:
            errors[i] = error
        if progress is not None:
            kind, p = steps[i]
            progress(what[kind].format(p), done[0] / len(jobs))

    results = map_runs(_measure_item, [(model, cfg, k, p) for k, p in jobs],
                       [f"{token}-{i}" for i in range(len(jobs))], client=client,
                       on_result=on_result, prefix="hetmesh-probe-study")
    return [r if r is not None else {"error": errors.get(i, "no result")}
            for i, r in enumerate(results)]


# ------------------------------------------------------------------------------- the study

def study(model, *, quick: bool = False, progress: Progress | None = None,
          order: int | None = None, reference_elements: int | None = None,
          uniform_elements: Sequence[int] | None = None,
          thresholds: Sequence[float] | None = None, check: bool | None = None,
          tolerance: float = TOLERANCE, client=None) -> ProbeStudy:
    """The case-4 study: probe von Mises errors of uniform and adaptive meshes against a
    fine uniform reference, and the elements each family needs for ``tolerance``.

    Parameters
    ----------
    model : Model
        With an ``[fea]`` table that has probes (``examples/fgm_plate.toml``).
    quick : bool
        :data:`PLANS` ``["quick"]`` (coarser reference, fewer meshes; ~10 s on fgm_plate)
        instead of ``["full"]`` (~40 s).
    progress : callable ``(stage, fraction)``, optional
        Called before every mesh with the fraction of the meshes done.
    order : 1 or 2, optional
        Element order (default: the model's ``[fea] order``).
    reference_elements, uniform_elements, thresholds, check : optional
        Override the plan's (see :class:`StudyPlan`).
    tolerance : float
        Relative probe accuracy (default 0.5 %).
    client : dask.distributed.Client or concurrent.futures.Executor, optional
        Mesh and solve the study's meshes there, all at once (:func:`measure` on each);
        the same numbers as in this process. ``progress`` then reports the meshes done.

    Returns
    -------
    ProbeStudy

    Raises
    ------
    FEAError
        No ``[fea]`` table or no probes; the reference solve failed. A uniform or adaptive
        mesh that fails is recorded with its message and the study goes on.

    Examples
    --------
    >>> model = hetmesh.load_model(hetmesh.example_path("fgm_plate"))   # doctest: +SKIP
    >>> s = hetmesh.fea.study(model, quick=True)                        # doctest: +SKIP
    >>> s.needed["uniform"], s.needed["adaptive"], s.reduction          # doctest: +SKIP
    """
    t_start = time.perf_counter()
    cfg = getattr(model, "fea", None)
    if cfg is None:
        raise FEAError(f"model {model.name!r} has no [fea] table: the study needs one with "
                       f"probes (see examples/fgm_plate.toml)")
    if not cfg.probes:
        raise FEAError(f"model {model.name!r}: the [fea] table has no probes to study")
    if order is not None:
        if order not in (1, 2):
            raise FEAError(f"order: expected 1 or 2, got {order!r}")
        cfg = replace(cfg, order=int(order))
    if not 0 < tolerance < 1:
        raise FEAError(f"tolerance: expected a relative accuracy in (0, 1), got {tolerance!r}")
    plan = PLANS["quick" if quick else "full"]
    plan = StudyPlan(
        int(plan.reference_elements if reference_elements is None else reference_elements),
        tuple(int(n) for n in (plan.uniform_elements if uniform_elements is None
                               else uniform_elements)),
        tuple(float(d) for d in (plan.thresholds if thresholds is None else thresholds)),
        plan.check if check is None else bool(check))
    if min(plan.reference_elements, *plan.uniform_elements) < 1:
        raise FEAError(f"reference_elements, uniform_elements: expected element counts >= 1, "
                       f"got {plan.reference_elements} and {list(plan.uniform_elements)}")

    names = list(cfg.probes)
    sets = probe_sets(names)
    primary = "P" if "P" in sets else next(iter(sets))
    area = model.domain.area
    uniform_mesh = uniform_mesher(model) if client is None else None
    h_ref = h_for_elements(area, plan.reference_elements)
    hs = sorted((h_for_elements(area, n) for n in plan.uniform_elements), reverse=True)
    d0s = sorted(plan.thresholds, reverse=True)
    steps = [("reference", h_ref)] + ([("check", 2 * h_ref)] if plan.check else []) \
        + [("uniform", h) for h in hs] + [("adaptive", d) for d in d0s]

    what = {"reference": "reference, uniform h = {:.3g}",
            "check": "reference check, uniform h = {:.3g}",
            "uniform": "uniform h = {:.3g}", "adaptive": "adaptive delta_0 = {:g}"}
    # the reference and its check are uniform meshes
    jobs = [("adaptive" if kind == "adaptive" else "uniform", p) for kind, p in steps]
    if client is None:
        measured = []
        for i, (kind, p) in enumerate(steps):
            if progress is not None:
                progress(what[kind].format(p), i / len(steps))
            measured.append(measure(model, cfg, *jobs[i], uniform_mesh=uniform_mesh))
            if kind in ("reference", "check") and "error" in measured[-1]:
                break  # the study cannot go on without its reference
    else:
        measured = _measure_on(client, model, cfg, jobs, steps, what, progress)

    reference: dict = {}
    meshes: list[dict] = []
    for (kind, p), m in zip(steps, measured):
        if kind in ("reference", "check"):
            if "error" in m:
                raise FEAError(f"the study's {kind} mesh (uniform h = {p:.4g}) failed: "
                               f"{m['error']}")
            entry = {"elements": m["elements"], "h": p, "von_mises": m["von_mises"],
                     "mesh_seconds": m["mesh_seconds"], "solve_seconds": m["solve_seconds"]}
            if kind == "reference":
                reference = entry
            else:
                entry["difference"] = _rel(m["von_mises"], reference["von_mises"], names)
                reference["check"] = entry
            continue
        if "error" in m:  # a study reports, it does not stop
            log.warning("study: %s failed: %s", what[kind].format(p), m["error"])
            meshes.append({"family": kind, "param": p, "error": m["error"]})
            continue
        vm = m["von_mises"]
        ref = reference["von_mises"]
        errors = {s: max(_rel(vm, ref, ns).values()) for s, ns in sets.items()}
        meshes.append({"family": kind, "param": p, "elements": m["elements"],
                       "von_mises": vm, "max_error": errors[primary], "errors": errors,
                       "mesh_seconds": m["mesh_seconds"], "solve_seconds": m["solve_seconds"]})
    if progress is not None:
        progress("done", 1.0)

    by_set = {s: _needed(meshes, ns, s, tolerance) for s, ns in sets.items()}
    seconds = time.perf_counter() - t_start
    n_u = sum(m["family"] == "uniform" for m in meshes)
    note = (f"{'quick' if quick else 'full'} run: reference uniform h = {h_ref:.3g} "
            f"({reference['elements']} elements), {n_u} uniform and {len(meshes) - n_u} "
            f"adaptive meshes, element order {cfg.order}, {seconds:.0f} s")
    log.info("study %s: %s", model.name, note)
    return ProbeStudy(reference=reference, meshes=meshes, needed=by_set[primary],
                      needed_by_set=by_set, probe_sets=sets, primary=primary, quick=bool(quick),
                      order=int(cfg.order), tolerance=tolerance, seconds=seconds, note=note)
