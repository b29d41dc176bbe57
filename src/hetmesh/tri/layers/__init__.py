"""Node placement on iso-composition curves ("layers"): MOR's start for two constituents.

Why: delta(T) of a small element is |grad f| times its extent along the gradient. A CVT spreads
that extent by ~1.4 between elements, so an isotropic CVT cannot go much below ~1.2 x N_iso
elements. Rows of nodes on the level curves f = c_k, c_k = anchor -/+ k * beta * delta_0,
with spacing 2 w / sqrt(3) along each row (w = beta * delta_0 / |grad f| the row distance),
make near-equilateral triangles whose vertices sit on two adjacent rows, so every such triangle
has delta(T) = beta * delta_0 exactly: the threshold is used to the full (about 0.75-0.9 x N_iso
elements). The rows are traced from where the level curves cross the boundary (predictor step
along the tangent, Newton corrector back onto the level); a row that runs from curve to curve
then gets its nodes re-spaced so that it is in phase with its neighbours (a node count shared
by adjacent rows, alternate rows starting a full and a half spacing from the curve,
:func:`~hetmesh.tri.layers.respacing.respace_rows`; closed rows likewise from their seeds).
Where |grad f| -> 0 at a border or an extremum the last band of rows is much higher than its
neighbours: it gets intermediate levels, graded from both ends, and the rows next to it a
node step that matches their bands (:func:`~hetmesh.tri.layers.grading.grade_levels`); what
no level covers is filled by circumcenter insertion to the maximum size; nodes then slide
along their rows (conforming Lloyd, :func:`hetmesh.tri.workset.smooth`) and the shared repair
loop of :mod:`hetmesh.tri.refine` fixes whatever is left, so the guarantee does not depend on
this placement.

The stages, one module each, in the order :func:`place_layers` runs them:

- :mod:`.pieces` -- the connected pieces of the domain between interface curves;
- :mod:`.levels` -- level selection: the row levels of every piece, counted from an anchor;
- :mod:`.paths` -- gradient paths (steepest ascent and descent) from just inside the curves;
- :mod:`.grading` -- intermediate levels in bands much higher than their neighbours;
- :mod:`.crossings` -- where the levels cross the curves, and the curve nodes between them
  (half-way between the levels where the rows meet a curve square);
- :mod:`.rows` -- all the row nodes: rows from the crossings, then from gradient-line seeds;
- :mod:`.tracing` -- one level curve followed node by node (predictor-corrector);
- :mod:`.respacing` -- the nodes of a row spaced evenly, in phase with its neighbours;
- :mod:`.fill` -- circumcenters inserted where no row reaches;
- :mod:`.stagger` -- every apex slid above the midpoint of the row edge it faces;
- :mod:`.assemble` -- :func:`place_layers`, the stages in order.

Shared by the stages: :mod:`.rowstep` (the node step along a row), :mod:`.curves` (points
just off a curve, distances to the curves, steps that cross an interface) and
:mod:`.records` (the mixin of the frozen dataclasses of parallel arrays the stages pass).
"""

from __future__ import annotations

from .assemble import place_layers

__all__ = ["place_layers"]
