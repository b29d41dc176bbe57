"""Post-refinement mesh optimisation: smart smoothing and edge flips that keep every claim.

After the repair loop every element has delta(T) < delta_0 and the angle floor holds; this
pass then raises the element quality q(T) (Eq. 17) at the same nodes and elements:

* **Smart smoothing.** Each node tries two directions: towards its *ideal point* (the mean
  over its triangles of the apex that would make each one equilateral on its opposite edge;
  it follows the local element size, so graded meshes stay graded), with the step fractions
  ``steps``, and up the gradient of its star's summed quality (forward differences), with
  steps ``grad_steps`` times the mean edge length. Free nodes move in the plane; curve nodes
  along their curve (the candidate is projected, its parameter ``vt`` clipped to the middle
  80 % of the interval to the neighbours along the curve, so their order holds, and to the
  window where both its chords stay within the chord tolerance, :func:`refine.chord_window`,
  so that no slide moves the curve farther from the mesh than the placement may; this includes
  the crossings where rows of nodes end on a curve, which the placement keeps in place: moved
  here, under the delta test, they raised q_min on power_plate at 0.05 from 0.659 to 0.759 and
  on fgm_plate from 0.551 to 0.687); nodes of a
  composition row along their level curve (tangential move, then chord-Newton back onto the
  level) and, as a second candidate, freely. A node takes the candidate that raises its
  star's mean quality most among those that keep, for every element of its star,
  (a) a positive orientation, (b) delta(T) < delta_0 (less a relative 1e-3, against
  rounding elsewhere) evaluated exactly as the repair loop does (same sampling; each element in
  its own subregion for feature-tree fields),
  (c) the smallest angle at least the floor or its old value, and (d) the star's minimum
  quality no lower than before. (b) is the costly test: it is made only for each node's best
  geometric candidate, then its next best where that fails.
* **The mean rule** (``keep``; :func:`hetmesh.tri.pipeline.generate` makes one such pass,
  with :data:`KEEP` = 0.8, on the mesh it keeps). Rule (d) raises the worst triangles, but
  it also refuses every move that costs a good triangle a little quality for a larger gain
  of its neighbours, which leaves the mean short of what the same nodes allow. With
  ``keep`` (d) becomes (d'): no triangle of the star falls below the lower of its old
  quality and ``keep``. A triangle below ``keep`` then never loses quality and one above it
  stays above ``keep``, so the mesh's minimum quality after the pass is at least the lower
  of its value before and ``keep``.
* **Independent sets.** Nodes move in sets with no two adjacent (Jones-Plassmann colouring
  by a fixed hash of the node id), so the moves of one set never share an element and are
  checked exactly in parallel (Jacobi within a set, Gauss-Seidel over the sets).
* **Edge flips.** An interior edge that is not a constraint is flipped when the two new
  triangles have a larger minimum quality than the two old ones and keep (a)-(c); the
  flips of one round share no triangle (each triangle takes its best candidate edge). This
  is not a Delaunay re-triangulation on purpose: a Delaunay flip may join nodes of rows two
  levels apart, which breaks delta(T) < delta_0.
* **Active set.** A sweep visits only the nodes with a triangle below ``q_active`` in their
  star; after the first, only those next to a node whose last move gained more than ``wake``
  in star mean quality. This keeps the cost small on large meshes of regular rows. The
  defaults (4 sweeps, ``q_active`` 0.99) were measured against 2 sweeps at 0.9: q_avg +0.002
  to +0.007 on the examples (fgm_plate 0.9385 -> 0.9448, power_plate 0.1 0.9500 -> 0.9566),
  at twice the pass's time (unit_square, 381,656 elements: 0.61 -> 1.22 s); 6 sweeps over
  every node gained under 0.001 more.

The result is re-verified as a whole (orientation and delta_max, with the same computation as
the refinement); should that fail, the input mesh is returned unchanged. Arrays first: the
Python loops run over sweeps, sets and curves, none over nodes or elements. Deterministic:
no random state is used.
"""

from __future__ import annotations

import logging

import numpy as np

from ..delta import element_delta
from ..material.field import element_subregions, has_subregions, thread_safe
from ..mesh import any_corner, edge_keys, edge_order
from ..metrics import signed_area2, triangle_areas2
from ..parallel import block_concat
from ..topology import unique
from .workset import FIXED, FREE, Context, WorkSet, chord_window, curve_bounds, row_tangent

__all__ = ["optimize", "independent_sets", "valid_input", "priority_hash", "DeltaEvaluator"]

log = logging.getLogger(__name__)

SQRT3_2 = 0.5 * np.sqrt(3.0)
DELTA_MARGIN = 1e-3  # relative: moves keep delta(T) < (1 - DELTA_MARGIN) delta_0
#: the mean rule's bound (``optimize(keep=...)``) in :func:`hetmesh.tri.pipeline.generate`'s
#: last pass: no triangle falls below the lower of its quality and this
KEEP = 0.8


# --------------------------------------------------------------------------- helpers
class DeltaEvaluator:
    """delta(T) of element batches, computed the repair loop's way."""

    def __init__(self, ctx: Context, sampling: str):
        self.field = ctx.field
        self.sampling = sampling
        # a hair below delta_0: a mesh re-evaluated elsewhere (user coordinates, another
        # batch) must not see an element this pass put at delta_0 - 1 ulp
        self.thr = ctx.threshold * (1.0 - DELTA_MARGIN)
        self.sub = has_subregions(ctx.field)
        self.max_edge = getattr(ctx, "max_edge", None)

    def comp(self, pts):
        """Compositions at ``pts`` (pointwise: by blocks of points)."""
        return block_concat(lambda s: self.field.composition(pts[s]), len(pts),
                            serial=not thread_safe(self.field))

    def delta(self, X: np.ndarray, C: np.ndarray, reg) -> np.ndarray:
        """delta of triangles with corners ``X (n, 3, 2)`` and corner compositions
        ``C (n, 3, m)``; ``reg`` their subregions (or None)."""
        n = len(X)
        if self.sampling == "vertices" and reg is None:
            d = (C.max(axis=1) - C.min(axis=1)).max(axis=1)
        else:
            tl = np.arange(3 * n).reshape(n, 3)
            d = element_delta(self.field, X.reshape(-1, 2), tl, self.sampling,
                              C.reshape(3 * n, -1), regions=reg, threshold=self.thr)
        if self.max_edge is not None:  # max_size: a move may not make an edge too long
            e = np.sqrt(((X - X[:, [1, 2, 0]]) ** 2).sum(axis=2)).max(axis=1)
            d = np.where(e > self.max_edge, np.inf, d)
        return d

    def full(self, P, tris):
        comp = self.comp(P)
        reg = element_subregions(self.field, P, tris) if self.sub else None
        return comp, element_delta(self.field, P, tris, self.sampling, comp, regions=reg,
                                   threshold=self.thr), reg


def _qa(X: np.ndarray):
    """Quality q (Eq. 17) and the cosine of the smallest angle of triangles ``X (n, 3, 2)``
    (a larger cosine is a smaller angle)."""
    d0 = X[:, 2] - X[:, 1]
    d1 = X[:, 0] - X[:, 2]
    d2 = X[:, 1] - X[:, 0]
    a2 = d0[:, 0] ** 2 + d0[:, 1] ** 2
    b2 = d1[:, 0] ** 2 + d1[:, 1] ** 2
    c2 = d2[:, 0] ** 2 + d2[:, 1] ** 2
    a, b, c = np.sqrt(a2), np.sqrt(b2), np.sqrt(c2)
    den = a * b * c
    with np.errstate(invalid="ignore", divide="ignore"):
        q = np.where(den > 0, (b + c - a) * (c + a - b) * (a + b - c) / den, 0.0)
        # the smallest angle is opposite the shortest side
        s2 = np.minimum(np.minimum(a2, b2), c2)
        cos = np.where(den > 0, (a2 + b2 + c2 - 2.0 * s2) / (2.0 * den / np.sqrt(s2)), 1.0)
    return np.clip(q, 0.0, 1.0), cos


def _quality_of(P: np.ndarray, tris: np.ndarray) -> np.ndarray:
    """:func:`_qa`'s quality of every triangle, by blocks (in threads)."""
    return block_concat(lambda s: _qa(P[tris[s]])[0], len(tris))


def _area2(X: np.ndarray) -> np.ndarray:
    return signed_area2(X[:, 0], X[:, 1], X[:, 2])


def priority_hash(i: np.ndarray, salt: int = 0) -> np.ndarray:
    """A fixed pseudo-random priority of node ids (deterministic, no rng state)."""
    x = (i.astype(np.uint64) + np.uint64(salt)) * np.uint64(0x9E3779B97F4A7C15)
    x ^= x >> np.uint64(31)
    x *= np.uint64(0xBF58476D1CE4E5B9)
    x ^= x >> np.uint64(29)
    return x


def independent_sets(n: int, edges: np.ndarray, active: np.ndarray, salt: int = 0) -> list:
    """Split the ``active`` nodes into sets with no edge inside a set (Luby / Jones-Plassmann:
    a node joins when its priority beats every unassigned active neighbour)."""
    pr = priority_hash(np.arange(n), salt)
    left = active.copy()
    a, b = edges[:, 0], edges[:, 1]
    sets = []
    while left.any():
        both = left[a] & left[b]
        ea, eb = a[both], b[both]
        lose = np.zeros(n, bool)
        lose[np.where(pr[ea] < pr[eb], ea, eb)] = True
        s = left & ~lose
        sets.append(np.flatnonzero(s))
        left &= ~s
    return sets


# --------------------------------------------------------------------------- smoothing
class _Star:
    """The stars of an independent set of nodes ``idx``: one row per (node, incident
    triangle), grouped by node; ``slot`` is the node's corner in that triangle."""

    def __init__(self, tris, order, owner_sorted, inset, idx, P, comp, reg):
        sel = inset[owner_sorted]
        ent = order[sel]
        own = owner_sorted[sel]
        self.tid, self.slot = ent // 3, ent % 3
        self.starts = np.flatnonzero(np.r_[True, own[1:] != own[:-1]])
        self.cnt = np.diff(np.r_[self.starts, len(own)])
        self.local = np.searchsorted(idx, own)
        self.rows = np.arange(len(own))
        T = tris[self.tid]
        self.X0, self.C0 = P[T], comp[T]
        self.reg = None if reg is None else reg[self.tid]

    def per_node(self, fn, v):
        return fn.reduceat(v, self.starts)

    def moved(self, cand):
        X = self.X0.copy()
        X[self.rows, self.slot] = cand[self.local]
        return X

    def ideal(self):
        """Mean over the node's triangles of the apex that makes each one equilateral on
        its opposite edge (the node sits left of that edge: counter-clockwise triangles)."""
        pj = self.X0[self.rows, (self.slot + 1) % 3]
        pl = self.X0[self.rows, (self.slot + 2) % 3]
        d = pl - pj
        apex = 0.5 * (pj + pl) + SQRT3_2 * np.column_stack([-d[:, 1], d[:, 0]])
        return np.column_stack([self.per_node(np.add, apex[:, 0]),
                                self.per_node(np.add, apex[:, 1])]) / self.cnt[:, None]

    def gradient(self, x, q0, h):
        """Forward-difference gradient of the star's summed quality at the node."""
        g = np.empty_like(x)
        f0 = self.per_node(np.add, q0)
        eps = 1e-6 * h
        for k in range(2):
            xe = x.copy()
            xe[:, k] += eps
            q, _ = _qa(self.moved(xe))
            g[:, k] = (self.per_node(np.add, q) - f0) / eps
        return g


def sweep(ws: WorkSet, ctx: Context, tris, comp, reg, ev: DeltaEvaluator, active, *,
          min_angle_deg, steps, grad_steps, salt, wake=0.0, shifted=None,
          keep: float | None = None) -> np.ndarray:
    """One Gauss-Seidel sweep of the ``active`` nodes over independent sets; returns the
    mask of the nodes moved with a star mean quality gain above ``wake``. ``shifted``, a
    mask if given, gets every node moved set."""
    P = ws.P
    n = len(P)
    cmax = np.cos(np.radians(min_angle_deg))
    oncurve = ws.vcurve >= 0
    lev = (ws.vcurve == FREE) & np.isfinite(ws.level)
    flat = tris.ravel()
    ent = np.flatnonzero(active[flat])
    # by node, then by entry (a stable sort by node, from one unique int64 key)
    order = ent[np.argsort(flat[ent].astype(np.int64) * len(flat) + ent)]
    owner_sorted = flat[order]
    e = np.concatenate([tris[:, [0, 1]], tris[:, [1, 2]], tris[:, [2, 0]]])
    e = e[active[e[:, 0]] & active[e[:, 1]]]
    moved = np.zeros(n, bool)
    for idx in independent_sets(n, e, active, salt):
        inset = np.zeros(n, bool)
        inset[idx] = True
        st = _Star(tris, order, owner_sorted, inset, idx, P, comp, reg)
        x0 = P[idx]
        a0 = _area2(st.X0)
        q0, cs0 = _qa(st.X0)
        qmin0 = st.per_node(np.minimum, q0)
        qsum0 = st.per_node(np.add, q0)
        h = st.per_node(np.add, np.hypot(*(st.X0[st.rows, (st.slot + 1) % 3] - x0[st.local]).T))
        h /= st.cnt
        dirs = [(st.ideal() - x0, steps)]
        if grad_steps:
            g = st.gradient(x0, q0, h)
            gn = np.hypot(*g.T)
            dirs.append((g * (h / np.where(gn > 0, gn, 1.0))[:, None], grad_steps))
        con = _Constraints(ws, ctx, idx, oncurve, lev)
        raws, modes = [], []
        for d, ss in dirs:
            for s in ss:
                for mode in con.modes:
                    raws.append(x0 + s * d)
                    modes.append(mode)
        cand, tc, valid = con.project(np.stack(raws), modes)  # (K, n, 2), (K, n), (K, n)
        K, R = len(raws), len(st.rows)
        X = np.broadcast_to(st.X0, (K,) + st.X0.shape).copy()
        X[:, st.rows, st.slot] = cand[:, st.local]
        q, cs = _qa(X.reshape(K * R, 3, 2))
        ok = (_area2(X.reshape(K * R, 3, 2)) > 1e-3 * np.tile(np.abs(a0), K))
        ok &= (cs <= cmax) | (cs <= np.tile(cs0, K))
        q, ok = q.reshape(K, R), ok.reshape(K, R)
        good = valid & np.logical_and.reduceat(ok, st.starts, axis=1)
        if keep is None:  # the star's minimum quality may not fall
            good &= np.minimum.reduceat(q, st.starts, axis=1) >= qmin0
        else:  # no triangle may fall below the lower of its quality and keep
            good &= np.logical_and.reduceat(q >= np.minimum(q0, keep), st.starts, axis=1)
        gain = (np.add.reduceat(q, st.starts, axis=1) - qsum0) / st.cnt
        good &= gain > 0
        best_k = np.full(len(idx), -1)
        best_c = comp[idx].copy()
        for _ in range(K):  # delta (the costly part) only for each node's best candidate
            score = np.where(good, gain, -np.inf)
            k = score.argmax(axis=0)
            ig = np.flatnonzero(np.isfinite(score[k, np.arange(len(idx))]) & (best_k < 0))
            if ig.size == 0:
                break
            kg = k[ig]
            cc = ev.comp(cand[kg, ig])
            lut = np.full(len(idx), -1)
            lut[ig] = np.arange(len(ig))
            rows = np.flatnonzero(lut[st.local] >= 0)
            j = lut[st.local[rows]]
            Xr = X[kg[j], rows]
            C = st.C0[rows]
            C[np.arange(len(rows)), st.slot[rows]] = cc[j]
            dl = ev.delta(Xr, C, None if st.reg is None else st.reg[rows])
            bad = np.zeros(len(ig), bool)
            bad[j[dl >= ev.thr]] = True
            best_k[ig[~bad]] = kg[~bad]
            best_c[ig[~bad]] = cc[~bad]
            good[kg[bad], ig[bad]] = False
        go = best_k >= 0
        if go.any():
            g = idx[go]
            P[g] = cand[best_k[go], np.flatnonzero(go)]
            ws.vt[g] = tc[best_k[go], np.flatnonzero(go)]
            comp[g] = best_c[go]
            # a node that gained little does not wake its neighbours for the next sweep
            moved[g] = gain[best_k[go], np.flatnonzero(go)] > wake
            if shifted is not None:
                shifted[g] = True
    ws.P = P
    return moved


class _Constraints:
    """Where the nodes ``idx`` may go: free nodes anywhere, curve nodes on their curve
    (between their neighbours along it), row nodes along their level curve (``"row"``
    mode) or, if delta allows, anywhere (``"free"`` mode)."""

    def __init__(self, ws, ctx, idx, oncurve, lev):
        self.ws, self.ctx, self.idx = ws, ctx, idx
        self.oc = np.flatnonzero(oncurve[idx])
        self.lv = np.flatnonzero(lev[idx])
        self.modes = ("row", "free") if len(self.lv) else ("free",)
        if len(self.oc):
            ids = idx[self.oc]  # sorted
            self.lo, self.hi = curve_bounds(ws, ctx, ids)
            # no slide may stretch a chord beyond the chord tolerance: it moves the curve
            # off its chord (the neighbours along the curve do not move in this set)
            self.tmin, self.tmax = chord_window(ws, ctx, self.lo, self.hi, ids)
        if len(self.lv):
            x = ws.P[idx[self.lv]]
            gr = ctx.grad_f(x)
            self.tng = row_tangent(gr)
            self.gr = gr / np.maximum((gr ** 2).sum(1), 1e-300)[:, None]
            self.level = ws.level[idx[self.lv]]

    def project(self, raw, modes):
        """Candidates ``raw (K, n, 2)`` (one per mode in ``modes``) moved onto what holds
        each node; returns positions, curve parameters and which are allowed."""
        ws, ctx, idx = self.ws, self.ctx, self.idx
        cand = raw.copy()
        K = len(raw)
        tc = np.broadcast_to(ws.vt[idx], (K, len(idx))).copy()
        valid = np.ones((K, len(idx)), bool)
        free = np.array([m == "free" for m in modes])
        if len(self.oc):
            io = self.oc
            vc = ws.vcurve[idx[io]]
            cur = ws.vt[idx[io]]
            span = self.hi - self.lo
            for c in unique(vc):
                k = io[vc == c]
                sel = vc == c
                tt = ctx.curves[c].project(raw[:, k].reshape(-1, 2)).reshape(K, -1)
                cu = cur[sel]
                if ctx.closed[c]:
                    tt = np.where(tt - cu > 0.5, tt - 1.0, np.where(cu - tt > 0.5, tt + 1.0, tt))
                lo, sp = self.lo[sel], span[sel]
                a = np.maximum(lo + 0.1 * sp, self.tmin[sel])
                b = np.minimum(lo + 0.9 * sp, self.tmax[sel])
                stay = a > b  # both chords already too long: the node keeps its place
                a[stay] = b[stay] = cu[stay]
                tt = np.clip(tt, a, b)
                tc[:, k] = tt
                cand[:, k] = ctx.curves[c].point(tt.ravel()).reshape(K, -1, 2)
            if len(self.lv):  # "free" duplicates the curve nodes' candidates
                valid[np.ix_(free, io)] = False
        if len(self.lv):
            il = self.lv
            row = ~free
            if len(self.lv) < len(idx):
                rest = np.ones(len(idx), bool)
                rest[il] = False
                valid[np.ix_(free, np.flatnonzero(rest))] = False
            if row.any():
                x = ws.P[idx[il]]
                kr = int(row.sum())
                y = cand[row][:, il] - x
                y = x + (y * self.tng).sum(2, keepdims=True) * self.tng
                lev = np.tile(self.level, kr)
                gr = np.tile(self.gr, (kr, 1))
                y = y.reshape(-1, 2)
                for _ in range(2):  # chord Newton (gradient frozen at the start) onto the level
                    y = y - (ctx.f(y) - lev)[:, None] * gr
                sub = cand[row]
                sub[:, il] = y.reshape(kr, -1, 2)
                cand[row] = sub
        return cand, tc, valid


# --------------------------------------------------------------------------- flips
def _half_edges(tris):
    """Keys of the half-edges (k * M + t is edge k of triangle t), sorted, with the order."""
    ea = np.concatenate([tris[:, 0], tris[:, 1], tris[:, 2]])
    eb = np.concatenate([tris[:, 1], tris[:, 2], tris[:, 0]])
    keys = edge_keys(ea, eb)
    order = edge_order(keys)
    return order, keys[order]


def _flip_round(ws: WorkSet, tris, comp, reg, ev: DeltaEvaluator, *, min_angle_deg, ckeys,
                q_active, half=None, qt=None) -> np.ndarray:
    """Flip the interior non-constraint edges that raise the pair's minimum quality (of
    pairs with a triangle below ``q_active``); ``half`` = :func:`_half_edges` and ``qt``
    the triangles' qualities, if known. Returns the ids of the triangles changed."""
    P = ws.P
    m = len(tris)
    if qt is None:
        qt, _ = _qa(P[tris])
    order, ks = _half_edges(tris) if half is None else half
    pair = np.flatnonzero(ks[1:] == ks[:-1])
    h1, h2 = order[pair], order[pair + 1]  # the two half-edges of each interior edge
    low = np.minimum(qt[h1 % m], qt[h2 % m]) < q_active
    h1, h2, pk = h1[low], h2[low], ks[pair[low]]
    inter = ~np.isin(pk, ckeys)
    h1, h2 = h1[inter], h2[inter]
    t1, k1 = h1 % m, h1 // m
    t2, k2 = h2 % m, h2 // m
    a = tris[t1, k1]
    b = tris[t1, (k1 + 1) % 3]
    c = tris[t1, (k1 + 2) % 3]
    d = tris[t2, (k2 + 2) % 3]
    # old pair (a, b, c), (b, a, d); new pair (a, d, c), (d, b, c)
    n1 = np.column_stack([a, d, c])
    n2 = np.column_stack([d, b, c])
    Xo1, Xo2 = P[tris[t1]], P[tris[t2]]
    Xn1, Xn2 = P[n1], P[n2]
    qo1, ao1 = _qa(Xo1)
    qo2, ao2 = _qa(Xo2)
    qn1, an1 = _qa(Xn1)
    qn2, an2 = _qa(Xn2)
    qold = np.minimum(qo1, qo2)
    qnew = np.minimum(qn1, qn2)
    cold = np.maximum(ao1, ao2)  # cosine of the pair's smallest angle
    scale = np.abs(_area2(Xo1)) + np.abs(_area2(Xo2))
    ok = (qnew > qold + 1e-6) & (_area2(Xn1) > 1e-6 * scale) & (_area2(Xn2) > 1e-6 * scale)
    cmax = np.cos(np.radians(min_angle_deg))
    for cn in (an1, an2):
        ok &= (cn <= cmax) | (cn <= cold)
    idx = np.flatnonzero(ok)
    if idx.size == 0:
        return np.zeros(0, np.int64)
    r = None if reg is None else reg[t1[idx]]
    dl1 = ev.delta(Xn1[idx], comp[n1[idx]], r)
    dl2 = ev.delta(Xn2[idx], comp[n2[idx]], r)
    idx = idx[(dl1 < ev.thr) & (dl2 < ev.thr)]
    if idx.size == 0:
        return np.zeros(0, np.int64)
    # one flip per triangle: each triangle keeps its best candidate edge
    gain = qnew[idx] - qold[idx]
    pri = np.lexsort((priority_hash(idx), gain))  # ascending; rank = position
    rank = np.empty(len(idx), np.int64)
    rank[pri] = np.arange(len(idx))
    best = np.full(m, -1, np.int64)
    np.maximum.at(best, t1[idx], rank)
    np.maximum.at(best, t2[idx], rank)
    win = (best[t1[idx]] == rank) & (best[t2[idx]] == rank)
    w = idx[win]
    tris[t1[w]] = n1[w]
    tris[t2[w]] = n2[w]
    return np.concatenate([t1[w], t2[w]])


def _update_half(half, tris, changed):
    """The sorted half-edges (:func:`_half_edges`) after the triangles ``changed`` got new
    corners: their old half-edges taken out, their new ones merged in by (key, id), which
    is the order of the stable sort, without sorting everything again."""
    if len(changed) == 0:
        return half
    order, ks = half
    m = len(tris)
    chg = np.zeros(m, bool)
    chg[changed] = True
    keep = ~chg[order % m]
    order, ks = order[keep], ks[keep]
    t = np.flatnonzero(chg)
    nid = np.concatenate([t, t + m, t + 2 * m])
    nk = edge_keys(np.concatenate([tris[t, 0], tris[t, 1], tris[t, 2]]),
                   np.concatenate([tris[t, 1], tris[t, 2], tris[t, 0]]))
    o = np.lexsort((nid, nk))
    nid, nk = nid[o], nk[o]
    pos = np.searchsorted(ks, nk, side="left")
    for _ in range(4):  # past the equal keys of smaller id (an edge has two half-edges)
        p = np.minimum(pos, len(ks) - 1)
        after = (pos < len(ks)) & (ks[p] == nk) & (order[p] < nid)
        if not after.any():
            return np.insert(order, pos, nid), np.insert(ks, pos, nk)
        pos = pos + after
    return _half_edges(tris)


def _valid(P, tris, ckeys, keys) -> bool:
    """Every triangle counter-clockwise and every constraint edge a mesh edge (``keys``:
    the sorted half-edge keys)."""
    if (triangle_areas2(P, tris) <= 0).any():
        return False
    pos = np.minimum(np.searchsorted(keys, ckeys), len(keys) - 1)
    return bool(np.all(keys[pos] == ckeys))


def valid_input(ws: WorkSet, tris: np.ndarray) -> bool:
    """Whether ``tris`` is a mesh the passes may work on: every triangle counter-clockwise and
    every constraint edge of ``ws`` a mesh edge (otherwise it is not theirs to mend:
    :func:`hetmesh.tri.finish.finish` reports it)."""
    ckeys = unique(edge_keys(ws.E[:, 0], ws.E[:, 1]))
    return _valid(ws.P, tris, ckeys, _half_edges(tris)[1])


def _grow(tris, mask):
    """``mask`` and the nodes sharing a triangle with it."""
    out = mask.copy()
    out[tris[any_corner(mask, tris)].ravel()] = True
    return out


# --------------------------------------------------------------------------- the pass
def optimize(ws: WorkSet, ctx: Context, tris: np.ndarray, comp=None, delta=None, *,
             sampling: str = "vertices",
             min_angle_deg: float = 30.0, sweeps: int = 4, steps=(1.0, 0.5, 0.25),
             grad_steps=(0.1, 0.03), flips: int = 1, q_active: float = 0.99, wake: float = 1e-3,
             keep: float | None = None, callback=None):
    """Raise the element quality of a repaired mesh, keeping every claim (see the module).

    ``ws`` is updated in place (node positions and curve parameters); ``comp`` and
    ``delta``, if given, are the repair loop's (compositions at the nodes, delta(T)).
    Returns ``(triangles, composition, delta)`` of the optimised mesh, as the loop does.
    ``sweeps`` rounds each of ``flips`` flip rounds and one smoothing sweep. ``keep`` None:
    no move lowers a star's minimum quality, (d); a quality: none lowers a triangle below the
    lower of its quality and ``keep``, (d') (see the module).
    """
    ev = DeltaEvaluator(ctx, sampling)
    ckeys = unique(edge_keys(ws.E[:, 0], ws.E[:, 1]))
    if comp is None or delta is None:
        comp, delta, _ = ev.full(ws.P, tris)
    half = _half_edges(tris)
    if not _valid(ws.P, tris, ckeys, half[1]):  # not ours to mend: finish() reports it
        log.warning("optimisation skipped: the input mesh is folded or misses constraint edges")
        return tris, comp, delta
    P0, vt0, tris0, comp0, delta0 = ws.P.copy(), ws.vt.copy(), tris.copy(), comp, delta
    tris, comp = tris.copy(), comp.copy()
    reg = element_subregions(ctx.field, ws.P, tris) if ev.sub else None
    movable = ws.vcurve != FIXED  # row crossings too: they slide on their curve, delta checked
    near = movable
    # the triangles' qualities and sorted half-edges, kept up to date where flips and
    # moves change them (the same numbers as computing them again)
    q = _quality_of(ws.P, tris)
    for it in range(sweeps):
        nf = 0
        for _ in range(flips):
            w = _flip_round(ws, tris, comp, reg, ev, min_angle_deg=min_angle_deg, ckeys=ckeys,
                            q_active=q_active, half=half, qt=q)
            half = _update_half(half, tris, w)
            q[w] = _qa(ws.P[tris[w]])[0]
            nf += len(w) // 2
            if len(w) == 0:
                break
        # nodes whose star has a triangle below q_active, near last sweep's changes
        low = np.zeros(ws.n, bool)
        low[tris[q < q_active].ravel()] = True
        active = low & near
        shifted = np.zeros(ws.n, bool)
        moved = sweep(ws, ctx, tris, comp, reg, ev, active, min_angle_deg=min_angle_deg,
                      steps=steps, grad_steps=grad_steps, salt=it, wake=wake, shifted=shifted,
                      keep=keep)
        touched = np.flatnonzero(any_corner(shifted, tris))
        q[touched] = _qa(ws.P[tris[touched]])[0]
        nm = int(moved.sum())
        log.info("optimize sweep %d: %d flips, %d of %d active nodes moved", it, nf, nm,
                 int(active.sum()))
        if callback is not None:
            callback(it, ws, tris)
        if nm == 0 and nf == 0:
            break
        near = movable & _grow(tris, moved)
    comp, delta, _ = ev.full(ws.P, tris)
    if delta.max() >= ctx.threshold or (triangle_areas2(ws.P, tris) <= 0).any():
        log.warning("optimisation broke a claim (delta_max %.6g, threshold %g); kept the "
                    "repaired mesh", delta.max(), ctx.threshold)
        ws.P, ws.vt = P0, vt0
        return tris0, comp0, delta0
    return tris, comp, delta
