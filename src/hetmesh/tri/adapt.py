"""The adaptive meshing pipeline: IMG -> MOR -> GOR (paper Sec. 3.1, Fig. 2).

``generate`` composes the stages:

* IMG: the domain's curves are sampled into a PSLG following the material size field and
  triangulated (constrained Delaunay);
* MOR: nodes are placed for the density rho = |grad f|^4 (Eq. 9), either by the paper's
  conforming CVT (``method="cvt"``: density-sampled nodes + Lloyd iterations, Sec. 3.2.3) or by
  aligning rows of nodes with the iso-composition curves (``method="layers"``, see
  :mod:`hetmesh.tri.layers`); the default ``method="auto"`` uses the rows, and on small models
  both placements, keeping the better mesh; then elements with delta(T) >= delta_0 are refined (Eq. 13; we
  split the edge carrying the largest composition jump, which removes both triangles sharing
  it) and the new nodes are smoothed locally by conforming Lloyd steps, until
  delta_max < delta_0 (Eq. 1);
* GOR: Delaunay refinement of triangles below the minimum angle or the quality floor
  (circumcenter insertion; encroached boundary and interface edges are split on their true
  curve, Ruppert), with delta re-checked in the same loop.

The loop ends: smoothing stops after a few rounds, after which every round only splits edges,
and the element budget bounds the count; a final verification re-checks every claim.
"""

from __future__ import annotations

import functools
import logging
import math
import time
from dataclasses import dataclass, field, replace

import numpy as np
from scipy.spatial import cKDTree

from .. import density as dens
from .corners import corner_exempt, sharp_corners, shell_split
from .discontinuity import FIT_TOL, crossing_elements, embed_discontinuities
from ..material.field import element_subregions, has_subregions
from ..errors import BudgetError, MeshDataError, MeshingError, OptionError, VerificationError
from .frame import local_field, local_frame
from .sizecap import variation_cap
from .geosize import GRADE, boundary_size
from .geometry import build_pslg
from .layers import place_layers
from ..mesh import Mesh, any_corner, edge_keys
from .optimize import optimize as optimize_mesh
from ..parallel import block_concat
from ..options import (DEFAULT_CHORD_TOL, DEFAULT_MAX_ELEMENTS, DEFAULT_ROW_SPACING, SAMPLINGS,
                      check_options, check_sampling)
from ..metrics import (MeshStats, circumcircles, delta_dense, element_delta,
                      quality, quality_and_angle, side_lengths, statistics, triangle_angles)
from .workset import (Context, WorkSet, add_free_points, lineage, workset_from_pslg,
                     split_constraint_edges, smooth, thin_candidates_mask,
                     triangulate)
from .workset import edge_params
from .verify import chord_areas, chord_problems, coverage_problems

__all__ = ["generate", "Result", "mesh_statistics", "prepare", "finish", "check_options"]

log = logging.getLogger(__name__)

#: the largest sagitta of a boundary or interface chord, relative to the domain's diameter:
#: the default of ``chord_tol`` (:data:`hetmesh.options.DEFAULT_CHORD_TOL`)
CHORD_TOL = DEFAULT_CHORD_TOL
#: how far a curve node may be from its curve in the final verification, x diameter
ON_CURVE_TOL = 1e-8
#: the smallest size the placement aims at, relative to the largest (``Context.h_min``)
H_MIN_RATIO = 2.0 ** -10
#: ``max_size`` is enforced as the longest edge less this (relative), against rounding in
#: the user's coordinates
MAX_EDGE_MARGIN = 1e-9


@dataclass
class Result:
    """What :func:`generate` and :func:`hetmesh.uniform` return."""

    mesh: Mesh
    stats: MeshStats
    threshold: float
    history: list = field(default_factory=list)
    timings: dict = field(default_factory=dict)
    options: dict = field(default_factory=dict)
    #: the model as meshed: with its material discontinuities embedded as interfaces
    model: object = None


def prepare(model, threshold, max_size, chord_tol: float = CHORD_TOL, *,
            row_spacing: float = DEFAULT_ROW_SPACING, geo_grade: float | None = GRADE):
    """The refinement context in the model's :class:`~hetmesh.tri.frame.LocalFrame` (moved to
    the origin and scaled to a diameter near 1, so that no tolerance depends on the user's
    units), and that frame. ``max_size`` is in user units, ``chord_tol`` relative to the
    domain's diameter."""
    frame = local_frame(model.domain.bounds)
    dom = model.domain.translated(-frame.offset).scaled(1.0 / frame.scale)
    fl = local_field(model.material, frame)
    h_max = float(max_size) / frame.scale if max_size is not None else dom.diameter / 8.0
    infos = dom.curves
    curves = [ci.curve for ci in infos]
    scale = dom.diameter
    closed = np.array([np.hypot(*(c.start - c.end)) < 1e-12 * scale for c in curves], bool)
    bnd = np.array([ci.kind != "interface" for ci in infos], bool)
    scalar = _row_constituent(fl, dom)
    ctx = Context(domain=dom, curves=curves, closed=closed, boundary_curve=bnd, field=fl,
                  threshold=threshold, h_max=h_max, scalar=scalar,
                  chord_tol=chord_tol * dom.diameter, h_min=H_MIN_RATIO * h_max,
                  row_spacing=row_spacing,
                  max_edge=h_max * (1.0 - MAX_EDGE_MARGIN) if max_size is not None else None,
                  variation_cap=variation_cap(fl.composition, dom.bounds, threshold))
    if geo_grade is not None:
        pslg = build_pslg(dom, h_max, ctx.chord_tol)
        ctx.geo_size = boundary_size(pslg.vertices, pslg.edges, h_max, geo_grade)
    return ctx, frame


# --------------------------------------------------------------------------- placement
def size_fn(ctx: Context, factor: float):
    def h(pts):
        return dens.size_at(ctx.g(pts), ctx.threshold, ctx.h_at(pts), factor)
    return h


def place_cvt(ctx: Context, rng, chord_tol: float, progress=None, start: float = 0.9
              ) -> WorkSet:
    """The paper's MOR start: density-sampled nodes, then global conforming Lloyd (Sec. 3.2.3).

    ``start`` is the node count relative to the density's (equilateral elements of side
    delta_0 / |grad f|). About 0.9 is best where one composition gradient sets the size: at
    1.0 some 40 % of the elements violate, below 0.85 the start is already finer than the
    refinement needs. Where several constituents vary in different directions (three_phase)
    the density undercounts: 0.9 leaves 59 % violators and the repair's insertions cost
    shape (q_avg 0.943), 1.3 leaves 19 % and ends with fewer elements (1,447 against 1,491
    at 0.05) of a better shape (0.955)."""
    factor = 1.0 / np.sqrt(start)
    h = size_fn(ctx, factor)
    ws = workset_from_pslg(build_pslg(ctx.domain, h, chord_tol))
    pts = _sample_interior(ctx, h, rng)
    add_free_points(ws, pts)
    tris = triangulate(ws, ctx)
    smooth(ws, ctx, tris, iters=12)
    return ws


def _sample_interior(ctx: Context, h, rng) -> np.ndarray:
    """Stratified random nodes with density 2/(sqrt(3) h^2) (equilateral triangles of side h)."""
    dom = ctx.domain
    x0, y0, x1, y1 = dom.bounds
    n = 256
    cx = (x1 - x0) / n
    cy = (y1 - y0) / n
    X, Y = np.meshgrid(x0 + (np.arange(n) + 0.5) * cx, y0 + (np.arange(n) + 0.5) * cy)
    c = np.column_stack([X.ravel(), Y.ravel()])
    lam = 2.0 / (np.sqrt(3.0) * h(c) ** 2) * cx * cy
    k = np.floor(lam).astype(np.int64)
    k += rng.random(len(k)) < (lam - k)
    cells = np.repeat(np.arange(len(c)), k)
    pts = c[cells] + (rng.random((len(cells), 2)) - 0.5) * [cx, cy]
    pts = pts[dom.contains(pts)]
    if len(pts):
        far = dom.distance_to_boundary(pts) > 0.5 * h(pts)
        pts = pts[far]
    return pts


# --------------------------------------------------------------------------- repair loop
def _constraint_index(ws: WorkSet):
    keys = edge_keys(ws.E[:, 0], ws.E[:, 1])
    order = np.argsort(keys)
    return keys[order], order


def _lookup(sorted_keys, order, keys):
    pos = np.searchsorted(sorted_keys, keys)
    pos = np.minimum(pos, len(sorted_keys) - 1)
    hit = sorted_keys[pos] == keys
    return np.where(hit, order[pos], -1)


def evaluate(ctx: Context, ws: WorkSet, tris: np.ndarray, sampling: str, known=None,
             at=None, carry=None):
    """Compositions at the nodes and delta(T); ``known`` holds those of the first nodes,
    evaluated where they were then (``at``, their positions then; without it they have not
    moved): only new and moved nodes are evaluated again. ``carry = (src, delta)``: the
    elements with ``src >= 0`` are unchanged since an evaluation that gave them
    ``delta[src]`` (:func:`_carried`); only the others are evaluated.

    With a feature-tree field every element is evaluated in its own subregion (Sec. 3.3).
    """
    n0 = len(known) if known is not None and len(known) <= ws.n else 0
    if n0:
        comp = np.empty((ws.n,) + known.shape[1:])
        comp[:n0] = known
        redo = np.arange(n0, ws.n)
        if at is not None:
            same = at[:n0] == ws.P[:n0]
            redo = np.concatenate([np.flatnonzero(~(same[:, 0] & same[:, 1])), redo])
        if len(redo):
            comp[redo] = _composition(ctx, ws.P[redo])
    else:
        comp = _composition(ctx, ws.P)

    def delta_of(rows):
        t = tris if rows is None else tris[rows]
        regions = element_subregions(ctx.field, ws.P, t) if has_subregions(ctx.field) else None
        return (element_delta(ctx.field, ws.P, t, sampling, comp, regions=regions,
                              threshold=ctx.threshold),)

    if carry is None:
        return comp, delta_of(None)[0]
    return comp, _carry(carry[0], (carry[1],), delta_of)[0]


def _carried(state, lin) -> np.ndarray | None:
    """For every triangle of the current triangulation (lineage ``lin``,
    :func:`hetmesh.tri.workset.lineage`), its position in the triangulation ``state`` was
    evaluated on (``(base, rows, ...)``), or -1 where it is new; None if the two do not
    descend from one full rebuild."""
    if state is None or lin is None or lin[0] is not state[0]:
        return None
    rows = state[1]
    pos = np.full(len(lin[0]), -1, np.int64)
    ok = rows >= 0
    pos[rows[ok]] = np.flatnonzero(ok)
    src = np.full(len(lin[1]), -1, np.int64)
    have = lin[1] >= 0
    src[have] = pos[lin[1][have]]
    return src


def _carry(src: np.ndarray, previous: tuple, compute) -> tuple:
    """Per-triangle arrays: ``previous[k][src]`` where ``src >= 0`` (unchanged triangles),
    ``compute(rows)[k]`` for the other rows."""
    old = np.flatnonzero(src >= 0)
    new = np.flatnonzero(src < 0)
    fresh = compute(new)
    out = []
    for a, f in zip(previous, fresh):
        o = np.empty(len(src), a.dtype)
        o[old] = a[src[old]]
        o[new] = f
        out.append(o)
    return tuple(out)


def _composition(ctx: Context, pts: np.ndarray) -> np.ndarray:
    """The field's compositions at ``pts``, by blocks of points (pointwise)."""
    return block_concat(lambda s: ctx.field.composition(pts[s]), len(pts), serial=True)


def repair(ws: WorkSet, ctx: Context, *, min_angle_deg: float, min_quality: float,
           sampling: str, max_elements: int, history: list, smooth_rounds: int = 6,
           max_rounds: int = 200, quality_rounds: int = 8, angle_rounds: int = 64, progress=None,
           check_delta: bool = True):
    """Refine until delta_max < delta_0 (MOR, Eq. 1) and no triangle is below the angle or
    quality floor (GOR). Returns ``(triangles, composition, delta)``.

    The minimum angle is enforced by Ruppert's circumcenter insertion, which terminates for
    angles up to ~34 degrees. The quality floor ``min_quality`` also catches obtuse triangles,
    for which circumcenter insertion has no termination guarantee (it can cascade): it is
    enforced during the first ``quality_rounds`` rounds, then relaxed to 0.5 while the angle
    floor holds, best effort. Likewise the angle
    is enforced for ``angle_rounds`` rounds: new nodes that keep the delta guarantee can
    interact with Ruppert's insertions; after that only delta-driven splits remain, which end
    (every split halves an edge with a composition jump >= delta_0 of a continuous field)."""
    thr = ctx.threshold
    tris = None
    # compositions of the nodes, and where the nodes were when they were evaluated; the
    # triangulation last evaluated (lineage) and its delta, quality and angle: local
    # updates of the triangulation keep most triangles, whose values are carried over
    known = known_at = state = None
    sharp = sharp_corners(ws, ctx)
    polish = None  # (first round, saved work set, saved result) of the final quality rounds
    for rnd in range(max_rounds):
        if tris is None:
            tris = triangulate(ws, ctx)
        with ctx.timed("evaluate"):
            lin = lineage(ws, tris)
            src = _carried(state, lin)
            comp, delta = evaluate(ctx, ws, tris, sampling, known, known_at,
                                   None if src is None else (src, state[2]))
            known, known_at = comp, ws.P.copy()
            viol = delta >= thr if check_delta else np.zeros(len(tris), bool)
            longest = _too_long(ws.P, tris, ctx.max_edge)  # max_size: split the longest edge
            viol |= longest
            if src is None:
                q, ang = quality_and_angle(ws.P, tris)
            else:
                q, ang = _carry(src, state[3:], lambda r: quality_and_angle(ws.P, tris[r]))
            state = None if lin is None else lin + (delta, q, ang)
        qfloor = min_quality if rnd < quality_rounds else (
            min(min_quality, 0.5) if rnd < angle_rounds else 0.0)
        if polish is not None:
            qfloor = min_quality
        afloor = min_angle_deg if rnd < angle_rounds else 0.0
        badq = ((ang < afloor) | (q < qfloor)) & ~viol
        if badq.any():
            badq &= ~corner_exempt(ws, tris, min_angle_deg, sharp)
        history.append({"round": rnd, "elements": int(len(tris)), "points": int(ws.n),
                        "delta_max": float(delta.max()), "violators": int(viol.sum()),
                        "bad_quality": int(badq.sum())})
        log.info("round %d: %d elements, delta_max %.4g, %d violators, %d bad-quality",
                 rnd, len(tris), delta.max(), viol.sum(), badq.sum())
        if progress:
            progress("refine", None)
        if not viol.any() and not badq.any():
            if polish is None and qfloor < min_quality and rnd < angle_rounds:
                low = (q < min_quality) & ~corner_exempt(ws, tris, min_angle_deg, sharp)
                if low.any():
                    # converged with the relaxed floor: a few rounds at the full floor,
                    # kept only if they end well (see POLISH_ROUNDS)
                    polish = (rnd, _copy_workset(ws), (tris, comp, delta), len(tris))
                    log.info("round %d: %d triangles below the quality floor %g; polishing",
                             rnd, int(low.sum()), min_quality)
                    badq = low
            if not badq.any():
                return tris, comp, delta
        if polish is not None and (rnd - polish[0] >= POLISH_ROUNDS or viol.any()
                                   or len(tris) > POLISH_GROWTH * polish[3]):
            log.info("quality polish abandoned in round %d; the mesh of round %d is kept",
                     rnd, polish[0])
            _restore_workset(ws, polish[1])
            return polish[2]
        if len(tris) > max_elements:
            raise BudgetError(f"refinement exceeded the element budget ({len(tris)} > "
                              f"{max_elements} elements); raise --max-elements or the threshold")
        n_before = ws.n
        with ctx.timed("insertion"):
            new_c = _insert_refinement_points(ws, ctx, tris, comp, viol, badq, afloor, sharp,
                                              longest=longest)
        if ws.n == n_before:
            raise MeshingError(f"refinement stalled in round {rnd} with {int(viol.sum())} "
                               f"elements at delta >= {thr:g} and {int(badq.sum())} below the "
                               "quality floor")
        if rnd < smooth_rounds:
            new = np.zeros(ws.n, bool)
            new[n_before:] = True
            new[new_c] = True
            tris = triangulate(ws, ctx)
            active = _rings(tris, new, 2)
            tris = smooth(ws, ctx, tris, iters=2, active=active, retriangulate_every=2)
        else:
            tris = None
    raise MeshingError(f"refinement did not converge in {max_rounds} rounds")


#: after the repair has converged with the relaxed quality floor, at most this many rounds
#: try the full floor again; they are kept only if they converge without a delta violator
#: and within ``POLISH_GROWTH`` x the elements (otherwise the converged mesh is kept)
POLISH_ROUNDS = 6
POLISH_GROWTH = 1.05


def _below_floor(ws: WorkSet, ctx: Context, tris, min_quality: float, min_angle: float) -> int:
    """How many triangles are below the quality floor away from exempt sharp corners."""
    q = quality(ws.P, tris)
    low = q < min_quality
    if low.any():
        low &= ~corner_exempt(ws, tris, min_angle, sharp_corners(ws, ctx))
    return int(low.sum())


def _copy_workset(ws: WorkSet) -> WorkSet:
    return WorkSet(**{f: (getattr(ws, f).copy() if isinstance(getattr(ws, f), np.ndarray)
                          else getattr(ws, f)) for f in ws.__dataclass_fields__})


def _restore_workset(ws: WorkSet, saved: WorkSet) -> None:
    for f in ws.__dataclass_fields__:
        setattr(ws, f, getattr(saved, f))


def _too_long(P: np.ndarray, tris: np.ndarray, max_edge: float | None) -> np.ndarray:
    """The triangles with an edge longer than ``max_edge`` (none if it is None)."""
    if max_edge is None:
        return np.zeros(len(tris), bool)
    return side_lengths(P, tris).max(axis=1) > max_edge


def _insert_refinement_points(ws: WorkSet, ctx: Context, tris, comp, viol, badq,
                              afloor: float, sharp: np.ndarray, longest=None) -> np.ndarray:
    """One round's new nodes; returns the ids of the nodes that split constraint edges.

    MOR: each violator's edge with the largest composition jump is split (on its curve if it
    is a constraint edge). GOR: bad triangles get an off-center; one that encroaches a
    constraint edge, or falls outside, splits that edge instead (Ruppert). Edges at the
    ``sharp`` corners (fixed vertices, found once per loop) are split on concentric shells.
    """
    skeys, sorder = _constraint_index(ws)
    split_c = []
    cand, cand_min, cand_clash = [], [], []
    if viol.any():
        tv = tris[viol]
        cv = comp[tv]  # (k, 3, m)
        jumps = np.stack([np.abs(cv[:, (k + 1) % 3] - cv[:, (k + 2) % 3]).max(axis=1)
                          for k in range(3)], axis=1)
        lens = side_lengths(ws.P, tv)
        kk = (jumps + 1e-9 * lens / lens.max()).argmax(axis=1)
        if longest is not None and longest.any():  # too long: split the longest edge
            kk = np.where(longest[viol], lens.argmax(axis=1), kk)
        a = tv[np.arange(len(tv)), (kk + 1) % 3]
        b = tv[np.arange(len(tv)), (kk + 2) % 3]
        ek, first = np.unique(edge_keys(a, b), return_index=True)
        a, b = a[first], b[first]
        ci = _lookup(skeys, sorder, ek)
        split_c.append(ci[ci >= 0])
        free = ci < 0
        elen = np.hypot(*(ws.P[a[free]] - ws.P[b[free]]).T)
        cand.append(0.5 * (ws.P[a[free]] + ws.P[b[free]]))
        cand_min.append(0.05 * elen)
        cand_clash.append(0.5 * elen)
    if badq.any():
        # a constraint edge already encroached by its own triangle (obtuse opposite angle) is
        # split first (Ruppert); its triangle gets no off-center this round
        tb = tris[badq]
        ang = triangle_angles(ws.P, tb)
        enc_own = np.full(len(tb), False)
        for k in range(3):
            ci = _lookup(skeys, sorder, edge_keys(tb[:, (k + 1) % 3], tb[:, (k + 2) % 3]))
            hit = (ci >= 0) & (ang[:, k] > 90.0)
            split_c.append(ci[hit])
            enc_own |= hit
        badq = badq.copy()
        badq[np.flatnonzero(badq)[enc_own]] = False
    if badq.any():
        cc, r = _off_centers(ws.P, tris[badq], max(afloor, 20.0) + 2.0)
        enc = _encroached(ws, cc, r)
        split_c.append(enc[enc >= 0])
        cc, r = cc[enc < 0], r[enc < 0]
        inside = ctx.inside(cc) if len(cc) else np.zeros(0, bool)
        if (~inside).any():  # outside but not encroaching: split the nearest constraint edge
            split_c.append(_nearest_constraint(ws, cc[~inside]))
        cand.append(cc[inside])
        cand_min.append(0.3 * r[inside])
        cand_clash.append(r[inside])
    sc = np.unique(np.concatenate(split_c)) if split_c else np.zeros(0, np.int64)
    new_c = split_constraint_edges(ws, ctx, sc, where=shell_split(ws, ctx, sharp))
    if cand:
        pts = np.concatenate(cand)
        keep = thin_candidates_mask(ws, pts, np.concatenate(cand_min), np.concatenate(cand_clash))
        add_free_points(ws, pts[keep])
    return new_c


def _rings(tris: np.ndarray, mask: np.ndarray, k: int) -> np.ndarray:
    out = mask.copy()
    for _ in range(k):
        hit = any_corner(out, tris)
        out[tris[hit].ravel()] = True
    return out


def _off_centers(P, t, angle_deg: float):
    """Üngör's off-centers: on the shortest edge's bisector, no farther than needed.

    The point x makes the triangle (p, q, x) on the shortest edge pq have its apex angle
    equal to ``angle_deg``; where the circumcenter is nearer, it is used (Ruppert). Off-centers
    give fewer Steiner points and end sooner than circumcenters. Returns (points, radius),
    the radius being the distance from the point to the shortest edge's ends: the radius of
    the empty circle it is inserted at (for spacing checks).
    """
    cc, r = circumcircles(P, t)
    p3 = P[t]
    ln = np.stack([np.linalg.norm(p3[:, (k + 2) % 3] - p3[:, (k + 1) % 3], axis=1) for k in range(3)], 1)
    k = ln.argmin(axis=1)
    i = np.arange(len(t))
    p = p3[i, (k + 1) % 3]
    q = p3[i, (k + 2) % 3]
    m = 0.5 * (p + q)
    l = ln[i, k]
    d = cc - m
    dc = np.linalg.norm(d, axis=1)
    h = l / (2.0 * np.tan(np.radians(angle_deg) / 2.0))
    use = (h < dc) & (dc > 0)
    out = cc.copy()
    out[use] = m[use] + (d[use] / dc[use, None]) * h[use, None]
    return out, np.linalg.norm(out - p, axis=1)


def _encroached(ws: WorkSet, pts: np.ndarray, r: np.ndarray) -> np.ndarray:
    """Index of a constraint edge whose diametral circle contains each point, or -1."""
    out = np.full(len(pts), -1, np.int64)
    if len(pts) == 0 or len(ws.E) == 0:
        return out
    a, b = ws.P[ws.E[:, 0]], ws.P[ws.E[:, 1]]
    mid = 0.5 * (a + b)
    half = 0.5 * np.hypot(*(b - a).T)
    k = min(8, len(mid))
    d, j = cKDTree(mid).query(pts, k=k)
    d, j = d.reshape(len(pts), k), j.reshape(len(pts), k)
    inside = d < half[j] * (1 - 1e-12)
    anyin = inside.any(axis=1)
    out[anyin] = j[anyin, inside[anyin].argmax(axis=1)]
    return out


def _nearest_constraint(ws: WorkSet, pts: np.ndarray) -> np.ndarray:
    if len(pts) == 0:
        return np.zeros(0, np.int64)
    mid = 0.5 * (ws.P[ws.E[:, 0]] + ws.P[ws.E[:, 1]])
    return cKDTree(mid).query(pts)[1].astype(np.int64)


# --------------------------------------------------------------------------- output
def _curve_problems(ws: WorkSet, ctx: Context, local: Mesh, scale: float) -> list[str]:
    """The mesh against the domain's curves (:mod:`hetmesh.tri.verify`): every boundary and
    interface edge within the chord tolerance of its curve, chord by chord; the mesh's
    boundary edges exactly the outer loop's and the holes' (no hole in the mesh, nothing
    outside); its area the domain's up to the circular segments of the boundary chords.
    Lengths in the messages are multiplied by ``scale`` (the frame's: user units)."""
    tol = ctx.chord_tol if ctx.chord_tol is not None else CHORD_TOL * ctx.domain.diameter
    batch, et = ctx.domain.curve_batch, edge_params(ws, ctx)
    out = chord_problems(batch, ws.ecurve, et, tol,
                         names=[ci.name for ci in ctx.domain.curves], scale=scale)
    bnd = ctx.boundary_curve[ws.ecurve]
    perimeter = float(batch.length[ctx.boundary_curve].sum())
    out += coverage_problems(local.boundary_edges, ws.E[bnd], float(local.area),
                             ctx.domain.area, float(chord_areas(batch, ws.ecurve[bnd],
                                                                et[bnd]).sum()),
                             node_area=ON_CURVE_TOL * ctx.domain.diameter * perimeter,
                             scale=scale)
    return out


def finish(ws: WorkSet, ctx: Context, tris, comp, delta, frame, *, threshold, min_angle_deg,
           check_delta=True) -> tuple[Mesh, MeshStats]:
    """Verify every claim on the final mesh; build the :class:`Mesh` (user coordinates) and
    its statistics.

    Claims checked: a valid triangulation (:meth:`Mesh.problems`), every boundary and
    interface edge an edge of it (conforming) and within the chord tolerance
    (``ctx.chord_tol``) of its curve, chord by chord; its boundary exactly the domain's
    boundary edges and its area the domain's up to the boundary chords
    (:mod:`hetmesh.tri.verify`), delta_max < delta_0 strictly, curve nodes on their curves, and
    for a feature-tree field no element crossing a subregion boundary
    (:func:`hetmesh.tri.discontinuity.crossing_elements`; the elements get their subregion id as
    cell data ``subregion``). A failure raises :class:`~hetmesh.errors.VerificationError`.
    The statistics also get ``delta_max_dense``, from the order-4 lattice of every element
    (:func:`hetmesh.metrics.delta_dense`; each element in its own subregion).
    """
    P = ws.P
    q, ang = quality_and_angle(P, tris)
    try:  # checked in local coordinates: no loss of precision far from 0
        local = Mesh(P, tris)
    except MeshDataError as exc:  # our own arrays: not the user's fault
        raise VerificationError(f"the mesh failed verification: {exc}") from exc
    problems = local.problems()
    missing = ~local.has_edges(ws.E)
    if missing.any():
        problems.append(f"{int(missing.sum())} boundary or interface edges are not mesh edges")
    problems += _curve_problems(ws, ctx, local, frame.scale)
    if check_delta and delta.max() >= threshold:
        problems.append(f"delta_max {delta.max():.6g} >= threshold {threshold:g}")
    if _too_long(P, tris, None if ctx.max_edge is None else
                 ctx.max_edge / (1.0 - MAX_EDGE_MARGIN)).any():
        problems.append(f"an edge is longer than max_size {ctx.h_max * frame.scale:g}")
    on = ws.vcurve >= 0
    if on.any():
        off = 0.0
        for c in np.unique(ws.vcurve[on]):
            s = np.flatnonzero(ws.vcurve == c)
            off = max(off, float(np.hypot(*(ctx.curves[c].point(ws.vt[s]) - P[s]).T).max()))
        if off > ON_CURVE_TOL * ctx.domain.diameter:
            problems.append(f"boundary nodes are off their curve by {off * frame.scale:.3g}")
    cell_data = {"delta": delta, "quality": q}
    if has_subregions(ctx.field):
        cell_data["subregion"] = element_subregions(ctx.field, P, tris)
        cross = crossing_elements(ctx.field, P, tris, ctx.domain.curve_batch,
                                  tol=2 * FIT_TOL * ctx.domain.diameter,
                                  regions=cell_data["subregion"])
        if cross.any():
            problems.append(f"{int(cross.sum())} elements cross a material discontinuity")
    if problems:
        raise VerificationError("the mesh failed verification: " + "; ".join(problems))
    low = ang < min_angle_deg - 1e-9
    if low.any():
        low &= ~corner_exempt(ws, tris, min_angle_deg, sharp_corners(ws, ctx))
        if low.any():
            log.warning("%d triangles are below the minimum angle %g (smallest %.2f degrees): "
                        "the angle refinement was stopped to keep the loop finite",
                        int(low.sum()), min_angle_deg, float(ang.min()))
    interfaces = ws.E[~ctx.boundary_curve[ws.ecurve]]
    mesh = Mesh(points=frame.to_user(P), cells=tris, regions=local.pieces(interfaces),
                facets=ws.E, facet_markers=ws.ecurve + 1,
                marker_names={i + 1: ci.curve.name or ci.owner  # one group per name
                              for i, ci in enumerate(ctx.domain.curves)},
                named_points=_named_nodes(P, ctx.domain),
                point_data={name: comp[:, k] for k, name in enumerate(ctx.field.constituents)},
                cell_data=cell_data)
    dense = delta_dense(ctx.field, P, tris, regions=cell_data.get("subregion"))
    return mesh, statistics(P, tris, delta, quality=q, angle=ang, dense=dense)


def _named_nodes(P: np.ndarray, domain) -> dict[str, int]:
    """The node at each named point of ``domain`` (fixed vertices; local coordinates)."""
    out = {}
    for name, xy in domain.points.items():
        d = np.hypot(*(P - np.asarray(xy, np.float64)).T)
        i = int(np.argmin(d))
        if d[i] <= ON_CURVE_TOL * domain.diameter:
            out[name] = i
    return out


# --------------------------------------------------------------------------- the pipeline
#: node placements of MOR, by ``method`` name
#: the CVT start that :func:`generate`'s ``"auto"`` tries besides the default 0.9
DENSE_START = 1.3
PLACEMENTS = {"cvt": place_cvt, "layers": place_layers,
              "cvt-dense": functools.partial(place_cvt, start=DENSE_START)}


#: ``method`` values of :func:`generate`: ``"auto"`` chooses (see :func:`_candidates`)
METHODS = ("auto", "layers", "cvt")
#: with ``method="auto"``, a model whose a-priori estimate is at most this many elements is
#: meshed from both placements and the better mesh kept (:func:`_better`): a few tenths of
#: a second more, and on geometry-dominated or bumpy models up to 5 x fewer elements
COMPARE_BELOW = 50_000
#: the exchange rate of :func:`_better`: 0.005 of mean quality is worth 10 % of the elements
QUALITY_WEIGHT = math.log(1.1) / 0.005


def _candidates(method: str, ctx: Context, est: float) -> list[str]:
    """The placements to try, in order. ``"auto"`` tries both on small models, and on
    models of more than two constituents always: their rows follow one constituent's level
    curves (:func:`_row_constituent`), which bound the others' variation only where they
    share level curves, and the CVT placement may be the better start."""
    if method == "auto":
        many = len(ctx.field.constituents) > 2
        return ["layers", "cvt", "cvt-dense"] if est <= COMPARE_BELOW or many else ["layers"]
    return [method]


def _row_constituent(field, domain) -> int:
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
    :data:`QUALITY_WEIGHT` (each 0.005 of mean quality worth 10 % of the elements; a
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
    placement ``method``; fills ``history`` and ``timings``; returns ``(mesh, stats)``."""
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
            tris, comp, delta = optimize_mesh(ws, ctx, tris, comp, delta, sampling=sampling,
                                              min_angle_deg=min_angle)
            low = _below_floor(ws, ctx, tris, min_quality, min_angle)
            if low:  # the few the smoothing left: repair them, then smooth again
                saved, kept = _copy_workset(ws), (tris, comp, delta)
                extra: list = []  # the rounds of this repair, in the history if it is kept
                try:
                    tris, comp, delta = repair(ws, ctx, min_angle_deg=min_angle,
                                               min_quality=min_quality, sampling=sampling,
                                               max_elements=max_elements, history=extra,
                                               smooth_rounds=0)
                    tris, comp, delta = optimize_mesh(ws, ctx, tris, comp, delta,
                                                      sampling=sampling,
                                                      min_angle_deg=min_angle)
                    after = _below_floor(ws, ctx, tris, min_quality, min_angle)
                except MeshingError:
                    after = low
                if after >= low or len(tris) > POLISH_GROWTH * len(kept[0]):
                    _restore_workset(ws, saved)
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
    return mesh, stats


def generate(model, threshold: float, *, min_angle: float = 30.0, max_size: float | None = None,
             max_elements: int = DEFAULT_MAX_ELEMENTS, sampling: str = "vertices",
             method: str = "auto", seed: int = 0, min_quality: float = 0.6,
             optimize: bool = True, chord_tol: float = CHORD_TOL,
             row_spacing: float = DEFAULT_ROW_SPACING, progress=None) -> Result:
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
    method : "auto" (default), "layers" (nodes on iso-composition curves) or "cvt" (the
        paper's CVT start). "auto" meshes from the layers placement and, where the model is
        small (a-priori estimate up to 50,000 elements), from the CVT placement too (at 0.9
        and at 1.3 x the density's node count: ``"cvt"`` and ``"cvt-dense"``), and
        keeps the best mesh (the lower ``Ne exp(-19 q_avg)``: each 0.005 of mean quality
        is worth 10 % of the elements);
        ``Result.options["placements"]`` has both outcomes and ``["method"]`` the one kept.
    seed : random seed (same input and seed, same mesh).
    min_quality : quality floor q(T) (Eq. 17) enforced by the refinement.
    optimize : after the refinement, raise the element quality by smoothing and edge flips
        that keep delta(T) < threshold and never lower a node star's minimum quality
        (:func:`hetmesh.tri.optimize.optimize`); same nodes and elements.
    chord_tol : the largest distance between a curved boundary or interface curve and any
        of its chords (the mesh edges along it), relative to the domain's diameter, in
        [1e-7, 0.05]; verified chord by chord.
    row_spacing : the step in composition between the rows of nodes of the layers
        placement, as a fraction of ``threshold``, in [0.3, 0.99]. The default 0.85 leaves
        every element some slack that the quality pass spends on shape; 0.985 gives the
        fewest elements (most of them just under the threshold) at a lower mean quality.

    If the layers placement fails on a model (an internal error of the row tracing or a
    mesh that fails verification), the run starts again from the CVT placement, logs a
    warning with the reason and records it in ``Result.options["fallbacks"]``.

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
                              seed=seed, chord_tol=chord_tol, row_spacing=row_spacing)
    if method not in METHODS:
        raise OptionError(f"method {method!r} is not one of {', '.join(METHODS)}")
    check_sampling(model.material, sampling)
    timings: dict = {}
    t0 = time.perf_counter()
    model = embed_discontinuities(model)
    ctx, frame = prepare(model, threshold, max_size, chord_tol, row_spacing=row_spacing)
    est = dens.estimate_elements(ctx.field, ctx.domain, threshold, ctx.h_max)
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
    queue = _candidates(method, ctx, est)
    while queue:
        name = queue.pop(0)
        history: list = []
        tm = dict(timings)
        t1 = time.perf_counter()
        try:
            mesh, stats = _mesh_with(name, ctx, frame, threshold, chord_tol, history, tm, **run)
        except FALLBACK_ERRORS as exc:
            first_error = first_error or exc
            tried[name] = {"error": _cause(exc)}
            if name != "cvt" and "cvt" not in queue and "cvt" not in tried \
                    and not isinstance(exc, BudgetError):
                # the row placement could not handle this model: start from the CVT placement
                log.warning("the %s placement failed (%s); meshing from the CVT placement "
                            "instead", name, _cause(exc))
                fallbacks.append({"from": name, "to": "cvt", "cause": _cause(exc),
                                  "stage": "refinement" if history else "placement"})
                queue.append("cvt")
            continue
        tried[name] = {"elements": stats.n_elements, "q_avg": stats.q_avg,
                       "seconds": time.perf_counter() - t1}
        if outcome is None or _better(stats, outcome[1]):
            outcome = (mesh, stats, history, tm, name)
    if outcome is None:
        raise first_error
    mesh, stats, history, timings, method = outcome
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
                row_spacing=float(row_spacing))
    return Result(mesh=mesh, stats=stats, threshold=threshold, history=history,
                  timings=timings, options=opts, model=model)


def mesh_statistics(mesh: Mesh, model, sampling: str = "vertices") -> MeshStats:
    """Recompute q and delta of any mesh from the model (Eqs. 1, 16-18); with a feature-tree
    field each element is evaluated in the subregion of its centroid."""
    if sampling not in SAMPLINGS:
        raise OptionError(f"sampling {sampling!r} is not one of {', '.join(SAMPLINGS)}")
    fld = model.material
    regions = (element_subregions(fld, mesh.points, mesh.triangles) if has_subregions(fld)
               else None)
    delta = element_delta(fld, mesh.points, mesh.triangles, sampling, regions=regions)
    return statistics(mesh.points, mesh.triangles, delta)
