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
           "h_for_elements", "probe_sets", "uniform_mesher", "measure", "study3d",
           "StudyPlan3D", "PLANS3D", "h_for_tets", "radial_reference",
           "plane_strain_reference", "measure3d"]

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
    dim : int
        2, or 3 for :func:`study3d` (elements are then tetrahedra).
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
    dim: int = 2

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
                "note": self.note, "dim": self.dim}


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

    ctx, frame = prepare(embed_discontinuities(model), 0.1, None, gradation=0.0)

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

    if kind == "adaptive":
        return _solved_on(lambda: generate(model, p).mesh, model, cfg)
    return _solved_on(lambda: (uniform_mesh or uniform_mesher(model))(p), model, cfg)


def _solved_on(make_mesh, model, cfg) -> dict:
    """:func:`measure`'s record of the mesh ``make_mesh()`` makes: its element count, the
    von Mises stress at the probes and the two times, or ``{"error": message}``."""
    from .analysis import solve

    t0 = time.perf_counter()
    try:
        mesh = make_mesh()
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


# --------------------------------------------------------------------------- the 3-D study

@dataclass(frozen=True)
class StudyPlan3D:
    """The meshes of a 3-D study: ``uniform_elements`` are tetrahedron counts of uniform
    meshes (turned into a size by :func:`h_for_tets`), ``thresholds`` the adaptive meshes'
    delta_0, ``reference_elements`` the triangles of the fine 2-D mesh of a plane-strain
    reference (:func:`plane_strain_reference`; unused by the radial one)."""

    uniform_elements: tuple[int, ...]
    thresholds: tuple[float, ...]
    reference_elements: int = 57_000


#: ``full``: 7 uniform meshes of 2,000-170,000 tetrahedra and 5 adaptive ones (delta_0 0.4 to
#: 0.1); ``quick``: 4 uniform (2,000-90,000) and 3 adaptive (0.4, 0.2, 0.15). Quadratic
#: tetrahedra take ~0.5-1 ms each per solve on this project's shared 2-core machine: the full
#: plan is about 10 minutes on fgm_plate_3d, the quick one about 3.
PLANS3D = {
    "full": StudyPlan3D((2_000, 5_000, 12_000, 25_000, 50_000, 100_000, 170_000),
                        (0.4, 0.3, 0.2, 0.15, 0.1)),
    "quick": StudyPlan3D((2_000, 8_000, 30_000, 90_000), (0.4, 0.2, 0.15), 19_000),
}


def h_for_tets(volume: float, n: float) -> float:
    """Size of a swept uniform mesh of about ``n`` tetrahedra filling ``volume``
    (:data:`hetmesh.tet.uniform.TETS_PER_H3` per h^3).

    >>> round(h_for_tets(1.0, 6928.2), 3)
    0.1
    """
    from ..tet.uniform import TETS_PER_H3

    return (TETS_PER_H3 * volume / n) ** (1.0 / 3.0)


def _von_mises_principal(s1, s2, s3) -> float:
    return float(math.sqrt(0.5 * ((s1 - s2) ** 2 + (s2 - s3) ** 2 + (s3 - s1) ** 2)))


def radial_reference(model, cfg=None) -> dict:
    """The exact von Mises stress at the probes of a graded thick-walled tube in plane strain
    (:func:`hetmesh.fea.radial.cylinder`): the solid is an extrusion along z whose section is
    bounded by circular arcs about the origin (the smallest radius ``a``, the largest ``b``)
    and straight symmetry cuts, its composition depends on ``sqrt(x^2 + y^2)`` only, the
    properties are those of ``cfg`` (default ``model.fea``) mixed at the composition along
    the radius; pressures and temperatures on faces lying on ``r = a`` or ``r = b`` are the
    inner and outer loads. The principal stresses at a probe are ``sigma_r``, ``sigma_t`` and
    ``sigma_z``.

    Returns ``{"kind": "radial", "von_mises": {probe: Pa}, "error_estimate": float}``.

    Raises
    ------
    FEAError
        If the model is not such a tube (no arcs, a composition that varies with the angle
        or along z, a load on a face that is not a cylinder about the axis).
    """
    from .mixing import mix_config
    from .radial import cylinder

    cfg = cfg or getattr(model, "fea", None)
    solid = model.solid
    if cfg is None or getattr(solid, "axis", None) != 2:
        raise FEAError(f"{model.name}: the radial reference needs an [fea] table and an "
                       f"extrusion along z")
    arcs = {c.name: c.curve for c in solid.section.curves if hasattr(c.curve, "radius")}
    if not arcs or any(np.hypot(*c.center) > 1e-9 * c.radius for c in arcs.values()):
        raise FEAError(f"{model.name}: the radial reference needs a section bounded by arcs "
                       f"about the origin")
    a = min(c.radius for c in arcs.values())
    b = max(c.radius for c in arcs.values())
    z_mid = 0.5 * (solid.s0 + solid.s1)
    # the composition must depend on the radius only
    rr = np.linspace(a, b, 9)
    comps = []
    for th, z in ((0.0, z_mid), (0.7, solid.s0), (1.3, solid.s1)):
        p = np.column_stack([rr * math.cos(th), rr * math.sin(th), np.full_like(rr, z)])
        comps.append(np.asarray(model.material.composition(p)))
    if max(np.abs(c - comps[0]).max() for c in comps) > 1e-9:
        raise FEAError(f"{model.name}: the radial reference needs a composition that depends "
                       f"on the radius only")
    cons = model.constituents

    def prop(key):
        def f(r):
            r = np.asarray(r, dtype=np.float64)
            p = np.column_stack([np.ravel(r), np.zeros(r.size), np.full(r.size, z_mid)])
            c = np.asarray(model.material.composition(p), dtype=np.float64)
            return mix_config(c, cfg, cons)[key].reshape(r.shape)
        return f

    def radius_of(faces) -> float:
        rs = {arcs[n].radius for n in faces if n in arcs}
        if len(rs) != 1 or len(rs & {a, b}) != 1 or any(n not in arcs for n in faces):
            raise FEAError(f"{model.name}: a load on faces {', '.join(faces)} is not on the "
                           f"inner or the outer cylinder")
        return rs.pop()

    loads = {"p_inner": 0.0, "p_outer": 0.0}
    for bc in cfg.pressure:
        side = "p_inner" if radius_of(bc.where.faces) == a else "p_outer"
        loads[side] += float(bc.value)
    temps = {}
    for bc in cfg.temperature:
        temps["t_inner" if radius_of(bc.where.faces) == a else "t_outer"] = float(bc.value)
    if temps and len(temps) != 2:
        raise FEAError(f"{model.name}: the radial reference needs both surface temperatures "
                       f"or none")
    sol = cylinder(a, b, prop("youngs_modulus"), prop("poisson_ratio"),
                   alpha=prop("expansion"), k=prop("conductivity"),
                   t_ref=cfg.reference_temperature, **loads, **temps)
    vm = {}
    for name, q in cfg.probes.items():
        r = math.hypot(q[0], q[1])
        vm[name] = _von_mises_principal(float(sol.sigma_r(r)), float(sol.sigma_t(r)),
                                        float(sol.sigma_z(r)))
    return {"kind": "radial", "von_mises": vm, "error_estimate": sol.error_estimate}


def plane_strain_reference(model, model2d, *, elements: int = 57_000,
                           check: bool = True) -> dict:
    """The von Mises stress at the probes of an extruded plate held in plane strain (u_z = 0
    on both end faces), from its 2-D model solved in plane strain on a fine uniform mesh of
    about ``elements`` triangles (:func:`measure`), which is then the exact 3-D field at
    every z; with ``check`` also on a mesh of twice the edge, whose difference bounds the
    reference's own error. Each 3-D probe takes the 2-D probe of the same name, which must
    lie at its ``(x, y)``.

    Returns ``{"kind": "plane-strain 2D", "elements", "h", "von_mises", "mesh_seconds",
    "solve_seconds"}`` and with ``check`` a ``"check"`` entry as :func:`study`'s.
    """
    cfg2 = getattr(model2d, "fea", None)
    cfg3 = getattr(model, "fea", None)
    if cfg2 is None or cfg3 is None:
        raise FEAError(f"{model.name}: a plane-strain reference needs [fea] tables in the 3-D "
                       f"and the 2-D model")
    if getattr(cfg2, "plane", "strain") != "strain":
        raise FEAError(f"{model2d.name}: the 2-D reference must be solved in plane strain")
    for name, q in cfg3.probes.items():
        q2 = cfg2.probes.get(name)
        if q2 is None or math.hypot(q2[0] - q[0], q2[1] - q[1]) > 1e-9 * model.solid.diameter:
            raise FEAError(f"{model.name}: probe {name} at ({q[0]:g}, {q[1]:g}) has no 2-D "
                           f"probe of the same name at the same place in {model2d.name}")
    names = list(cfg3.probes)
    uniform_mesh = uniform_mesher(model2d)
    h = h_for_elements(model2d.domain.area, elements)
    out: dict = {"kind": "plane-strain 2D"}
    for kind, hh in [("reference", h)] + ([("check", 2 * h)] if check else []):
        m = measure(model2d, cfg2, "uniform", hh, uniform_mesh=uniform_mesh)
        if "error" in m:
            raise FEAError(f"the plane-strain {kind} (uniform h = {hh:.4g}) failed: "
                           f"{m['error']}")
        entry = {"elements": m["elements"], "h": hh,
                 "von_mises": {k: m["von_mises"][k] for k in names},
                 "mesh_seconds": m["mesh_seconds"], "solve_seconds": m["solve_seconds"]}
        if kind == "reference":
            out.update(entry)
        else:
            entry["difference"] = _rel(entry["von_mises"], out["von_mises"], names)
            out["check"] = entry
    return out


def measure3d(model, cfg, kind: str, p: float, *, sections=None,
              chord_tol: float | None = None) -> dict:
    """One tetrahedral mesh of a 3-D study and its probes: ``kind`` "uniform" with size
    ``p`` (:func:`hetmesh.tet.uniform.uniform_tets_at`) or "adaptive" with ``delta_0 = p``
    (:func:`hetmesh.generate`), both with ``chord_tol`` (relative to the solid's diameter;
    default the meshers'). Returns what :func:`measure` returns."""
    from ..meshing import generate
    from ..tet.api import to_mesh
    from ..tet.uniform import uniform_tets_at

    if kind == "adaptive":
        return _solved_on(lambda: generate(model, p, chord_tol=chord_tol).mesh, model, cfg)
    return _solved_on(lambda: to_mesh(uniform_tets_at(model, p, 0.5, sections=sections,
                                                      chord_tol=chord_tol),
                                      model.constituents), model, cfg)


def study3d(model, reference: dict, *, quick: bool = False, progress: Progress | None = None,
            order: int | None = None, uniform_elements: Sequence[int] | None = None,
            thresholds: Sequence[float] | None = None, tolerance: float = TOLERANCE,
            chord_tol: float | None = None) -> ProbeStudy:
    """The 3-D study: probe von Mises errors of uniform and adaptive tetrahedral meshes of a
    3-D model against ``reference`` (:func:`radial_reference` or
    :func:`plane_strain_reference`), and the tetrahedra each family needs for
    ``tolerance`` (as :func:`study`: the error must stay below it on every finer mesh).

    The uniform meshes are the swept uniform meshes of :mod:`hetmesh.tet.uniform` at the
    sizes :func:`h_for_tets` gives for the plan's counts, the adaptive ones
    :func:`hetmesh.generate` at the plan's thresholds (:data:`PLANS3D`), both with
    ``chord_tol`` (relative to the solid's diameter; default the meshers' 0.002). Curved
    faces matter here: the polygonal faces' error in the stresses near them does not
    decrease with delta_0, and where the material varies slowly along a curved face the
    adaptive mesh keeps its chords at the tolerance. Returns a :class:`ProbeStudy` whose
    ``reference`` is ``reference`` and ``dim`` 3.
    """
    from ..tet.uniform import SectionMesher, section_chord

    t_start = time.perf_counter()
    cfg = getattr(model, "fea", None)
    if cfg is None or not cfg.probes:
        raise FEAError(f"model {model.name!r} has no [fea] table with probes: the 3-D study "
                       f"needs one (see examples/graded_cylinder.toml)")
    if order is not None:
        if order not in (1, 2):
            raise FEAError(f"order: expected 1 or 2, got {order!r}")
        cfg = replace(cfg, order=int(order))
    if not 0 < tolerance < 1:
        raise FEAError(f"tolerance: expected a relative accuracy in (0, 1), got {tolerance!r}")
    plan = PLANS3D["quick" if quick else "full"]
    counts = tuple(int(n) for n in (plan.uniform_elements if uniform_elements is None
                                    else uniform_elements))
    d0s = sorted((float(d) for d in (plan.thresholds if thresholds is None else thresholds)),
                 reverse=True)
    if not counts or min(counts) < 1:
        raise FEAError(f"uniform_elements: expected tetrahedron counts >= 1, got {list(counts)}")
    names = list(cfg.probes)
    missing = [n for n in names if n not in reference.get("von_mises", {})]
    if missing:
        raise FEAError(f"the reference has no value at probe(s) {', '.join(missing)}")
    sets = probe_sets(names)
    primary = "P" if "P" in sets else next(iter(sets))
    hs = sorted((h_for_tets(model.solid.volume, n) for n in counts), reverse=True)
    steps = [("uniform", h) for h in hs] + [("adaptive", d) for d in d0s]
    what = {"uniform": "uniform h = {:.3g}", "adaptive": "adaptive delta_0 = {:g}"}
    sections = SectionMesher(model, 0.5, section_chord(model.solid, chord_tol))
    ref = reference["von_mises"]
    meshes: list[dict] = []
    for i, (kind, p) in enumerate(steps):
        if progress is not None:
            progress(what[kind].format(p), i / len(steps))
        m = measure3d(model, cfg, kind, p, sections=sections, chord_tol=chord_tol)
        if "error" in m:
            log.warning("3-D study: %s failed: %s", what[kind].format(p), m["error"])
            meshes.append({"family": kind, "param": p, "error": m["error"]})
            continue
        errors = {s: max(_rel(m["von_mises"], ref, ns).values()) for s, ns in sets.items()}
        meshes.append({"family": kind, "param": p, "elements": m["elements"],
                       "von_mises": m["von_mises"], "max_error": errors[primary],
                       "errors": errors, "mesh_seconds": m["mesh_seconds"],
                       "solve_seconds": m["solve_seconds"]})
        log.info("3-D study %s: %s, %d tets, max error %.3g", model.name,
                 what[kind].format(p), m["elements"], errors[primary])
    if progress is not None:
        progress("done", 1.0)
    by_set = {s: _needed(meshes, ns, s, tolerance) for s, ns in sets.items()}
    seconds = time.perf_counter() - t_start
    n_u = sum(m["family"] == "uniform" for m in meshes)
    note = (f"{'quick' if quick else 'full'} 3-D run: reference {reference.get('kind', '?')}, "
            f"{n_u} uniform and {len(meshes) - n_u} adaptive tetrahedral meshes, element "
            f"order {cfg.order}, chord tolerance "
            f"{0.002 if chord_tol is None else chord_tol:g} x the diameter, {seconds:.0f} s")
    log.info("3-D study %s: %s", model.name, note)
    return ProbeStudy(reference=reference, meshes=meshes, needed=by_set[primary],
                      needed_by_set=by_set, probe_sets=sets, primary=primary, quick=bool(quick),
                      order=int(cfg.order), tolerance=tolerance, seconds=seconds, note=note,
                      dim=3)
