"""The adaptive meshing pipeline: IMG -> MOR -> GOR (paper Sec. 3.1, Fig. 2).

``generate`` composes the stages:

* IMG: the domain's curves are sampled into a PSLG following the material size field and
  triangulated (constrained Delaunay);
* MOR: nodes are placed for the density rho = |grad f|^4 (Eq. 9), either by the paper's
  conforming CVT (``method="cvt"``: density-sampled nodes + Lloyd iterations, Sec. 3.2.3), by
  aligning rows of nodes with the iso-composition curves (``method="layers"``, see
  :mod:`hetmesh.tri.layers`) or by relaxing nodes of the same density as a truss of springs
  (``method="springs"``, :mod:`hetmesh.tri.springs`); the default ``method="auto"`` uses the
  rows, and on small models the springs too, keeping the better mesh; then elements with
  delta(T) >= delta_0 are refined (Eq. 13; we split the edge carrying the largest composition
  jump, which removes both triangles sharing it) and the new nodes are smoothed locally by
  conforming Lloyd steps, until delta_max < delta_0 (Eq. 1);
* GOR: Delaunay refinement of triangles below the minimum angle or the quality floor
  (circumcenter insertion; encroached boundary and interface edges are split on their true
  curve, Ruppert), with delta re-checked in the same loop.

The loop ends: smoothing stops after a few rounds, after which every round only splits edges,
and the element budget bounds the count; a final verification re-checks every claim.
"""

from __future__ import annotations

import logging
import math
import time
from dataclasses import replace

import numpy as np

from .. import density as dens
from ..errors import BudgetError, MeshingError, OptionError
from ..kernel import Result
from ..metrics import MeshStats
from ..options import (
    DEFAULT_GRADATION,
    DEFAULT_MAX_ELEMENTS,
    DEFAULT_ROW_SPACING,
    check_options,
    check_sampling,
)
from .coarsen import collapse
from .discontinuity import embed_discontinuities
from .finish import CHORD_TOL, MAX_EDGE_MARGIN, finish
from .frame import local_field, local_frame
from .geometry import build_pslg
from .geosize import GRADE, boundary_size
from .grading import material_grading
from .optimize import KEEP
from .optimize import optimize as optimize_mesh
from .placement import PLACEMENTS
from .refine import POLISH_GROWTH, below_floor, copy_workset, repair, restore_workset
from .sizecap import variation_cap
from .workset import Context

__all__ = ["generate", "prepare", "candidates", "METHODS", "H_MIN_RATIO"]

log = logging.getLogger(__name__)

#: the smallest size the placement aims at, relative to the largest (``Context.h_min``)
H_MIN_RATIO = 2.0 ** -10



def prepare(model, threshold, max_size, chord_tol: float = CHORD_TOL, *,
            row_spacing: float = DEFAULT_ROW_SPACING, geo_grade: float | None = GRADE,
            gradation: float = DEFAULT_GRADATION):
    """The refinement context in the model's :class:`~hetmesh.tri.frame.LocalFrame` (moved to
    the origin and scaled to a diameter near 1, so that no tolerance depends on the user's
    units), and that frame. ``max_size`` is in user units, ``chord_tol`` relative to the
    domain's diameter; ``gradation`` (0: none) grades the material sizes
    (:mod:`hetmesh.tri.grading`)."""
    frame = local_frame(model.domain.bounds)
    dom = model.domain.translated(-frame.offset).scaled(1.0 / frame.scale)
    fl = local_field(model.material, frame)
    h_max = float(max_size) / frame.scale if max_size is not None else dom.diameter / 8.0
    infos = dom.curves
    curves = [ci.curve for ci in infos]
    scale = dom.diameter
    closed = np.array([np.hypot(*(c.start - c.end)) < 1e-12 * scale for c in curves], bool)
    bnd = np.array([ci.kind != "interface" for ci in infos], bool)
    scalar = row_constituent(fl, dom)
    ctx = Context(domain=dom, curves=curves, closed=closed, boundary_curve=bnd, field=fl,
                  threshold=threshold, h_max=h_max, scalar=scalar,
                  chord_tol=chord_tol * dom.diameter, h_min=H_MIN_RATIO * h_max,
                  row_spacing=row_spacing,
                  max_edge=h_max * (1.0 - MAX_EDGE_MARGIN) if max_size is not None else None,
                  variation_cap=variation_cap(fl.composition, dom.bounds, threshold))
    if geo_grade is not None:
        pslg = build_pslg(dom, h_max, ctx.chord_tol)
        ctx.geo_size = boundary_size(pslg.vertices, pslg.edges, h_max, geo_grade)
    if gradation > 0:
        ctx.gradient_floor = material_grading(ctx.g_capped, dom.contains, dom.bounds, threshold,
                                              h_max, float(gradation))
    return ctx, frame



#: ``method`` values of :func:`generate`: ``"auto"`` chooses (see :func:`candidates`)
METHODS = ("auto", "layers", "cvt", "springs")



#: with ``method="auto"``, a model whose a-priori estimate is at most this many elements is
#: meshed from the layers and the springs placements and the best mesh kept
#: (:func:`_better`): on the robustness benchmark's models (111 runs below 20,000 elements)
#: the mean quality came within 0.01 of Gmsh's Frontal-Delaunay mesh in 107 runs with the
#: springs starts against 66 with the CVT starts, at fewer elements than Gmsh's in 108
COMPARE_BELOW = 50_000



#: the exchange rate of :func:`_better`: 0.005 of mean quality is worth 12 % of the elements
#: (10 % before the sizes were graded, which left the meshes a larger margin of elements
#: below Gmsh's: on the robustness benchmark 12 % keeps 106 of 113 runs below Gmsh's count
#: and 68 within 0.01 of its q_avg, against 108 and 66 at 10 %; 13 % gives 104 and 69 but
#: took a 32 % larger section for graded_ring, whose tetrahedra multiply its triangles)
QUALITY_WEIGHT = math.log(1.12) / 0.005



#: the mean-rule pass on the kept mesh (see ``optimize`` in :func:`generate`) is made where
#: the a-priori estimate is at most this many elements: on the ~1M-element unit_square it
#: took 2 s and a second verification 1.4 s more (19 -> 21-22 s of a run that must stay
#: under half of Gmsh's 43 s) for a q_avg of 0.999 either way; the robustness benchmark's
#: runs, the examples and the 3D sweeps' sections are all below it
POLISH_BELOW = COMPARE_BELOW

#: the placements ``"auto"`` compares on small models
AUTO_STARTS = ("layers", "springs", "springs-dense")
#: those the 3D sweeps compare for their sections: the layers (with a node at every
#: crossing of a level with a curve) and the two CVT starts. The springs starts' sections
#: were measured to give fewer tetrahedra on some sweeps (graded_cylinder at 0.3: 1,088
#: against 1,330) and 58 % more on graded_ring, and a coarser radial layout whose stresses
#: at graded_cylinder's probes were 3 % off at 0.4 (0.5 % from the layers section), so the
#: sweeps keep these until that is resolved. With the curve nodes half-way between the
#: levels where the rows meet a curve square (``"layers"``), the sections of graded_ring at
#: 0.2 and graded_cylinder at 0.3 had 109 and 162 triangles of q_avg 0.948 and 0.944
#: (against 101 of 0.954 and 160 of 0.948) and the sweeps 33,573 and 1,379 tetrahedra
#: (against 29,599 and 1,330)
SWEEP_STARTS = ("layers-crossings", "cvt", "cvt-dense")



def candidates(method: str, ctx: Context, est: float,
               starts: tuple[str, ...] | None = None) -> list[str]:
    """The placements to try, in order. ``"auto"`` tries ``starts`` (default
    :data:`AUTO_STARTS`: the layers and the springs placements, from 1.3 x the density's
    node count where the material sets the size and from 1.5 x everywhere) on small
    models, and on models of more than two constituents always: their rows follow one
    constituent's level curves (:func:`row_constituent`), which bound the others'
    variation only where they share level curves, and the isotropic starts may be the
    better ones; on large models the first alone."""
    if method == "auto":
        every = list(AUTO_STARTS if starts is None else starts)
        many = len(ctx.field.constituents) > 2
        return every if est <= COMPARE_BELOW or many else every[:1]
    return [method]



def row_constituent(field, domain) -> int:
    """The constituent whose level curves carry the rows of the layers placement: for two
    constituents the second (their variations are equal); for more, the one with the
    largest integral of |grad f_i| (most rows), so that where the fractions share level
    curves (a radial grading of three phases) the rows bound every fraction's variation."""
    m = len(field.constituents)
    if m == 2:
        return 1
    g = np.linalg.norm(field.gradient(dens.background_points(domain, 100)), axis=2)
    g = np.where(np.isfinite(g), g, 0.0)
    return int(np.argmax(g.sum(axis=0)))



def _better(a: MeshStats, b: MeshStats) -> bool:
    """Whether mesh statistics ``a`` beat ``b``: the lower ``Ne exp(-w q_avg)``, w =
    :data:`QUALITY_WEIGHT` (each 0.005 of mean quality worth 12 % of the elements; a
    model where one placement needs 7 x the elements of the other for 0.014 of q_avg keeps
    the smaller mesh, one where they differ by 12 % and 0.006 keeps the better shaped)."""
    score = lambda s: math.log(s.n_elements) - QUALITY_WEIGHT * s.q_avg  # noqa: E731
    return score(a) < score(b)



#: failures of a placement after which :func:`generate` starts again from the CVT placement:
#: meshing errors other than the element budget, and internal errors (never bad input)
FALLBACK_ERRORS = (MeshingError, ArithmeticError, ValueError, IndexError, RuntimeError)



def _cause(exc: Exception) -> str:
    """A one-line reason for a fallback, e.g. ``MeshingError: the mesh failed verification``."""
    first = str(exc).splitlines()[0] if str(exc) else ""
    return f"{type(exc).__name__}: {first[:200]}"



def _mesh_with(method: str, ctx: Context, frame, threshold: float, chord_tol: float,
               history: list, timings: dict, *, min_angle: float, min_quality: float,
               sampling: str, max_elements: int, seed: int, optimize: bool, progress):
    """Placement (MOR start), refinement (MOR + GOR), optimisation and verification with the
    placement ``method``; fills ``history`` and ``timings``; returns ``(mesh, stats,
    state)``, ``state`` the work set and the repair loop's ``(triangles, composition,
    delta)`` of the verified mesh, for :func:`_polish`."""
    rng = np.random.default_rng(seed)
    t1 = time.perf_counter()
    ws = PLACEMENTS[method](ctx, rng, chord_tol, progress=progress)
    timings["placement"] = time.perf_counter() - t1
    t2 = time.perf_counter()
    tris, comp, delta = repair(ws, ctx, min_angle_deg=min_angle, min_quality=min_quality,
                               sampling=sampling, max_elements=max_elements, history=history,
                               progress=progress)
    timings["refine"] = time.perf_counter() - t2
    if optimize:
        t4 = time.perf_counter()
        with ctx.timed("optimize"):
            tris, comp, delta = collapse(ws, ctx, tris, comp, delta, sampling=sampling,
                                         min_angle_deg=min_angle)
            tris, comp, delta = optimize_mesh(ws, ctx, tris, comp, delta, sampling=sampling,
                                              min_angle_deg=min_angle)
            low = below_floor(ws, ctx, tris, min_quality, min_angle)
            if low:  # the few the smoothing left: repair them, then smooth again
                saved, kept = copy_workset(ws), (tris, comp, delta)
                extra: list = []  # the rounds of this repair, in the history if it is kept
                try:
                    tris, comp, delta = repair(ws, ctx, min_angle_deg=min_angle,
                                               min_quality=min_quality, sampling=sampling,
                                               max_elements=max_elements, history=extra,
                                               smooth_rounds=0)
                    tris, comp, delta = optimize_mesh(ws, ctx, tris, comp, delta,
                                                      sampling=sampling,
                                                      min_angle_deg=min_angle)
                    after = below_floor(ws, ctx, tris, min_quality, min_angle)
                except MeshingError:
                    after = low
                if after >= low or len(tris) > POLISH_GROWTH * len(kept[0]):
                    restore_workset(ws, saved)
                    tris, comp, delta = kept
                else:
                    history.extend(extra)
                log.info("final quality repair: %d -> %d triangles below the floor%s", low,
                         after, "" if after < low else " (not kept)")
        timings["optimize"] = time.perf_counter() - t4
        history.append({"round": len(history), "stage": "optimize", "elements": int(len(tris)),
                        "points": int(ws.n), "delta_max": float(delta.max()),
                        "violators": int((delta >= threshold).sum())})
    t3 = time.perf_counter()
    mesh, stats = finish(ws, ctx, tris, comp, delta, frame, threshold=threshold,
                         min_angle_deg=min_angle)
    timings["verify"] = time.perf_counter() - t3
    return mesh, stats, (ws, tris, comp, delta)


def _polish(state, ctx: Context, frame, threshold: float, history: list, timings: dict, *,
            min_angle: float, sampling: str):
    """The optimisation pass with the mean rule (:data:`~hetmesh.tri.optimize.KEEP`) on the
    mesh ``generate`` keeps, then its verification; returns ``(mesh, stats)``. Made once,
    after the placements are compared (on the small models three times fewer passes than
    for each of them): the comparison sees each mesh as the first pass left it."""
    ws, tris, comp, delta = state
    ws = copy_workset(ws)  # the verified mesh holds (read-only) arrays of its own
    t0 = time.perf_counter()
    with ctx.timed("optimize"):
        tris, comp, delta = optimize_mesh(ws, ctx, tris, comp, delta, sampling=sampling,
                                          min_angle_deg=min_angle, keep=KEEP)
    timings["optimize_mean"] = time.perf_counter() - t0
    t1 = time.perf_counter()
    mesh, stats = finish(ws, ctx, tris, comp, delta, frame, threshold=threshold,
                         min_angle_deg=min_angle)
    timings["verify"] = timings.get("verify", 0.0) + time.perf_counter() - t1
    history.append({"round": len(history), "stage": "optimize", "rule": "mean",
                    "elements": int(len(tris)), "points": int(ws.n),
                    "delta_max": float(delta.max()),
                    "violators": int((delta >= threshold).sum())})
    return mesh, stats



def generate(model, threshold: float, *, min_angle: float = 30.0, max_size: float | None = None,
             max_elements: int = DEFAULT_MAX_ELEMENTS, sampling: str = "vertices",
             method: str = "auto", seed: int = 0, min_quality: float = 0.6,
             optimize: bool = True, chord_tol: float = CHORD_TOL,
             row_spacing: float = DEFAULT_ROW_SPACING, gradation: float = DEFAULT_GRADATION,
             starts: tuple[str, ...] | None = None, progress=None) -> Result:
    """Mesh ``model`` so that every element has delta(T) < ``threshold`` (Eq. 1).

    Parameters
    ----------
    model : hetmesh Model (``load_model`` or built in code)
    threshold : delta_0 in (0, 1)
    min_angle : minimum angle in degrees, (0, 34]; triangles at input corners sharper
        than twice it are exempt.
    max_size : largest element edge (default: domain diameter / 8); floors rho.
    max_elements : element budget, checked against an a-priori estimate and while refining.
    sampling : "vertices" (the paper's Eqs. 14-15), "dense" (also a lattice inside
        every element), "certified" (an upper bound over the element) or "pixels" (image
        fields: also every pixel centre the element covers).
    method : "auto" (default), "layers" (nodes on iso-composition curves), "springs"
        (isotropically sized nodes relaxed as a truss of springs: nearly equilateral
        elements) or "cvt" (the paper's CVT start). "auto" meshes from the layers placement
        and, where the model is small (a-priori estimate up to 50,000 elements) or has more
        than two constituents, from the springs placement too (from 1.3 x the density's
        node count where the material sets the size, ``max_size`` where it does not:
        ``"springs"``; from 1.5 x everywhere: ``"springs-dense"``), and keeps the best mesh
        (the lower ``Ne exp(-22.7 q_avg)``: each 0.005 of mean quality is worth 12 % of the
        elements); ``Result.options["placements"]`` has every outcome (before the kept
        mesh's last pass, see ``optimize``) and ``["method"]`` the one kept.
    seed : random seed (same input and seed, same mesh).
    min_quality : quality floor q(T) (Eq. 17) enforced by the refinement.
    optimize : after the refinement, raise the element quality by smoothing and edge flips
        that keep delta(T) < threshold and never lower a node star's minimum quality
        (:func:`hetmesh.tri.optimize.optimize`); then, on the mesh kept, one more pass for
        the mean quality, in which no triangle falls below the lower of its quality and
        0.8 (:data:`hetmesh.tri.optimize.KEEP`); same nodes and elements. The last pass is
        made where the a-priori estimate is at most 50,000 elements
        (:data:`POLISH_BELOW`).
    chord_tol : the largest distance between a curved boundary or interface curve and any
        of its chords (the mesh edges along it), relative to the domain's diameter, in
        [1e-7, 0.05]; verified chord by chord.
    row_spacing : the step in composition between the rows of nodes of the layers
        placement, as a fraction of ``threshold``, in [0.3, 0.99]. The default 0.85 leaves
        every element some slack that the quality pass spends on shape; 0.985 gives the
        fewest elements (most of them just under the threshold) at a lower mean quality.
    gradation : how fast the placement's element size may grow per unit length, in
        [0, 10] (0: not graded). The size ``delta_0 / |grad f|`` is made smaller where a
        much smaller size is near (:mod:`hetmesh.tri.grading`), as Gmsh's and MMG's size
        gradation do; without it a narrow bump or a steep front in a flat part gets tiny
        elements next to ones of size ``max_size``, which the quality refinement then has
        to grade at a higher cost. Like ``max_size`` it never relaxes the delta guarantee.
    starts : the placements ``"auto"`` compares on small models (default
        :data:`AUTO_STARTS`: the layers and the two springs starts; the first alone on
        large models); only with ``method="auto"``. The 3D sweeps mesh their sections with
        :data:`SWEEP_STARTS`.

    If the layers placement fails on a model (an internal error of the row tracing or a
    mesh that fails verification), the run goes on from the next placement (the springs
    start where ``"auto"`` tries it, else the CVT placement), logs a warning with the
    reason and records it in ``Result.options["fallbacks"]``; so does a run whose every
    placement failed, with the CVT placement last.

    Examples
    --------
    >>> import hetmesh
    >>> m = hetmesh.load_model(hetmesh.example_path("power_plate"))   # doctest: +SKIP
    >>> r = hetmesh.generate(m, 0.05)                                   # doctest: +SKIP
    >>> r.stats.delta_max < 0.05                                        # doctest: +SKIP
    True
    """
    threshold = check_options(threshold, min_angle=min_angle, max_elements=max_elements,
                              max_size=max_size, sampling=sampling, min_quality=min_quality,
                              seed=seed, chord_tol=chord_tol, row_spacing=row_spacing,
                              gradation=gradation)
    if method not in METHODS:
        raise OptionError(f"method {method!r} is not one of {', '.join(METHODS)}")
    if starts is not None and (not starts or any(p not in PLACEMENTS for p in starts)):
        raise OptionError(f"starts must name placements among {', '.join(PLACEMENTS)}, "
                          f"got {starts!r}")
    if starts is not None and method != "auto":
        raise OptionError(f"starts is for method 'auto', not {method!r}")
    check_sampling(model.material, sampling)
    timings: dict = {}
    t0 = time.perf_counter()
    model = embed_discontinuities(model)
    ctx, frame = prepare(model, threshold, max_size, chord_tol, row_spacing=row_spacing,
                         gradation=gradation)
    est = dens.estimate_elements(ctx.field, ctx.domain, threshold, ctx.h_max)
    if ctx.gradient_floor is not None:  # graded sizes: never fewer elements than that
        est = max(est, dens.estimate_elements(ctx.field, ctx.domain, threshold, ctx.h_max,
                                              g=ctx.g))
    if est > max_elements:
        raise BudgetError(f"the a-priori estimate is {est:,.0f} elements, above the budget of "
                          f"{max_elements:,}; raise --max-elements or the threshold")
    rel_chord_tol, chord_tol = chord_tol, ctx.chord_tol  # relative (the option), absolute
    timings["prepare"] = time.perf_counter() - t0
    run = dict(min_angle=min_angle, min_quality=min_quality, sampling=sampling,
               max_elements=max_elements, seed=seed, optimize=optimize, progress=progress)
    fallbacks: list = []
    tried: dict = {}
    outcome, first_error = None, None
    queue = candidates(method, ctx, est, starts)
    while queue:
        name = queue.pop(0)
        history: list = []
        tm = dict(timings)
        t1 = time.perf_counter()
        try:
            mesh, stats, state = _mesh_with(name, ctx, frame, threshold, chord_tol, history, tm,
                                            **run)
        except FALLBACK_ERRORS as exc:
            first_error = first_error or exc
            tried[name] = {"error": _cause(exc)}
            if isinstance(exc, BudgetError):
                continue
            nxt = queue[0] if queue else None
            if nxt is None and outcome is None and "cvt" not in tried:
                nxt = "cvt"  # no placement handled this model: start from the CVT placement
                queue.append(nxt)
            if nxt is not None and (name == "layers" or nxt == "cvt"):
                log.warning("the %s placement failed (%s); meshing from the %s placement "
                            "instead", name, _cause(exc), nxt)
                fallbacks.append({"from": name, "to": nxt, "cause": _cause(exc),
                                  "stage": "refinement" if history else "placement"})
            continue
        tried[name] = {"elements": stats.n_elements, "q_avg": stats.q_avg,
                       "seconds": time.perf_counter() - t1}
        if outcome is None or _better(stats, outcome[1]):
            outcome = (mesh, stats, history, tm, name, state)
    if outcome is None:
        raise first_error
    mesh, stats, history, timings, method, state = outcome
    if optimize and est <= POLISH_BELOW:
        try:
            mesh, stats = _polish(state, ctx, frame, threshold, history, timings,
                                  min_angle=min_angle, sampling=sampling)
        except MeshingError as exc:  # never expected: the pass keeps every claim
            log.warning("the last optimisation pass failed (%s); kept the mesh before it",
                        _cause(exc))
    if sampling == "certified":  # delta_max is then an upper bound on every element's variation
        stats = replace(stats, delta_max_certified=stats.delta_max)
    timings["total"] = time.perf_counter() - t0
    # where the time went, across the phases above (seconds): Delaunay rebuilds, Lloyd steps
    # (CVT and row staggering), refinement-point computation, delta/quality evaluation
    timings.update({f"{k}_s": v for k, v in sorted(ctx.clock.items())})
    opts = dict(threshold=threshold, min_angle=min_angle, max_size=ctx.h_max * frame.scale,
                max_elements=max_elements, sampling=sampling, method=method, seed=seed,
                min_quality=min_quality, optimize=optimize, estimate=float(est),
                fallbacks=fallbacks, placements=tried, chord_tol=float(rel_chord_tol),
                row_spacing=float(row_spacing), gradation=float(gradation))
    return Result(mesh=mesh, stats=stats, threshold=threshold, history=history,
                  timings=timings, options=opts, model=model)

