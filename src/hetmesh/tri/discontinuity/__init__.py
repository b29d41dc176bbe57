"""Material discontinuities of piecewise fields: found, fitted and embedded (Sec. 3.3).

A heterogeneous feature tree (:mod:`hetmesh.material.hft`) divides the domain into
subregions, each with its own smooth material distribution (Secs. 3.3.1-3.3.3). Where the
owning subregion changes -- the medial curves between the sub-features of a composite curve,
the boundary of a ``select`` rule -- the composition may jump. An element straddling such a
curve is not homogeneous however small it is, so the curves must be mesh edges. A formula
field with jumps (``where``, ``sign``; :class:`~hetmesh.material.AnalyticField`) has
subregions too: the patterns of truth values of its conditions.

The paper derives those curves by hand per model. Here they are found for any such field
(anything with ``region(points)`` and ``n_regions > 1``):

1. **Trace.** The subregion id is sampled on a grid over the domain's bounding box; every
   grid edge whose ends differ is bisected to the switch point (to ~1e-12 of the diameter),
   the crossings are linked cell by cell (marching squares; a cell with three or more
   subregions holds a junction, located by nested refinement) and chained into polylines.
2. **Clip.** Polylines are cut at the domain boundary, where the end point is located *on
   the boundary curve* by bisecting the subregion along it (or snapped to a corner), and
   at the corners they run through (a straight jump through a re-entrant corner).
   Pieces lying on an existing interface (a ``select`` rule "inside A" where A is an
   interface of the domain) are dropped: they are embedded already.
3. **Fit.** Each polyline becomes a chain of circular arcs and segments within ``tol`` of the
   crossings (greedy, longest piece first), so the mesher can place nodes freely along it.
4. **Embed.** Boundary curves are split where a discontinuity ends on them, and each chain is
   added to the domain as an interface path named ``discontinuity[k]``.

:func:`embed_discontinuities` does all four on a model; :func:`crossing_elements` checks a mesh
against the claim that no element interior crosses a discontinuity.
"""

from __future__ import annotations

from .check import crossing_elements
from .embed import embed_discontinuities, embedded_count
from .fit import fit_curves
from .regions import (
                      BISECT,
                      DISCONTINUITY,
                      FIT_TOL,
                      GRID_CELLS,
                      MAX_CROSSINGS_PER_CELL,
                      Discontinuity,
)
from .trace import trace_discontinuities

__all__ = ["Discontinuity", "DISCONTINUITY", "trace_discontinuities",
           "fit_curves", "embed_discontinuities", "embedded_count", "crossing_elements",
           "FIT_TOL", "GRID_CELLS", "BISECT", "MAX_CROSSINGS_PER_CELL"]
