"""The final verification of a 2D mesh: every claim re-checked before it is returned.

:func:`finish` checks the triangulation (:meth:`hetmesh.mesh.Mesh.problems`), conformity to
every boundary and interface edge, the curves chord by chord (:mod:`hetmesh.tri.verify`),
delta_max < delta_0 (Eq. 1), the largest size, curve nodes on their curves and, for a
piecewise field, no element across a material discontinuity; then builds the
:class:`~hetmesh.mesh.Mesh` in user coordinates and its statistics.
"""

from __future__ import annotations

import logging

import numpy as np

from ..errors import MeshDataError, VerificationError
from ..material.field import element_subregions, has_subregions
from ..mesh import Mesh
from ..metrics import MeshStats, delta_dense, quality_and_angle, statistics
from ..options import DEFAULT_CHORD_TOL
from ..topology import unique
from .corners import corner_exempt, sharp_corners
from .discontinuity import FIT_TOL, crossing_elements
from .refine import too_long
from .verify import chord_areas, chord_problems, coverage_problems
from .workset import Context, WorkSet, edge_params

__all__ = ["finish", "named_nodes", "curve_problems", "ON_CURVE_TOL", "MAX_EDGE_MARGIN",
           "CHORD_TOL"]

log = logging.getLogger(__name__)

#: the largest sagitta of a boundary or interface chord, relative to the domain's diameter:
#: the default of ``chord_tol`` (:data:`hetmesh.options.DEFAULT_CHORD_TOL`)
CHORD_TOL = DEFAULT_CHORD_TOL



#: how far a curve node may be from its curve in the final verification, x diameter
ON_CURVE_TOL = 1e-8



#: ``max_size`` is enforced as the longest edge less this (relative), against rounding in
#: the user's coordinates
MAX_EDGE_MARGIN = 1e-9



def curve_problems(ws: WorkSet, ctx: Context, local: Mesh, scale: float) -> list[str]:
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
    problems += curve_problems(ws, ctx, local, frame.scale)
    if check_delta and delta.max() >= threshold:
        problems.append(f"delta_max {delta.max():.6g} >= threshold {threshold:g}")
    if too_long(P, tris, None if ctx.max_edge is None else
                 ctx.max_edge / (1.0 - MAX_EDGE_MARGIN)).any():
        problems.append(f"an edge is longer than max_size {ctx.h_max * frame.scale:g}")
    on = ws.vcurve >= 0
    if on.any():
        off = 0.0
        for c in unique(ws.vcurve[on]):
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
                named_points=named_nodes(P, ctx.domain),
                point_data={name: comp[:, k] for k, name in enumerate(ctx.field.constituents)},
                cell_data=cell_data)
    dense = delta_dense(ctx.field, P, tris, regions=cell_data.get("subregion"))
    return mesh, statistics(P, tris, delta, quality=q, angle=ang, dense=dense)



def named_nodes(P: np.ndarray, domain) -> dict[str, int]:
    """The node at each named point of ``domain`` (fixed vertices; local coordinates)."""
    out = {}
    for name, xy in domain.points.items():
        d = np.hypot(*(P - np.asarray(xy, np.float64)).T)
        i = int(np.argmin(d))
        if d[i] <= ON_CURVE_TOL * domain.diameter:
            out[name] = i
    return out

