"""The working point set of the mesher and the local operations on it.

A :class:`WorkSet` holds the points and what each one is tied to: a boundary or interface
curve (with its parameter), a fixed corner or named point, a composition level (for nodes
placed on iso-composition curves), or nothing (free interior nodes). The triangulation is
always recomputed from it (constrained Delaunay), so the operations here only add or move
points: splitting constraint edges on their true curve, inserting free points, and the
conforming CVT smoothing of :mod:`hetmesh.tri.cvt`.
"""

from __future__ import annotations

import time
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
from scipy.spatial import cKDTree

from .. import density as dens
from ..material.field import field_dim, thread_safe
from ..parallel import BLOCK, block_concat
from ..topology import any_corner, points_near, unique
from . import cvt
from .cdt import constrained_delaunay, patch

if TYPE_CHECKING:
    from ..material.field import MaterialField
    from .geometry import Curve, Domain
    from .geosize import BoundarySize
    from .grading import GradientFloor
    from .sizecap import VariationCap

__all__ = ["WorkSet", "Context", "triangulate", "lineage", "split_constraint_edges",
           "add_free_points", "drop_nodes", "smooth"]

FREE, FIXED = -2, -1


@dataclass
class Context:
    """Everything the local operations need to know about the model (read-only)."""

    domain: Domain
    curves: list[Curve]  # index = curve id
    closed: np.ndarray  # (C,) bool: curve start == end
    boundary_curve: np.ndarray  # (C,) bool: outer or hole (not interface)
    field: MaterialField
    threshold: float
    h_max: float
    scalar: int | None = None  # constituent whose level sets carry nodes (layers)
    chord_tol: float | None = None  # largest sagitta of a curved boundary or interface chord
    #: smallest element size the placement aims at: where |grad f| blows up (sqrt(x) at
    #: x = 0, a kink) the density is capped at g = delta_0 / h_min; the delta-driven
    #: refinement then splits only where the composition really varies
    h_min: float = 0.0
    #: a local cap on |grad f| from the composition's sampled variation (a
    #: :class:`~hetmesh.tri.sizecap.VariationCap`), or None
    variation_cap: VariationCap | None = None
    #: a local floor on |grad f| that grades the material sizes (a
    #: :class:`~hetmesh.tri.grading.GradientFloor`), or None
    gradient_floor: GradientFloor | None = None
    #: step in composition between the rows of the layers placement, over delta_0
    row_spacing: float = 0.985
    #: the geometric size bound near small boundary features (a
    #: :class:`~hetmesh.tri.geosize.BoundarySize`), or None
    geo_size: BoundarySize | None = None
    #: the longest edge allowed (``max_size`` given), or None: no bound beyond ``h_max``'s
    #: placement size
    max_edge: float | None = None
    clock: dict = field(default_factory=dict)  # seconds spent per kind of work (phase split)

    @contextmanager
    def timed(self, key: str):
        t0 = time.perf_counter()
        try:
            yield
        finally:
            self.clock[key] = self.clock.get(key, 0.0) + time.perf_counter() - t0

    def inside(self, pts: np.ndarray) -> np.ndarray:
        return self.domain.contains(pts)

    @property
    def serial(self) -> bool:
        """Whether pointwise work on the field runs block after block in the calling thread
        (a field that is not :func:`~hetmesh.material.field.thread_safe`) rather than in
        parallel threads; the values are the same either way."""
        return not thread_safe(self.field)

    @property
    def g_cap(self) -> float:
        """The largest gradient norm the size and density fields use (inf without h_min)."""
        return self.threshold / self.h_min if self.h_min > 0 else np.inf

    def g(self, pts: np.ndarray) -> np.ndarray:
        """The gradient norm the placement sizes by: :meth:`g_capped`, raised to the
        :attr:`gradient_floor` where one is set (graded sizes)."""
        g = self.g_capped(pts)
        if self.gradient_floor is not None:
            g = np.maximum(g, self.gradient_floor(pts))
        return g

    def g_capped(self, pts: np.ndarray) -> np.ndarray:
        """|grad f| (Eq. 5), capped at :attr:`g_cap` (also where it is nan or inf).

        The norm is :func:`hetmesh.density.gradient_norm`'s, the same numbers by elementwise
        passes over the constituents (its reductions over the short axes cost twice the
        gradient itself on a million points); by blocks of points."""
        if len(pts) > BLOCK:
            return block_concat(lambda s: self.g_capped(pts[s]), len(pts), serial=self.serial)
        gr = self.field.gradient(pts)
        g = None
        for j in range(gr.shape[1]):
            gx, gy = gr[:, j, 0], gr[:, j, 1]
            gj = np.sqrt(gx * gx + gy * gy)
            g = gj if g is None else np.maximum(g, gj, out=g)
        if g is None:
            g = np.zeros(len(gr))
        return np.minimum(np.nan_to_num(g, nan=np.inf, posinf=np.inf), self.cap_at(pts))

    def cap_at(self, pts: np.ndarray) -> np.ndarray:
        """The cap on |grad f| at ``pts``: :attr:`g_cap` and the variation cap."""
        if self.variation_cap is None:
            return np.full(len(pts), self.g_cap)
        return np.minimum(self.variation_cap(pts), self.g_cap)

    def h_at(self, pts: np.ndarray):
        """The largest element size at ``pts``: ``h_max``, or the geometric bound
        ``min(h_max, h_geo)`` (:mod:`hetmesh.tri.geosize`) where the model has small features."""
        if self.geo_size is None:
            return self.h_max
        return self.geo_size(pts)

    def rho(self, pts: np.ndarray) -> np.ndarray:
        if len(pts) > BLOCK:
            return block_concat(lambda s: self.rho(pts[s]), len(pts), serial=self.serial)
        return dens.density(self.g(pts), self.h_at(pts), self.threshold,
                            field_dim(self.field))  # Eq. (9)

    # the scalar composition whose level curves carry node rows (two constituents)
    def f(self, pts: np.ndarray) -> np.ndarray:
        return self.field.composition(pts)[:, self.scalar]

    def grad_f(self, pts: np.ndarray) -> np.ndarray:
        return self.field.gradient(pts)[:, self.scalar, :]


@dataclass
class WorkSet:
    P: np.ndarray  # (N, 2)
    vcurve: np.ndarray  # (N,) curve id, FIXED or FREE
    vt: np.ndarray  # (N,) parameter on vcurve (nan otherwise)
    pinned: np.ndarray  # (N,) bool: never moved
    level: np.ndarray  # (N,) composition level carried (nan otherwise)
    E: np.ndarray  # (K, 2) constraint edges
    ecurve: np.ndarray  # (K,) curve of every constraint edge
    #: the last triangulation and copies of the points and edges it was made of
    #: (:func:`triangulate`)
    cdt: tuple | None = field(default=None, repr=False, compare=False)

    @property
    def n(self) -> int:
        return len(self.P)


def workset_from_pslg(pslg, pinned_t=None) -> WorkSet:
    """A work set from a PSLG; curve nodes whose parameter is in ``pinned_t[curve]`` stay put."""
    n = len(pslg.vertices)
    vc = np.array(pslg.vertex_curve, np.int64)
    vt = np.array(pslg.vertex_t, float)
    pinned = vc == FIXED
    for k, tk in enumerate(pinned_t or ()):
        if len(tk):
            s = vc == k
            pinned[s] |= np.isin(vt[s], tk)
    return WorkSet(P=np.array(pslg.vertices, float), vcurve=vc, vt=vt, pinned=pinned,
                   level=np.full(n, np.nan), E=np.array(pslg.edges, np.int64),
                   ecurve=np.array(pslg.edge_curve, np.int64))


def edge_params(ws: WorkSet, ctx: Context) -> np.ndarray:
    """Parameters (K, 2) of the two ends of every constraint edge on that edge's curve."""
    E, c = ws.E, ws.ecurve
    out = np.empty(E.shape)
    for j in (0, 1):
        v = E[:, j]
        own = ws.vcurve[v] == c
        out[own, j] = ws.vt[v[own]]
        oth = np.flatnonzero(~own)
        for k in oth:  # edges ending at a curve end point (few): parameter 0 or 1
            cu = ctx.curves[c[k]]
            w = E[k, 1 - j]
            if ctx.closed[c[k]]:
                other = ws.vt[w] if ws.vcurve[w] == c[k] else 0.5
                out[k, j] = 0.0 if other < 0.5 else 1.0
            else:
                p = ws.P[E[k, j]]
                d0 = np.hypot(*(p - cu.start))
                d1 = np.hypot(*(p - cu.end))
                out[k, j] = 0.0 if d0 <= d1 else 1.0
    return out


def curve_bounds(ws: WorkSet, ctx: Context, ids: np.ndarray | None = None
                 ) -> tuple[np.ndarray, np.ndarray]:
    """For every curve vertex (or the vertices ``ids``, sorted), the parameters of its
    neighbours along the curve."""
    et = edge_params(ws, ctx)
    k = ws.n if ids is None else len(ids)
    lo = np.full(k, -np.inf)
    hi = np.full(k, np.inf)
    for j in (0, 1):
        v, tv, to = ws.E[:, j], et[:, j], et[:, 1 - j]
        own = ws.vcurve[v] == ws.ecurve
        if ids is not None:  # the edges at the vertices asked for, by their place in ids
            pos = np.minimum(np.searchsorted(ids, v), max(k - 1, 0))
            own &= (ids[pos] == v) if k else np.zeros(len(v), bool)
            v = pos
        up = own & (to > tv)
        np.minimum.at(hi, v[up], to[up])
        dn = own & (to < tv)
        np.maximum.at(lo, v[dn], to[dn])
    vt = ws.vt if ids is None else ws.vt[ids]
    lo = np.where(np.isfinite(lo), lo, vt)
    hi = np.where(np.isfinite(hi), hi, vt)
    return lo, hi


def chord_window(ws: WorkSet, ctx: Context, lo: np.ndarray, hi: np.ndarray,
                 ids: np.ndarray | None = None):
    """The parameters a curve vertex may slide to without a chord to its neighbours (at
    ``lo`` and ``hi``, :func:`curve_bounds`) exceeding the chord tolerance ``ctx.chord_tol``
    (sagitta, exact for arcs): ``(t_min, t_max)``, for every vertex or the vertices ``ids``
    (``lo``, ``hi`` then theirs). Where the window is empty (a chord already too long on
    both sides) the vertex keeps its parameter. Unbounded for segments and without a
    tolerance."""
    k = ws.n if ids is None else len(ids)
    t_min, t_max = np.full(k, -np.inf), np.full(k, np.inf)
    vc = ws.vcurve if ids is None else ws.vcurve[ids]
    on = vc >= 0
    if ctx.chord_tol is None or not on.any():
        return t_min, t_max
    batch = ctx.domain.curve_batch
    step_t = batch.max_step(ctx.chord_tol) / np.array([c.length for c in ctx.curves])
    st = step_t[np.where(on, vc, 0)]
    t_min = np.where(on, hi - st, -np.inf)
    t_max = np.where(on, lo + st, np.inf)
    empty = t_min > t_max
    vt = ws.vt if ids is None else ws.vt[ids]
    t_min[empty] = t_max[empty] = vt[empty]
    return t_min, t_max


def chord_violators(ws: WorkSet, ctx: Context, t_new: np.ndarray, moving: np.ndarray) -> np.ndarray:
    """The moving curve vertices (mask) an end of a chord that would exceed the chord
    tolerance with the curve parameters ``t_new``: neighbours moved at the same time can
    stretch a chord that each move alone (:func:`chord_window`) kept short. Reverting them
    to their old parameters restores chords that were within the tolerance before."""
    bad = np.zeros(ws.n, bool)
    if ctx.chord_tol is None or not moving.any():
        return bad
    et = edge_params(ws, ctx)
    for j in (0, 1):
        v = ws.E[:, j]
        own = (ws.vcurve[v] == ws.ecurve) & moving[v]
        et[own, j] = t_new[v[own]]
    step_t = (ctx.domain.curve_batch.max_step(ctx.chord_tol)
              / np.array([c.length for c in ctx.curves]))[ws.ecurve]
    long = np.abs(et[:, 1] - et[:, 0]) > step_t
    for j in (0, 1):
        v = ws.E[long, j]
        bad[v] |= moving[v] & (ws.vcurve[v] >= 0)
    return bad


#: work sets of at least this many points update their triangulation locally where little
#: changed (:func:`hetmesh.tri.cdt.patch`); smaller ones are always rebuilt
PATCH_MIN_POINTS = 1 << 17


def triangulate(ws: WorkSet, ctx: Context) -> np.ndarray:
    """The constrained Delaunay triangulation of the work set's points and constraint edges,
    inside the domain (read-only).

    The last one is kept on the work set beside copies of the points and edges it was made
    of. While they are unchanged it is returned again (the placement's last triangulation
    is the repair loop's first): a comparison instead of a rebuild. On a work set of at
    least :data:`PATCH_MIN_POINTS` points where a few points moved or were added and a few
    constraint edges were split (a refinement round in a million-element mesh), it is
    updated in a window around the changes (:func:`hetmesh.tri.cdt.patch`): the same
    triangles (up to the choice among cocircular points) in another order, for a
    twentieth of the cost. Below that size the full rebuild is cheap, and keeps the
    triangle order, so the meshes, of the versions before local updates.
    """
    c = ws.cdt
    if (c is not None and c[0] is ctx and np.array_equal(c[1], ws.P)
            and np.array_equal(c[2], ws.E)):
        return c[3]
    with ctx.timed("cdt"):
        bmask = ctx.boundary_curve[ws.ecurve]
        up = None
        if c is not None and c[0] is ctx and ws.n >= PATCH_MIN_POINTS:
            up = patch(ws.P, ws.E, bmask, c[1], c[2], c[3])
        if up is None:
            tris = constrained_delaunay(ws.P, ws.E, inside=ctx.inside,
                                        boundary_edges=ws.E[bmask])
            base, rows = tris, None
        else:  # rows kept from the last full rebuild (base), -1 for the window's
            tris, kept = up
            base, prev = c[4], c[5]
            rows = np.full(len(tris), -1, np.int64)
            rows[:len(kept)] = kept if prev is None else prev[kept]
    tris.flags.writeable = False
    ws.cdt = (ctx, ws.P.copy(), ws.E.copy(), tris, base, rows)
    return tris


def lineage(ws: WorkSet, tris: np.ndarray):
    """``(base, rows)`` for the work set's current triangulation ``tris``: the triangles of
    the last full rebuild, and for every triangle its row there (-1 for those made by a
    local update since); a triangle with a row there has not changed (same corners, none of
    them moved). None if ``tris`` is not the current triangulation."""
    c = ws.cdt
    if c is None or c[3] is not tris:
        return None
    return c[4], (np.arange(len(tris)) if c[5] is None else c[5])


def split_constraint_edges(ws: WorkSet, ctx: Context, idx: np.ndarray,
                           where=None) -> np.ndarray:
    """Split constraint edges ``idx`` on their curve, at the parameter midpoint or at
    ``where(idx, et) -> t`` (``et`` the ends' parameters); returns the new vertex ids."""
    idx = unique(idx)
    if idx.size == 0:
        return np.zeros(0, np.int64)
    et = edge_params(ws, ctx)[idx]
    tm = 0.5 * (et[:, 0] + et[:, 1]) if where is None else where(idx, et)
    c = ws.ecurve[idx]
    newp = np.empty((len(idx), 2))
    for cid in unique(c):
        s = c == cid
        newp[s] = ctx.curves[cid].point(tm[s])
    n0 = ws.n
    nid = n0 + np.arange(len(idx))
    b = ws.E[idx, 1].copy()
    ws.P = np.vstack([ws.P, newp])
    ws.vcurve = np.concatenate([ws.vcurve, c])
    ws.vt = np.concatenate([ws.vt, tm])
    ws.pinned = np.concatenate([ws.pinned, np.zeros(len(idx), bool)])
    ws.level = np.concatenate([ws.level, np.full(len(idx), np.nan)])
    ws.E[idx, 1] = nid
    ws.E = np.vstack([ws.E, np.column_stack([nid, b])])
    ws.ecurve = np.concatenate([ws.ecurve, c])
    return nid


def drop_nodes(ws: WorkSet, removed: np.ndarray) -> np.ndarray:
    """Remove the nodes ``removed`` (mask) from ``ws`` in place, no constraint edge using
    them; returns the new id of every kept node by its old id (the entries of the removed
    ones are not ids)."""
    keep = ~removed
    new = np.cumsum(keep) - 1
    ws.P, ws.vcurve, ws.vt = ws.P[keep], ws.vcurve[keep], ws.vt[keep]
    ws.pinned, ws.level = ws.pinned[keep], ws.level[keep]
    ws.E = new[ws.E]
    ws.cdt = None
    return new


def add_free_points(ws: WorkSet, pts: np.ndarray, level: np.ndarray | None = None) -> np.ndarray:
    n0 = ws.n
    k = len(pts)
    ws.P = np.vstack([ws.P, pts])
    ws.vcurve = np.concatenate([ws.vcurve, np.full(k, FREE)])
    ws.vt = np.concatenate([ws.vt, np.full(k, np.nan)])
    ws.pinned = np.concatenate([ws.pinned, np.zeros(k, bool)])
    ws.level = np.concatenate([ws.level, np.full(k, np.nan) if level is None else level])
    return n0 + np.arange(k)


#: the smallest distance :func:`thin_candidates_mask` lets a new point have to any other
MIN_SEPARATION = 1e-12
#: the most candidate pairs one k-d tree query of :func:`thin_candidates_mask`'s clash
#: test looks at
CLASH_PAIRS = 4_000_000


def thin_candidates_mask(ws: WorkSet, cand: np.ndarray, min_dist: np.ndarray,
                         clash_dist: np.ndarray | None = None) -> np.ndarray:
    """Which candidates to keep: away from existing points (``min_dist``) and from each other.

    ``clash_dist`` (default ``min_dist``) separates candidates of the same round: inserting
    two nearby Steiner points at once makes a short edge and a new skinny triangle, which is
    how parallel refinement can cascade; the dropped one is reconsidered next round.
    """
    if clash_dist is None:
        clash_dist = min_dist
    out = np.zeros(len(cand), bool)
    if len(cand) == 0:
        return out
    # never a point on top of another, whatever the spacing (a zero or nan step where the
    # composition is flat or noisy would let exact duplicates through, which the kernel
    # refuses): distances are floored at MIN_SEPARATION (the local frame's diameter is ~1)
    min_dist = np.maximum(np.nan_to_num(np.broadcast_to(min_dist, (len(cand),)), nan=0.0),
                          MIN_SEPARATION)
    clash_dist = np.maximum(np.nan_to_num(np.broadcast_to(clash_dist, (len(cand),)), nan=0.0),
                            MIN_SEPARATION)
    d = nearest_distance(ws.P, cand, float(np.max(min_dist)))
    keep = np.flatnonzero(d > min_dist)
    cand, md = cand[keep], clash_dist[keep]
    if len(cand) < 2:
        out[keep] = True
        return out
    # a candidate yields to an earlier one within either's distance, among its k nearest
    # (deterministic); only those with another candidate within the largest distance can
    tree, near, count = _near_candidates(cand, md)
    # exact copies go first: a point traced many times over (rows that collapse onto one
    # point of a noisy field) would make a cluster the clash test has to look through
    # whole. Copies are among the near ones (distance 0).
    if len(near) > 1:
        _, first = unique(cand[near], axis=0, return_index=True)
        if len(first) < len(near):
            copy = np.ones(len(cand), bool)
            copy[near] = False
            copy[near[first]] = True  # True: not a later copy
            keep, cand, md = keep[copy], cand[copy], md[copy]
            tree, near, count = _near_candidates(cand, md)
    clash = np.zeros(len(cand), bool)
    if len(near):
        # each candidate looks at every other one within its distance: the 6 nearest where
        # there are at most that many (nearly always), else as many as there are (a cluster:
        # the circumcenters of the triangles of a ring of cocircular nodes coincide to 1e-9),
        # by blocks of at most CLASH_PAIRS pairs
        k = np.minimum(np.maximum(count[near], 6), len(cand))
        for kk in unique(k):
            sel = near[k == kk]
            step = max(1, CLASH_PAIRS // int(kk))
            for b0 in range(0, len(sel), step):
                s = sel[b0:b0 + step]
                d, j = tree.query(cand[s], k=int(kk), workers=-1)
                clash[s] = ((j < s[:, None]) & (d < np.minimum(md[s, None], md[j]))).any(axis=1)
    out[keep[~clash]] = True
    return out


def _near_candidates(cand: np.ndarray, md: np.ndarray):
    """A k-d tree of ``cand``, the candidates with another one within their ``md`` and how
    many candidates (themselves included) every candidate has within its ``md``. Where a
    distance is not finite every candidate counts as near, with the count 6 (its 6 nearest
    are looked at): a count of all of them would make the clash test quadratic."""
    tree = cKDTree(cand)
    if np.isfinite(md).all():
        count = tree.query_ball_point(cand, r=md, return_length=True, workers=-1)
        near = np.flatnonzero(count > 1)
    else:
        near = np.arange(len(cand))
        count = np.full(len(cand), 6)
    return tree, near, count


def nearest_distance(points: np.ndarray, query: np.ndarray, reach: float) -> np.ndarray:
    """Distance from every ``query`` point to the nearest of ``points``, exact where it is at
    most ``reach`` (elsewhere it may be any larger value, inf included).

    A few queries among many points (a refinement round's Steiner candidates) do not need
    a k-d tree over all the points: only the points near the queries go into it
    (:func:`hetmesh.mesh.points_near`); the tree's search stops a hair beyond ``reach``.
    """
    pts = points
    if len(pts) == 0:
        return np.full(len(query), np.inf)
    if len(query) * 64 < len(pts) and np.isfinite(reach) and reach >= 0:
        pts = pts[points_near(pts, query, reach)]
        if len(pts) == 0:
            return np.full(len(query), np.inf)
    # a bound a hair above ``reach`` prunes the search for far points (inf there)
    bound = max(float(reach), 0.0) * (1.0 + 1e-9) + 1e-300 if np.isfinite(reach) else np.inf
    d, _ = cKDTree(pts).query(query, distance_upper_bound=bound, workers=-1)
    return d


def project_to_level(ctx: Context, pts: np.ndarray, level: np.ndarray, iters: int = 3,
                     tol: float | None = None):
    """Newton steps along the gradient onto f = level (for nodes on iso-composition curves).

    Every step is capped at ``ctx.h_max``: where the field is nearly flat (a plateau of a
    steep tanh front, |grad f| ~ 1e-20) an uncapped Newton step would throw the point
    arbitrarily far (1e13 domain widths were seen). With ``tol``, also returns whether each
    point ended on its level, |f - level| <= ``tol``, and inside the domain: callers drop
    (or do not move) the points that did not.

    Pointwise, so done by blocks of points (the material field's temporaries stay small).
    """
    if len(pts) > BLOCK:
        tl = np.broadcast_to(tol, level.shape) if tol is not None else None
        return block_concat(lambda s: project_to_level(
            ctx, pts[s], level[s], iters, None if tl is None else tl[s]), len(pts),
            serial=ctx.serial)
    p = pts.copy()
    cap = ctx.h_max
    for _ in range(iters):
        f = ctx.f(p)
        gr = ctx.grad_f(p)
        gx, gy = gr[:, 0], gr[:, 1]
        g2 = gx * gx + gy * gy
        ok = g2 > 1e-30
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            c = (f - level) / g2
            sx = np.where(ok, c * gx, 0.0)
            sy = np.where(ok, c * gy, 0.0)
            ln = np.hypot(sx, sy)
            big = ln > cap
            if big.any():
                r = cap / ln
                sx = np.where(big, sx * r, sx)
                sy = np.where(big, sy * r, sy)
        p = np.column_stack([p[:, 0] - sx, p[:, 1] - sy])
    if tol is None:
        return p
    good = np.abs(ctx.f(p) - level) <= tol
    good[good] = ctx.inside(p[good])
    return p, good


def row_tangent(gr: np.ndarray) -> np.ndarray:
    """Unit tangents ``(N, 2)`` of the level curves with gradients ``gr`` (gradient turned +90°)."""
    nrm = np.linalg.norm(gr, axis=1, keepdims=True)
    return np.column_stack([-gr[:, 1], gr[:, 0]]) / np.maximum(nrm, 1e-300)


def slide_along_rows(ctx: Context, x: np.ndarray, target: np.ndarray, level: np.ndarray,
                     relax: float = 1.0, iters: int = 3) -> np.ndarray:
    """Move row nodes ``x`` towards ``target`` along their row only: the tangential part of
    the move (times ``relax``), then Newton back onto the level curve f = ``level``
    (pointwise: by blocks of points)."""
    if len(x) > BLOCK:
        return block_concat(lambda s: slide_along_rows(ctx, x[s], target[s], level[s], relax,
                                                       iters), len(x), serial=ctx.serial)
    tng = row_tangent(ctx.grad_f(x))
    step = relax * ((target - x) * tng).sum(1, keepdims=True) * tng
    return project_to_level(ctx, x + step, level, iters=iters)


def smooth(ws: WorkSet, ctx: Context, tris: np.ndarray, iters: int = 3,
           active: np.ndarray | None = None, retriangulate_every: int = 1) -> np.ndarray:
    """Conforming density-weighted Lloyd iterations (Sec. 3.2.3); returns the last triangles.

    Free nodes move to their cell's rho-centroid; curve nodes slide along their curve; nodes
    carrying a composition level slide along that level curve (tangential move, then Newton
    back onto it); fixed and pinned nodes stay. ``active`` limits the moves to some vertices.
    The Delaunay connectivity is rebuilt every ``retriangulate_every`` iterations and at the
    end; in between, moves limited to each vertex's star keep the old connectivity valid.
    """
    for it in range(iters):
        with ctx.timed("cvt"):
            _lloyd_step(ws, ctx, tris, active)
        if (it + 1) % retriangulate_every == 0 or it == iters - 1:
            tris = triangulate(ws, ctx)
    return tris


def _lloyd_step(ws: WorkSet, ctx: Context, tris: np.ndarray, active: np.ndarray | None) -> None:
    """One conforming Lloyd move of the work set on the connectivity ``tris`` (see smooth).

    With ``active``, only the triangles around the active vertices and their points are
    looked at, in arrays of their own (the same moves as over the whole mesh: nothing else
    enters them), so a local smoothing in a mesh of millions costs in proportion to it."""
    if active is None:
        sub, U = tris, None
        P, pinned, vcurve, level, vt = ws.P, ws.pinned, ws.vcurve, ws.level, ws.vt
    else:
        sub = tris[any_corner(active, tris)]
        U, loc = unique(sub, return_inverse=True)  # the points these triangles use
        sub = loc.reshape(sub.shape)
        P, pinned, vcurve, level, vt = ws.P[U], ws.pinned[U], ws.vcurve[U], ws.level[U], ws.vt[U]
    cent, mass = cvt.cell_centroids(P, sub, ctx.rho)
    movable = ~pinned & (vcurve != FIXED) & (mass > 0)
    if active is not None:
        movable &= active[U]
    target = cent
    lev = np.isfinite(level) & movable & (vcurve == FREE)
    if lev.any():
        target = target.copy()
        target[lev] = slide_along_rows(ctx, P[lev], cent[lev], level[lev])
    oncurve = movable & (vcurve >= 0)
    if oncurve.any():
        lo, hi = curve_bounds(ws, ctx, U)
        slid, tnew = cvt.slide_on_curves(target, np.where(oncurve, vcurve, -1), vt,
                                         ctx.curves, lo, hi)
        t_min, t_max = chord_window(ws, ctx, lo, hi, U)
        clip = oncurve & ((tnew < t_min) | (tnew > t_max))
        if clip.any():  # a chord would exceed the tolerance: slide only as far as allowed
            tnew = np.where(clip, np.clip(tnew, t_min, t_max), tnew)
            for c in unique(vcurve[clip]):
                s = np.flatnonzero(clip & (vcurve == c))
                slid[s] = ctx.curves[c].point(tnew[s])
        target = np.where(oncurve[:, None], slid, target)
    moved = cvt.limit_to_star(P, sub, target, movable)
    if oncurve.any():
        # keep the parameter of curve nodes consistent with where they ended up
        ok = oncurve & (moved[:, 0] == target[:, 0]) & (moved[:, 1] == target[:, 1])
        vt_new = np.where(ok, tnew, vt)
        back = oncurve & ~ok
        moved[back] = P[back]
        vt_old = ws.vt
        slid_t = ok & (vt_new != vt)
        if U is None:
            ws.vt, moving = vt_new, slid_t
        else:
            ws.vt = vt_old.copy()
            ws.vt[U] = vt_new
            moving = np.zeros(ws.n, bool)
            moving[U] = slid_t
        stretch = chord_violators(ws, ctx, ws.vt, moving)
        if stretch.any():
            ws.vt = np.where(stretch, vt_old, ws.vt)
            st = stretch if U is None else stretch[U]
            moved[st] = P[st]
    if U is None:
        ws.P = moved
    else:
        out = ws.P.copy()
        out[U] = moved
        ws.P = out
