"""Vertex removal by half-edge collapse: fewer elements at no cost in quality.

The repair loop (:mod:`hetmesh.tri.refine`) only adds nodes. Where it inserted many in a
small area (a cascade of off-centres where the size changes fast, a violator split next to
another), some nodes are not needed: the elements around them would keep delta(T) < delta_0
and their shape without them. This pass removes such interior nodes, so that the mesh gets
fewer elements and, by the acceptance rule below, no lower mean quality.

A node ``v`` of the interior (not on a boundary, interface or other curve, not pinned) is
removed by collapsing it onto one of its neighbours ``u``: the triangles ``(v, a, b)`` of its
star that do not hold ``u`` become ``(u, a, b)``; the two that hold the edge ``uv`` go.
The collapse is taken, for the neighbour that gains most, when the new triangles

* are positively oriented: then the fan from ``u`` covers the polygon of ``v``'s star
  exactly (its rays turn one way), so no new edge can be one the mesh has (that edge would
  cross the star's interior) and the result is a valid triangulation of the same region,
* keep delta(T) < delta_0 (less the optimiser's relative margin), evaluated exactly as the
  repair loop does (same sampling; every element in the subregion of the star),
* keep the smallest angle at least the floor or the star's old smallest angle, and the star's
  minimum quality q (Eq. 17) at least ``min(old minimum, q_keep)``, and
* do not lower the mesh's mean quality: with ``k`` triangles in the star and ``k - 2`` after,
  ``sum q_new - sum q_old >= -2 q_avg`` (two elements fewer at the current mean).

Collapses are made in rounds; within a round the removed nodes are at least three edges
apart (a node joins when its gain beats every other candidate whose star shares a vertex with
its own; ties by a fixed hash), so their stars are disjoint and every check made on the old
mesh still holds after all of them. Only nodes whose star holds a triangle below
``q_active`` are candidates: a regular lattice of rows is left alone. Arrays first: the
loops run over rounds only. Deterministic: no random state.

>>> import numpy as np
>>> P = np.array([[0, 0], [1, 0], [0.5, 0.85], [0.5, 0.3]], float)
>>> t = np.array([[0, 1, 3], [1, 2, 3], [2, 0, 3]])
>>> star_table(t, np.array([3]))[0].tolist()
[[0, 1, 2]]
"""

from __future__ import annotations

import logging
from typing import NamedTuple

import numpy as np

from ..material.field import element_subregions, has_subregions
from ..metrics import quality_and_angle, signed_area2
from .optimize import DeltaEvaluator, priority_hash, valid_input
from .workset import FREE, Context, WorkSet, drop_nodes

__all__ = ["collapse", "star_table", "MAX_DEGREE"]

log = logging.getLogger(__name__)

#: nodes with more triangles around them are not removed (a fan of many is rarely good)
MAX_DEGREE = 10
#: the margin of every comparison of qualities, angles and gains: far above the rounding
#: of coordinates scaled to the local frame, so the same model gives the same mesh in any
#: units
TIE = 1e-9


def star_table(tris: np.ndarray, nodes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The triangles around each of ``nodes`` (sorted, unique) as a padded table
    ``(len(nodes), d)`` (-1 pads) and their counts; ``d`` is the largest count."""
    flat = tris.ravel()
    sel = np.flatnonzero(np.isin(flat, nodes))
    owner = flat[sel]
    order = np.argsort(owner, kind="stable")
    owner, tid = owner[order], sel[order] // 3
    row = np.searchsorted(nodes, owner)
    cnt = np.bincount(row, minlength=len(nodes))
    start = np.r_[0, np.cumsum(cnt)[:-1]]
    col = np.arange(len(owner)) - start[row]
    table = np.full((len(nodes), max(int(cnt.max(initial=0)), 1)), -1, np.int64)
    table[row, col] = tid
    return table, cnt


def _rotated(tris: np.ndarray, tid: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Triangles ``tid`` rotated so that node ``v`` (one per row) comes first: ``(v, a, b)``,
    still counter-clockwise."""
    T = tris[tid]
    k = np.argmax(T == v[:, None], axis=1)
    r = np.arange(len(T))
    return np.column_stack([T[r, k], T[r, (k + 1) % 3], T[r, (k + 2) % 3]])


def _proposals(P, tris, comp, reg, delta_ev, q, ang, cand, *, min_angle, q_keep, q_mean):
    """Every candidate node's best collapse, as a :class:`_Proposals`, or None."""
    table, cnt = star_table(tris, cand)
    ok = (cnt >= 3) & (cnt <= MAX_DEGREE)
    cand, table = cand[ok], table[ok]
    if not len(cand):
        return None
    nv, d = table.shape
    valid = table >= 0
    # every star triangle as (v, a, b); the targets are the a's (each neighbour once)
    R = _rotated(tris, np.where(valid, table, 0).ravel(), np.repeat(cand, d)).reshape(nv, d, 3)
    A, B = R[:, :, 1], R[:, :, 2]
    q_old_sum = np.where(valid, q[table], 0.0).sum(axis=1)
    q_old_min = np.where(valid, q[table], np.inf).min(axis=1)
    a_old_min = np.where(valid, ang[table], np.inf).min(axis=1)
    # pairs (node i, neighbour u = A[i, j]); their new triangles (u, A[i, m], B[i, m]) for
    # the m with neither corner u
    ii, jj = np.nonzero(valid)
    u = A[ii, jj]
    keep = valid[ii] & (A[ii] != u[:, None]) & (B[ii] != u[:, None])
    pi, mm = np.nonzero(keep)
    nt = np.column_stack([u[pi], A[ii[pi], mm], B[ii[pi], mm]])
    X = P[nt]
    npair = len(u)
    good = np.ones(npair, bool)
    np.logical_and.at(good, pi, signed_area2(X[:, 0], X[:, 1], X[:, 2]) > 0)
    qn, an = quality_and_angle(X.reshape(-1, 2), np.arange(3 * len(nt)).reshape(-1, 3))
    q_new_min = np.full(npair, np.inf)
    np.minimum.at(q_new_min, pi, qn)
    a_new_min = np.full(npair, np.inf)
    np.minimum.at(a_new_min, pi, an)
    gain = np.bincount(pi, qn, minlength=npair) - q_old_sum[ii] + 2.0 * q_mean
    # margins well above rounding: a tie in exact arithmetic is a refusal at every scale
    good &= q_new_min >= np.minimum(q_old_min[ii], q_keep) + TIE
    good &= a_new_min >= np.minimum(a_old_min[ii], min_angle) + TIE
    good &= gain >= TIE
    # delta, the costly test, only where the rest holds
    rg = None if reg is None else reg[table[ii[pi], mm]]
    s = np.flatnonzero(good[pi])
    dn = np.full(len(nt), np.inf)
    if len(s):
        dn[s] = delta_ev.delta(X[s], comp[nt[s]], None if rg is None else rg[s])
    dmax = np.full(npair, -np.inf)
    np.maximum.at(dmax, pi, dn)
    good &= dmax < delta_ev.thr
    if not good.any():
        return None
    # each node's best neighbour (the first of equal gains)
    g = np.where(good, gain, -np.inf)
    best = np.full(nv, -np.inf)
    np.maximum.at(best, ii, g)
    pick = np.flatnonzero(good & (g == best[ii]))
    pick = pick[np.r_[True, ii[pick][1:] != ii[pick][:-1]]]
    return _Proposals(cand[ii[pick]], table[ii[pick]], gain[pick], pick, pi, nt, dn, rg, qn,
                      an)


class _Proposals(NamedTuple):
    """The best collapse of each node that has one: ``node``, its ``star`` (triangle ids,
    -1 pads) and ``gain``; ``pair`` the index of the chosen (node, neighbour) pair, and for
    every new triangle of every pair: ``owner`` (its pair), ``tris``, ``delta``, subregion
    ``reg``, quality ``q`` and smallest angle ``angle``."""

    node: np.ndarray
    star: np.ndarray
    gain: np.ndarray
    pair: np.ndarray
    owner: np.ndarray
    tris: np.ndarray
    delta: np.ndarray
    reg: np.ndarray | None
    q: np.ndarray
    angle: np.ndarray


def _independent(n: int, tris: np.ndarray, prop: _Proposals) -> np.ndarray:
    """Which proposals to take together: those whose gain (ties: a fixed hash of the node,
    then the larger node id) beats every other proposal whose star shares a vertex with
    theirs, so that the taken nodes are at least three edges apart."""
    gain = np.round(prop.gain / TIE) * TIE  # equal up to rounding: the hash decides
    pr = np.lexsort((prop.node, priority_hash(prop.node) % np.uint64(1 << 20), gain))
    rank = np.empty(len(pr), np.int64)
    rank[pr] = np.arange(len(pr))  # a strict total order
    ok = prop.star >= 0
    verts = tris[np.where(ok, prop.star, 0)]  # (n, d, 3)
    own = np.broadcast_to(np.arange(len(pr))[:, None, None], verts.shape)
    sel = np.broadcast_to(ok[:, :, None], verts.shape)
    vv, oo = verts[sel], own[sel]
    top = np.full(n, -1, np.int64)
    np.maximum.at(top, vv, rank[oo])
    beaten = np.zeros(len(pr), bool)
    np.logical_or.at(beaten, oo, top[vv] > rank[oo])
    return np.flatnonzero(~beaten)


def collapse(ws: WorkSet, ctx: Context, tris: np.ndarray, comp: np.ndarray,
             delta: np.ndarray, *, sampling: str = "vertices", min_angle_deg: float = 30.0,
             rounds: int = 6, q_active: float = 0.9, q_keep: float = 0.75):
    """Remove interior nodes by half-edge collapses that keep every claim (see the module).

    ``ws`` is compacted in place (the removed nodes go; the others keep their order). A
    folded mesh or one missing a constraint edge is returned unchanged (the final
    verification reports it). Returns ``(triangles, composition, delta)`` of the coarser
    mesh.
    """
    if not valid_input(ws, tris):
        return tris, comp, delta
    ev = DeltaEvaluator(ctx, sampling)
    reg = element_subregions(ctx.field, ws.P, tris) if has_subregions(ctx.field) else None
    removable = (ws.vcurve == FREE) & ~ws.pinned
    removed = np.zeros(ws.n, bool)
    q, ang = quality_and_angle(ws.P, tris)
    total = 0
    for rnd in range(rounds):
        low = np.zeros(ws.n, bool)
        low[tris[q < q_active].ravel()] = True
        cand = np.flatnonzero(low & removable & ~removed)
        prop = None if not len(cand) else _proposals(
            ws.P, tris, comp, reg, ev, q, ang, cand, min_angle=min_angle_deg, q_keep=q_keep,
            q_mean=float(q.mean()))
        if prop is None:
            break
        take = _independent(ws.n, tris, prop)
        drop = prop.star[take]
        keep_t = np.ones(len(tris), bool)
        keep_t[drop[drop >= 0]] = False
        rows = np.isin(prop.owner, prop.pair[take])
        tris = np.concatenate([tris[keep_t], prop.tris[rows]])
        delta = np.concatenate([delta[keep_t], prop.delta[rows]])
        q = np.concatenate([q[keep_t], prop.q[rows]])
        ang = np.concatenate([ang[keep_t], prop.angle[rows]])
        if reg is not None:
            reg = np.concatenate([reg[keep_t], prop.reg[rows]])
        removed[prop.node[take]] = True
        total += len(take)
        log.info("collapse round %d: %d of %d candidate nodes removed", rnd, len(take),
                 len(cand))
    if not total:
        return tris, comp, delta
    tris, comp = _compact(ws, tris, comp, removed)
    return tris, comp, delta


def _compact(ws: WorkSet, tris, comp, removed):
    """Drop the ``removed`` nodes from ``ws`` (in place) and renumber ``tris``."""
    new = drop_nodes(ws, removed)
    return new[tris], comp[~removed]
