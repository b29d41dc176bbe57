"""The 2D refinement loop: delta-driven insertion (MOR) and Ruppert's refinement (GOR).

:func:`repair` is the loop of the paper's Sec. 3.1 after the node placement: every round
evaluates delta(T) (Eqs. 14-15) and the shape of every triangle, splits each violator's
edge with the largest composition jump (:func:`hetmesh.refinement.largest_jump_edges`; on
its curve if it is a boundary or interface edge), gives every triangle below the angle or
quality floor an off-center (Uengoer) or splits the constraint edge it encroaches
(Ruppert), re-triangulates, and smooths the new nodes locally in the first rounds. It ends
at delta_max < delta_0 with the floors met; the element budget and the stall check of
:mod:`hetmesh.refinement` keep it finite.
"""

from __future__ import annotations

import logging

import numpy as np
from scipy.spatial import cKDTree

from ..errors import MeshingError
from ..mesh import any_corner, edge_keys
from ..metrics import circumcircles, quality, quality_and_angle, side_lengths, triangle_angles
from ..refinement import (
    carried,
    carry,
    cell_delta,
    check_budget,
    check_progress,
    composition_at,
    largest_jump_edges,
    round_record,
)
from ..topology import unique
from .corners import corner_exempt, sharp_corners, shell_split
from .workset import (
    Context,
    WorkSet,
    add_free_points,
    lineage,
    smooth,
    split_constraint_edges,
    thin_candidates_mask,
    triangulate,
)

__all__ = ["repair", "evaluate", "below_floor", "copy_workset", "restore_workset",
           "too_long", "POLISH_ROUNDS", "POLISH_GROWTH"]

log = logging.getLogger(__name__)


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
             at=None, kept=None):
    """Compositions at the nodes and delta(T); ``known`` holds those of the first nodes,
    evaluated where they were then (``at``, their positions then; without it they have not
    moved): only new and moved nodes are evaluated again. ``kept = (src, delta)``: the
    elements with ``src >= 0`` are unchanged since an evaluation that gave them
    ``delta[src]`` (:func:`carried`); only the others are evaluated.

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
            comp[redo] = composition_at(ctx.field, ws.P[redo])
    else:
        comp = composition_at(ctx.field, ws.P)

    def delta_of(rows):
        t = tris if rows is None else tris[rows]
        return (cell_delta(ctx.field, ws.P, t, sampling, comp, ctx.threshold),)

    if kept is None:
        return comp, delta_of(None)[0]
    return comp, carry(kept[0], (kept[1],), delta_of)[0]



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
            src = carried(state, lin)
            comp, delta = evaluate(ctx, ws, tris, sampling, known, known_at,
                                   None if src is None else (src, state[2]))
            known, known_at = comp, ws.P.copy()
            viol = delta >= thr if check_delta else np.zeros(len(tris), bool)
            longest = too_long(ws.P, tris, ctx.max_edge)  # max_size: split the longest edge
            viol |= longest
            if src is None:
                q, ang = quality_and_angle(ws.P, tris)
            else:
                q, ang = carry(src, state[3:],  # called now: binding tris late is safe
                               lambda r: quality_and_angle(ws.P, tris[r]))  # noqa: B023
            state = None if lin is None else lin + (delta, q, ang)
        qfloor = min_quality if rnd < quality_rounds else (
            min(min_quality, 0.5) if rnd < angle_rounds else 0.0)
        if polish is not None:
            qfloor = min_quality
        afloor = min_angle_deg if rnd < angle_rounds else 0.0
        badq = ((ang < afloor) | (q < qfloor)) & ~viol
        if badq.any():
            badq &= ~corner_exempt(ws, tris, min_angle_deg, sharp)
        history.append(round_record(rnd, len(tris), ws.n, delta, viol, badq))
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
                    polish = (rnd, copy_workset(ws), (tris, comp, delta), len(tris))
                    log.info("round %d: %d triangles below the quality floor %g; polishing",
                             rnd, int(low.sum()), min_quality)
                    badq = low
            if not badq.any():
                return tris, comp, delta
        if polish is not None and (rnd - polish[0] >= POLISH_ROUNDS or viol.any()
                                   or len(tris) > POLISH_GROWTH * polish[3]):
            log.info("quality polish abandoned in round %d; the mesh of round %d is kept",
                     rnd, polish[0])
            restore_workset(ws, polish[1])
            return polish[2]
        check_budget(len(tris), max_elements)
        n_before = ws.n
        with ctx.timed("insertion"):
            new_c = _insert_refinement_points(ws, ctx, tris, comp, viol, badq, afloor, sharp,
                                              longest=longest)
        check_progress(n_before, ws.n, rnd, int(viol.sum()), int(badq.sum()), thr)
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



def below_floor(ws: WorkSet, ctx: Context, tris, min_quality: float, min_angle: float) -> int:
    """How many triangles are below the quality floor away from exempt sharp corners."""
    q = quality(ws.P, tris)
    low = q < min_quality
    if low.any():
        low &= ~corner_exempt(ws, tris, min_angle, sharp_corners(ws, ctx))
    return int(low.sum())



def copy_workset(ws: WorkSet) -> WorkSet:
    return WorkSet(**{f: (getattr(ws, f).copy() if isinstance(getattr(ws, f), np.ndarray)
                          else getattr(ws, f)) for f in ws.__dataclass_fields__})



def restore_workset(ws: WorkSet, saved: WorkSet) -> None:
    for f in ws.__dataclass_fields__:
        setattr(ws, f, getattr(saved, f))



def too_long(P: np.ndarray, tris: np.ndarray, max_edge: float | None) -> np.ndarray:
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
        too_long_rows = longest[viol] if longest is not None and longest.any() else None
        a, b = largest_jump_edges(tv, comp, side_lengths(ws.P, tv), too_long_rows)
        ci = _lookup(skeys, sorder, edge_keys(a, b))
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
    sc = unique(np.concatenate(split_c)) if split_c else np.zeros(0, np.int64)
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
    ln = np.stack([np.linalg.norm(p3[:, (k + 2) % 3] - p3[:, (k + 1) % 3], axis=1)
                   for k in range(3)], 1)
    k = ln.argmin(axis=1)
    i = np.arange(len(t))
    p = p3[i, (k + 1) % 3]
    q = p3[i, (k + 2) % 3]
    m = 0.5 * (p + q)
    short = ln[i, k]
    d = cc - m
    dc = np.linalg.norm(d, axis=1)
    h = short / (2.0 * np.tan(np.radians(angle_deg) / 2.0))
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

