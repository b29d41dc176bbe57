"""MOR's node placements: where the nodes start before the refinement loop.

Three placements, by ``method`` name (:data:`PLACEMENTS`):

* ``"cvt"`` -- the paper's start (Sec. 3.2.3): nodes sampled with the density
  rho = |grad f|^(d+2) (Eq. 9), then conforming Lloyd iterations (the CVT step,
  :mod:`hetmesh.tri.cvt`); ``"cvt-dense"`` the same from 1.3 x the density's node count;
* ``"springs"`` -- isotropically sized nodes (1.3 x the density's node count where the
  material sets the size, ``h_max`` where it does not: :func:`start_size`), relaxed as a
  truss of springs (:mod:`hetmesh.tri.springs`): nearly equilateral elements, for the best
  mean quality where the element count allows; ``"springs-dense"`` from 1.5 x the count
  everywhere (flat zones too: smaller elements, a better mean quality on small models);
* ``"layers"`` -- rows of nodes on the composition's level curves
  (:mod:`hetmesh.tri.layers`); ``"layers-crossings"`` the same with a curve node at every
  crossing of a level with a curve, also where the rows meet the curve square (the 3D
  sweeps' sections, :data:`hetmesh.tri.pipeline.SWEEP_STARTS`).
"""

from __future__ import annotations

import functools

import numpy as np

from .. import density as dens
from .geometry import build_pslg
from .layers import place_layers
from .springs import relax
from .workset import Context, WorkSet, add_free_points, smooth, triangulate, workset_from_pslg

__all__ = ["place_cvt", "place_springs", "size_fn", "start_size", "sample_interior",
           "PLACEMENTS", "BOUND_AIM", "DENSE_START", "SPRING_START", "SPRING_DENSE_START",
           "BOUNDARY_SPACING"]


def size_fn(ctx: Context, factor: float):
    def h(pts):
        return dens.size_at(ctx.g(pts), ctx.threshold, ctx.h_at(pts), factor)
    return h



def start_size(ctx: Context, start: float):
    """The springs start's edge length: ``start`` x the density's node count where the
    material sets the size, the largest size where it does not,

        1 / h^2 = 1 / h_max^2 + start (1 / h_m^2 - 1 / h_max^2),

    ``h_m = delta_0 / g`` the material size (``g`` graded, so ``h_m <= h_max``), then capped
    by ``Context.h_at`` (small features). Far below ``h_max`` that is
    ``h_m / sqrt(start)``, as ``size_fn(ctx, 1 / sqrt(start))``; where the material is flat
    it is ``h_max``, continuously in between. The extra nodes of ``start > 1`` leave fewer
    elements above delta_0 after the relaxation where the composition varies; where the
    size is ``h_max`` no element comes near delta_0, and ``size_fn`` (which scales
    ``h_max`` too) only put 1.3 x the nodes a geometric mesher puts there: a near-constant
    field on a 3 x 2 rectangle at delta_0 = 0.1 had 94 elements of mean edge 0.86 h_max
    (68 equilateral ones of side h_max tile it), 70 of 0.99 h_max with this size.

    Where the user set ``max_size``, every edge must stay below it (``Context.max_edge``),
    and the relaxed truss's edges spread around their rest length: the size is capped at
    :data:`BOUND_AIM` x that bound, so that the repair has few edges to split."""
    hmax = ctx.h_max
    # an explicit max_size bounds every edge: aim below it (BOUND_AIM)
    bound = np.inf if ctx.max_edge is None else BOUND_AIM * ctx.max_edge

    def h(pts):
        hm = dens.size_at(ctx.g(pts), ctx.threshold, hmax)
        inv = 1.0 / hmax ** 2 + start * (1.0 / hm ** 2 - 1.0 / hmax ** 2)
        return np.minimum(np.minimum(1.0 / np.sqrt(inv), ctx.h_at(pts)), bound)
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
    pts = sample_interior(ctx, h, rng)
    add_free_points(ws, pts)
    tris = triangulate(ws, ctx)
    smooth(ws, ctx, tris, iters=12)
    return ws



def sample_interior(ctx: Context, h, rng) -> np.ndarray:
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



#: the springs start's size where an explicit ``max_size`` bounds it, relative to the bound
#: (``Context.max_edge``): aimed at the bound itself, the relaxed edges above it were split
#: by the repair, at a cost in shape (a near-constant field on a 3 x 2 rectangle at 0.1 with
#: max_size 0.3: 329 elements of q_avg 0.940; at 0.9 x 321 of 0.948; at 0.8 x 238 of 0.981,
#: where the springs-dense start, which ``auto`` kept, had 239 of 0.966; at 0.75 x 258 of
#: 0.985). With 0.8, ``auto`` kept a mesh as good or better on the seven runs with
#: max_size measured (that rectangle at 0.3 and 0.45, random-0002-power at 0.2 and 0.1,
#: power_plate at 2, unit_square at 0.06, bracket at 3)
BOUND_AIM = 0.8

#: node count of the springs placement relative to the density's (equilateral elements of
#: side delta_0 / |grad f|): its rest lengths are delta_0 / (sqrt(1.3) |grad f|)
SPRING_START = 1.3
#: the denser CVT start that the 3D sweeps' sections also try
#: (:data:`hetmesh.tri.pipeline.SWEEP_STARTS`)
DENSE_START = 1.3
#: the denser springs start that :func:`hetmesh.tri.pipeline.generate`'s ``"auto"`` also
#: tries: fewer elements violate delta_0 after the relaxation, so the repair's insertions
#: spoil fewer shapes (three_phase at 0.1: 346 elements of q_avg 0.977 against 323 of 0.959)
SPRING_DENSE_START = 1.5
#: the springs start's curve spacing relative to its interior size h. The curve nodes do not
#: move in the relaxation, and the relaxed bars next to a curve come out about 1.07 h long
#: (random-0044-power at 0.19: 1.08 h, 1.01 h further in); sampled at h with the count
#: rounded up, a short curve's edges were shorter still (0.91 h): the triangles along the
#: boundary were tall (their boundary edge 0.84 x the mean of their other two) and, after
#: the quality passes, of mean quality 0.909 against 0.960 inside (Gmsh's: 0.974). With
#: the count rounded to the nearest, on the robustness benchmark's 48 models 1.1 kept every
#: mark of the default method against Gmsh at both thresholds, 1.07 and 1.04 lost one each
#: (an element count 2 above Gmsh's, a q_min); at 1.1 the mean q_avg rose by 0.0013 at
#: 1.8 % fewer elements at the coarser thresholds and stayed within 0.0003 at 0.1 % fewer
#: at the finer ones, random-0044-power's at 0.19 from 0.945 to 0.962
BOUNDARY_SPACING = 1.1


def place_springs(ctx: Context, rng, chord_tol: float, progress=None,
                  start: float = SPRING_START, everywhere: bool = False) -> WorkSet:
    """The springs start: the interior filled at the size :func:`start_size` (``start`` x
    the density's node count where the material sets the size, ``h_max`` where it does
    not; ``everywhere=True``: ``size_fn(ctx, 1 / sqrt(start))``, ``start`` x the count
    everywhere, flat zones too, as ``"springs-dense"`` does), the curves sampled at
    :data:`BOUNDARY_SPACING` x that size (the count of intervals rounded to the nearest),
    then the free nodes moved to the equilibrium of a truss of springs
    (:func:`hetmesh.tri.springs.relax`)."""
    h = size_fn(ctx, 1.0 / np.sqrt(start)) if everywhere else start_size(ctx, start)

    def hb(pts):
        return np.minimum(BOUNDARY_SPACING * h(pts), ctx.h_at(pts))

    ws = workset_from_pslg(build_pslg(ctx.domain, hb, chord_tol, nearest=True))
    add_free_points(ws, sample_interior(ctx, h, rng))
    relax(ws, ctx, h)
    return ws


#: node placements of MOR, by ``method`` name
PLACEMENTS = {"cvt": place_cvt, "layers": place_layers,
              "layers-crossings": functools.partial(place_layers, mid_levels=False),
              "cvt-dense": functools.partial(place_cvt, start=DENSE_START),
              "springs": place_springs,
              "springs-dense": functools.partial(place_springs, start=SPRING_DENSE_START,
                                                       everywhere=True)}
