"""Spring relaxation: isotropically sized nodes moved as a truss of springs.

The node moves of MOR's springs start (``method="springs"``,
:func:`hetmesh.tri.placement.place_springs`), made for element shape. The CVT placement
(:func:`hetmesh.tri.placement.place_cvt`) and the springs placement size their nodes alike:
the curves are sampled and the interior is filled at the edge length
``h = delta_0 / (sqrt(start) |grad f|)`` (graded, capped by ``max_size`` and by the geometric
size near small features; the springs start keeps ``max_size`` itself where the material is
flat, :func:`hetmesh.tri.placement.start_size`). They differ in how the nodes then move:

* **Springs.** Every edge of the constrained Delaunay triangulation is a bar whose rest
  length is the mean of ``h`` at its two ends, scaled by one factor so that the rest
  lengths' squares sum to ``FSCALE**2`` times the actual lengths' squares (the truss is
  compressed a little, so that it spreads into every corner of the domain). Bars shorter
  than their rest length push their two ends apart, longer ones do nothing. Every free
  node moves by ``DT`` times the sum of its bars' forces, the step shortened so that no
  triangle folds (:func:`hetmesh.tri.cvt.limit_to_star`) (Persson and Strang's DistMesh,
  "A simple mesh generator in MATLAB", SIAM Review 46, 2004). Curve nodes, corners and
  named points stay where the curve sampling put them: letting curve nodes slide along
  their curves lowered the mean quality after the repair (bracket at 0.05: 0.972 ->
  0.965).
* **Clearance.** A free node stays at least ``CLEARANCE`` times a constraint edge's length
  away from that edge: when the repair later splits the edge on its true curve (an arc
  bulges by up to a quarter of its chord), the node stays on the domain's side.

At equilibrium the bars have nearly their rest lengths, so the triangles are nearly
equilateral at the local size: on the robustness benchmark's models the mesh after the repair
and the quality pass has a mean quality (Eq. 17) above the CVT start's at about the same
element count. Lloyd's iterations (the CVT) converge to the same kind of lattice far more
slowly from a random start.

The truss (the triangulation, and the rest lengths at the nodes) is rebuilt when a node has
moved ``REBUILD`` x its rest length since the last rebuild; in between, the moves are
limited to the old stars, so it stays valid. Deterministic: the interior sample uses the
run's seed, the iterations none.
"""

from __future__ import annotations

import numpy as np

from ..topology import edge_keys, unique
from .cvt import limit_to_star
from .workset import FREE, Context, WorkSet, drop_nodes, triangulate

__all__ = ["relax", "spring_forces", "ITERATIONS", "FSCALE", "DT", "CLEARANCE", "REBUILD",
           "SETTLED"]

#: the most relaxation steps
ITERATIONS = 300
#: the truss's compression: rest lengths are this much above the mean actual length
FSCALE = 1.2
#: the step: a node moves by DT times its net force (a length)
DT = 0.2
#: the truss is rebuilt when a node has moved this much (relative to its rest length) since
#: the last rebuild
REBUILD = 0.2
#: the iterations stop when no node moves more than this (relative to its rest length)
SETTLED = 1e-3
#: the least distance of a free node to a constraint edge, relative to the edge's length
CLEARANCE = 0.25


def relax(ws: WorkSet, ctx: Context, h, iterations: int = ITERATIONS, *,
          fscale: float = FSCALE, dt: float = DT, clearance: float = CLEARANCE,
          rebuild: float = REBUILD, settled: float = SETTLED) -> np.ndarray:
    """Move the work set's free nodes up to ``iterations`` times by their spring forces
    (see the module); ``h(points)`` is the rest length at ``points``.

    The triangulation (the truss) is rebuilt when a node has moved more than ``rebuild``
    times its rest length since the last rebuild (DistMesh's rule; the rest lengths are
    evaluated at the nodes then); the iterations stop early when no node moves more than
    ``settled`` times its rest length. Free nodes that end outside every triangle are
    dropped. Returns the last triangulation."""
    free = ws.vcurve == FREE
    with ctx.timed("springs"):
        stale = True
        for _ in range(iterations):
            if stale:
                tris = triangulate(ws, ctx)
                bars = _bars(tris)
                hn = h(ws.P)
                apex = _constraint_apexes(ws, tris)
                at_rebuild = ws.P
            P = ws.P
            target = P + dt * spring_forces(P, bars, hn, fscale)
            ws.P = limit_to_star(P, tris, target, free)
            _keep_clear(ws, P, apex, clearance)
            step = np.hypot(*(ws.P - P).T) / hn
            if not (step > settled).any():
                break
            stale = bool((np.hypot(*(ws.P - at_rebuild).T) > rebuild * hn).any())
        tris = triangulate(ws, ctx)
        return _drop_unused_free(ws, ctx, tris)


def spring_forces(P: np.ndarray, bars: np.ndarray, h: np.ndarray,
                  fscale: float = FSCALE) -> np.ndarray:
    """The net force on every node of the truss ``bars`` (pairs of node ids): repulsive
    only, ``max(L0 - L, 0)`` along each bar, ``L0`` the mean of the sizes ``h`` (per node)
    at its ends, scaled so that ``sum L0^2 = fscale^2 sum L^2``. ``(N, 2)``."""
    a, b = bars[:, 0], bars[:, 1]
    v = P[b] - P[a]
    L = np.hypot(v[:, 0], v[:, 1])
    hm = 0.5 * (h[a] + h[b])
    L0 = hm * (fscale * np.sqrt((L * L).sum() / (hm * hm).sum()))
    with np.errstate(divide="ignore", invalid="ignore"):
        f = np.where(L > 0, np.maximum(L0 - L, 0.0) / L, 0.0)
    n = len(P)
    fx, fy = f * v[:, 0], f * v[:, 1]
    return np.column_stack([np.bincount(b, fx, n) - np.bincount(a, fx, n),
                            np.bincount(b, fy, n) - np.bincount(a, fy, n)])


def _bars(tris: np.ndarray) -> np.ndarray:
    """The triangulation's edges, each once, as sorted pairs (in the order of their
    :func:`~hetmesh.topology.edge_keys`)."""
    e = tris[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
    key = unique(edge_keys(e[:, 0], e[:, 1]))
    return np.column_stack([key >> 32, key & 0xFFFFFFFF])


def _constraint_apexes(ws: WorkSet, tris: np.ndarray) -> np.ndarray:
    """``(K, 3)``: a free node and the ends of a constraint edge opposite it in a triangle."""
    constraint = edge_keys(ws.E[:, 0], ws.E[:, 1])
    free = ws.vcurve == FREE
    out = []
    for k in range(3):
        c, a, b = tris[:, k], tris[:, (k + 1) % 3], tris[:, (k + 2) % 3]
        s = free[c] & np.isin(edge_keys(a, b), constraint)
        out.append(np.column_stack([c[s], a[s], b[s]]))
    return np.vstack(out)


def _keep_clear(ws: WorkSet, before: np.ndarray, apex: np.ndarray, clearance: float) -> None:
    """Put back the free nodes that moved closer than ``clearance`` times a constraint
    edge's length to that edge (``apex`` from :func:`_constraint_apexes`)."""
    if not len(apex):
        return
    p, a, b = ws.P[apex[:, 0]], ws.P[apex[:, 1]], ws.P[apex[:, 2]]
    ab = b - a
    ll = np.einsum("ij,ij->i", ab, ab)
    t = np.clip(np.einsum("ij,ij->i", p - a, ab) / ll, 0.0, 1.0)
    d2 = ((a + t[:, None] * ab - p) ** 2).sum(axis=1)
    close = apex[d2 < clearance * clearance * ll, 0]
    if len(close):
        P = ws.P.copy()
        P[close] = before[close]
        ws.P = P


def _drop_unused_free(ws: WorkSet, ctx: Context, tris: np.ndarray) -> np.ndarray:
    """Drop free nodes that no triangle uses; returns the (re)triangulation."""
    used = np.zeros(ws.n, bool)
    used[tris.ravel()] = True
    drop = ~used & (ws.vcurve == FREE)
    if not drop.any():
        return tris
    drop_nodes(ws, drop)
    return triangulate(ws, ctx)
