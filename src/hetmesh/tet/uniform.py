"""The uniform tetrahedral baseline: the coarsest mesh of one size h meeting delta_0.

The 3D counterpart of :func:`hetmesh.tri.uniform.uniform`. At a size ``h`` the solid's
section (a prism: box, cylinder, extrusion) or profile (a solid of revolution) gets the 2D
uniform quality mesh of edge ~h (:func:`hetmesh.tri.uniform.uniform_at`: boundary curves
split into pieces of ~h, a hexagonal lattice inside, the feature tree's discontinuities
embedded), which is swept through layers of thickness ~h along the axis, or through angular
steps of at most ~h at the largest radius about it; every triangular prism becomes three
tetrahedra (:func:`hetmesh.tet.extrude.prism_tets`). No element is refined for the material:
delta(T) over the four vertices is measured, and the size is searched as in 2D -- lowered by
0.8 until delta_max < delta_0, raised by 1.25 until it fails, then bisected on log h until the
passing and failing sizes are within 2 % -- and the coarsest passing mesh is verified
(:func:`hetmesh.tet.verify.tet_problems`, :func:`hetmesh.tet.revolve.revolution_problems`)
and returned. Every size's element count is estimated before it is meshed, so a threshold
that would need more than ``max_elements`` raises :class:`~hetmesh.errors.BudgetError`
instead of running on.

Solids with no section to sweep are remeshed by MMG to the one size ``h`` from the start the
adaptive mesher of that kind uses, nothing refined for the material: a solid of primitives
(:func:`hetmesh.tet.general.uniform_solid_at`), a closed triangulated surface
(:func:`uniform_surface_at`: the builtin fill of the input triangles, MMG's
Hausdorff distance half the chord tolerance) and the non-zero voxels of a mask
(:func:`uniform_mask_at`: the cut voxel-centre grid, MMG's Hausdorff distance in voxels,
the optimisation pass and the polish of the adaptive mask mesh, every phase of a label
volume kept) and an extrusion or a revolution minus primitives
(:func:`uniform_carved_at`: the cut and projected swept background, the
slivers removed as in the adaptive mesh). Each is verified as the adaptive mesh of that
kind is.

>>> import hetmesh
>>> r = uniform_tets(hetmesh.load_model(hetmesh.example_path("unit_cube")), 0.3)
>>> r.mesh.cell_type, bool(r.stats.delta_max < 0.3), r.options["placement"]
('tetra', True, 'uniform swept')
"""

from __future__ import annotations

import dataclasses
import logging
import math
import time

import numpy as np

from ..errors import BudgetError, OptionError, VerificationError
from ..kernel import Result
from ..material import has_subregions
from ..mesh import simplex_measures
from ..metrics import delta_vertices
from ..topology import unique
from .api import DEFAULT_MAX_ELEMENTS, result_statistics, to_mesh
from .carve import (
    CarvedSolid,
    carved_problems,
    carved_start,
    remesh_carved,
    remove_slivers,
    section_field,
)
from .columns import face_multiplicity, strip_faces, strip_problems, swept_interfaces
from .extrude import cut_face_names, prism_cuts, prism_tets
from .faces import boundary_faces
from .general import (
    HGRAD,
    REGULAR_PER_H3,
    cap_curved,
    check_count,
    check_estimate,
    estimate_regular,
    mmg_remesh,
    solid_problems,
    uniform_solid_at,
    with_interfaces,
)
from .implicit import CSGSolid
from .masked import (
    HAUSD,
    VoxelSolid,
    boundary_estimate,
    cut_mask,
    mask_problems,
    phase_delta,
    polish,
    remesh_phases,
)
from .mesher import TetResult
from .revolve import on_half_planes, revolution_cuts
from .surface import SurfaceSolid
from .sweep_regions import interface_edges, on_axial_planes, plane_faces, region_problems
from .verify import raise_problems

__all__ = ["uniform_tets", "uniform_model", "uniform_tets_at", "verify_uniform",
           "SectionMesher", "estimate_uniform", "section_chord", "TETS_PER_H3",
           "uniform_surface_at", "uniform_mask_at", "surface_start", "estimate_remeshed",
           "REGULAR_PER_H3"]

log = logging.getLogger(__name__)

#: tetrahedra per h^3 of volume in a swept uniform mesh: 4 / (sqrt(3) h^2) triangles per
#: unit area (equilateral, edge h), 3 tetrahedra per triangle and layer of thickness h
TETS_PER_H3 = 12.0 / math.sqrt(3.0)
#: default chord tolerance of curved faces, x the solid's diameter (as for the adaptive mesh)
CHORD = 2e-3
#: stop the size search when the failing and passing sizes are this close (ratio)
BRACKET = 1.02


def _is_revolution(solid) -> bool:
    from .revolve import Revolution

    return isinstance(solid, Revolution)


def section_chord(solid, chord_tol: float | None) -> float:
    """The 2D mesh's chord tolerance relative to the section's (profile's) diameter, from the
    solid's (relative to its diameter): all of it for a prism, half for a revolution (the
    angular steps take the other half). Without ``chord_tol``, a prism's section takes the
    2D mesher's default, as the adaptive sweep's does (the baseline meets the same bound)."""
    from ..options import DEFAULT_CHORD_TOL

    revolved = _is_revolution(solid)
    dom = solid.profile if revolved else solid.section
    if chord_tol is None and not revolved:
        return float(DEFAULT_CHORD_TOL)
    chord = (CHORD if chord_tol is None else float(chord_tol)) * solid.diameter
    return min(max((0.5 if revolved else 1.0) * chord / dom.diameter, 1e-7), 0.05)


def estimate_uniform(solid, h: float) -> float:
    """A-priori tetrahedron count of a swept uniform mesh of size ``h`` (volume x
    :data:`TETS_PER_H3` / h^3, plus 10 % for the boundary)."""
    return 1.1 * TETS_PER_H3 * float(solid.volume) / h ** 3 + 100.0


class SectionMesher:
    """The 2D uniform quality meshes of a solid's section (or profile), one per size.

    The 2D model -- the section or profile and its 2D field (the extruded model's own field,
    the axisymmetric profile field, or the field on the middle section) -- is prepared once
    (discontinuities embedded, local frame); :meth:`__call__` meshes it at edge ``h`` (user
    units) and returns the verified :class:`~hetmesh.mesh.Mesh` (subregions as cell data
    ``subregion``; delta is not required of it) and the triangles' delta over their
    vertices in the 2D field.
    """

    def __init__(self, model, threshold: float, chord_rel: float):
        from ..io.model import Model
        from ..tri.discontinuity import embed_discontinuities
        from ..tri.pipeline import prepare
        from .extrude import mid_section_field
        from .revolve import profile_field

        solid = model.solid
        if _is_revolution(solid):
            domain = solid.profile
            f2 = model.material2d or profile_field(model.material, solid)
        else:
            domain = solid.section
            f2 = model.material2d or mid_section_field(solid, model.material)
        self.threshold = float(threshold)
        self.model2d = embed_discontinuities(Model(name=model.name, domain=domain,
                                                   material=f2))
        self.ctx, self.frame = prepare(self.model2d, self.threshold, None, chord_rel,
                                       gradation=0.0)

    def __call__(self, h: float, *, min_angle: float = 30.0, max_elements: int | None = None):
        from ..tri.finish import finish
        from ..tri.refine import evaluate
        from ..tri.uniform import uniform_at

        kw = {} if max_elements is None else {"max_elements": int(max_elements)}
        ws, tris = uniform_at(self.ctx, float(h) / self.frame.scale, min_angle_deg=min_angle,
                              **kw)
        comp, delta = evaluate(self.ctx, ws, tris, "vertices")
        mesh, _ = finish(ws, self.ctx, tris, comp, delta, self.frame,
                         threshold=self.threshold, min_angle_deg=min_angle, check_delta=False)
        return mesh, delta


def _layer_levels(s0: float, s1: float, h: float) -> np.ndarray:
    nl = max(1, int(math.ceil((s1 - s0) / h - 1e-9)))
    levels = s0 + (s1 - s0) * np.arange(nl + 1) / nl
    levels[-1] = s1
    return levels


def _sweep_prism(solid, p2, t2, h, cuts=()):
    """The section mesh swept through layers of thickness at most ``h``, every jump plane
    of ``cuts`` (axis values) a level."""
    ends = np.concatenate([[solid.s0], np.asarray(cuts, dtype=float), [solid.s1]])
    levels = np.concatenate([_layer_levels(a, b, h)[:-1] for a, b in zip(ends[:-1], ends[1:])]
                            + [[solid.s1]])
    nl = len(levels) - 1
    pl, tets, _ = prism_tets(p2, t2, levels)
    points = solid.to3d(pl[:, :2], pl[:, 2])
    tri_of = np.tile(np.repeat(np.arange(len(t2)), 3), nl)
    return points, tets, tri_of, {"layers": nl, "column": np.arange(len(pl)) % len(p2)}


def _angular_steps(solid, p2, h, chord) -> int:
    r_max = max(float(p2[:, 0].max()), 1e-300)
    step_chord = 2.0 * math.acos(max(-1.0, 1.0 - 0.5 * chord / r_max))
    step = min(step_chord, h / r_max)
    return max(3 if solid.full else 1, int(math.ceil(solid.sweep / step - 1e-9)))


def _sweep_revolution(solid, p2, t2, h, chord, cuts=()):
    """The profile mesh turned through equal angular steps of at most ``h`` at the largest
    radius (and within the chord tolerance there), every jump half-plane's angle of
    ``cuts`` a step; the copies of a vertex on the axis, and of the last angle of a full
    turn, merged; the collapsed tetrahedra dropped."""
    n = _angular_steps(solid, p2, h, chord)
    if len(cuts):
        ends = np.concatenate([[0.0], np.asarray(cuts, dtype=float)[np.asarray(cuts) > 0],
                               [solid.sweep]])
        theta = np.concatenate([_layer_levels(a, b, solid.sweep / n)[:-1]
                                for a, b in zip(ends[:-1], ends[1:])] + [[solid.sweep]])
        n = len(theta) - 1
    else:
        theta = solid.sweep * np.arange(n + 1) / n
    pl, tets, _ = prism_tets(p2, t2, theta)
    n2 = len(p2)
    ids = np.arange(len(pl))
    if solid.full:
        ids[n * n2:] = ids[:n2]
    on_axis = np.flatnonzero(np.abs(p2[:, 0]) <= 1e-12 * solid.profile.diameter)
    for j in range(n + 1):
        ids[j * n2 + on_axis] = ids[on_axis]
    tets = ids[tets]
    keep = (np.diff(np.sort(tets, axis=1), axis=1) > 0).all(axis=1)
    tets = tets[keep]
    used, inv = unique(tets, return_inverse=True)
    q = pl[used]
    points = solid.to3d(q[:, :2], q[:, 2])
    points[np.abs(q[:, 0]) <= 1e-12 * solid.profile.diameter, :2] = 0.0
    tri_of = np.tile(np.repeat(np.arange(len(t2)), 3), n)[keep]
    return points, inv.reshape(-1, 4), tri_of, {"angular_steps": n, "column": used % n2}


def _delta(field, points, tets, regions):
    """delta(T) over the vertices, each vertex evaluated in its tetrahedron's subregion when
    the field has subregions (a vertex on a discontinuity takes its element's side)."""
    if regions is None:
        return delta_vertices(field.composition(points), tets)
    c = field.composition(points[tets.ravel()], region=np.repeat(regions, 4))
    c = c.reshape(len(tets), 4, -1)
    return (c.max(axis=1) - c.min(axis=1)).max(axis=1)


def uniform_tets_at(model, h: float, threshold: float, *, sections: SectionMesher | None = None,
                    chord_tol: float | None = None, max_elements: int | None = None,
                    min_angle: float = 30.0) -> TetResult:
    """The swept uniform tetrahedral mesh of ``model`` (a 3D model) at size ``h`` (model
    units), not verified: its ``delta`` over the vertices, ``threshold`` recorded but not
    required. ``sections``: a :class:`SectionMesher` of the model to reuse; ``chord_tol``
    relative to the solid's diameter (default :data:`CHORD`)."""
    solid = model.solid
    chord = (CHORD if chord_tol is None else float(chord_tol)) * solid.diameter
    revolved = _is_revolution(solid)
    dom = solid.profile if revolved else solid.section
    sec_rel = section_chord(solid, chord_tol)
    if sections is None:
        sections = SectionMesher(model, threshold, sec_rel)
    est = check_estimate(h, estimate_uniform(solid, h), max_elements)
    m2, _ = sections(h, min_angle=min_angle, max_elements=max_elements)
    p2, t2 = np.asarray(m2.points), np.asarray(m2.cells, dtype=np.int64)
    cuts = ()
    moving = has_subregions(model.material) and not _is_swept(model)  # jumps may move
    if revolved:
        cuts = revolution_cuts(solid, model.material) if moving else ()
        points, tets, tri_of, info = _sweep_revolution(solid, p2, t2, h, chord, cuts)
    else:
        cuts = prism_cuts(solid, model.material) if moving else ()
        points, tets, tri_of, info = _sweep_prism(solid, p2, t2, h, cuts)
    check_count(h, len(tets), max_elements)
    v = simplex_measures(points, tets)
    tets[v < 0] = tets[v < 0][:, [0, 1, 3, 2]]
    tets = tets.astype(np.int32)
    sub2 = m2.cell_data.get("subregion") if m2.cell_data else None
    regions = None if sub2 is None else np.asarray(sub2)[tri_of].astype(np.int32)
    if len(cuts):  # every layer's own subregions
        regions = np.asarray(model.material.region(points[tets].mean(axis=1)),
                             dtype=np.int32)
    delta = _delta(model.material, points, tets, regions)
    faces, _ = boundary_faces(tets)
    markers = solid.classify_faces(points[faces]) + 1
    column = info.pop("column")  # the section vertex of every point
    tol, chord2 = 1e-9 * solid.diameter, sec_rel * dom.diameter
    if dom.interfaces:  # the interface curves' sweeps, after the boundary
        inter, im = swept_interfaces(dom, p2, t2, m2.facets, tets, column, tol, chord2)
        faces, markers = np.concatenate([faces, inter]), np.concatenate([markers, im])
    # then the material discontinuities the section mesher embedded, as the adaptive
    # sweeps record them: faces discontinuity[k] after the solid's
    ie, imark, disc = interface_edges(dom, sections.model2d.domain, p2, t2, m2.facets, tol,
                                      chord2, len(solid.face_names))
    if disc:
        d = imark > len(solid.face_names)
        f2, k2 = strip_faces(tets, column, ie[d])
        faces, markers = np.concatenate([faces, f2]), np.concatenate([markers, imark[d][k2]])
    cut_names = ()
    if len(cuts):  # then the jump planes across the axis (half-planes of a revolution)
        if revolved:
            on = on_half_planes(points, cuts, 1e-9 * solid.diameter)
        else:
            on = on_axial_planes(points, solid.axis, cuts)
        f3, k3 = plane_faces(tets, on)
        cut_names = cut_face_names(disc, len(cuts))
        faces = np.concatenate([faces, f3])
        markers = np.concatenate([markers, len(solid.face_names) + len(disc) + 1 + k3])
        info["jump_planes"] = tuple(float(c) for c in cuts)
    info.update({"placement": "uniform swept" if not revolved else "uniform revolved",
                 "size": float(h), "section_triangles": int(len(t2)), "estimate": est,
                 "chord_tol": chord, "section_chord_tol": sec_rel * dom.diameter})
    res = TetResult(points, tets, faces.astype(np.int32), markers.astype(np.int32),
                    tuple(solid.face_names) + disc + cut_names, delta, float(threshold), info)
    if regions is not None:
        res.info["regions"] = regions
    return res


def verify_uniform(res: TetResult, solid, field=None) -> None:
    """Raise :class:`VerificationError` naming the first broken claim of a uniform mesh
    (validity, faces, chord tolerance, volume, delta_max < delta_0; with the ``field``,
    every tetrahedron in its subregion)."""
    if _is_revolution(solid):
        from .revolve import revolution_problems
        probs = revolution_problems(res, solid, None, res.info["chord_tol"])
    else:
        from .verify import tet_problems
        # the section's chords: as the 2D mesher verified them (1e-6 for rounding)
        probs = tet_problems(res.points, res.tets, res.faces, res.face_markers, solid,
                             res.delta, res.threshold,
                             res.info["section_chord_tol"] * (1 + 1e-6))
    # the recorded faces off the boundary (interfaces, discontinuities): each a face of two
    # tetrahedra, as the adaptive sweeps check theirs
    inner = face_multiplicity(res.tets, res.faces) != 1
    probs = probs + strip_problems(res.tets, res.faces[inner])
    if field is not None:
        probs += region_problems(field, res.points, res.tets, res.info.get("regions"))
    if probs:
        raise VerificationError(f"uniform tetrahedral mesh verification failed: {probs[0]}"
                                + (f" (and {len(probs) - 1} more)" if len(probs) > 1 else ""))


def _is_swept(model) -> bool:
    """Whether the composition is the section's (profile's) at every point of the sweep: an
    extruded 2D model, or an axisymmetric field on a solid of revolution. Then every
    tetrahedron's vertices are copies of one triangle's, among them all three: its delta is
    its triangle's, and the size search can run on the section's mesh alone."""
    if model.material2d is not None:
        return True
    if _is_revolution(model.solid):
        from .revolve import is_axisymmetric
        return is_axisymmetric(model.material, model.solid)
    return False


def _section_trial(model, h, threshold, sections, chord_tol, max_elements, min_angle):
    """The section's mesh at ``h`` standing for the swept mesh in the size search: a
    :class:`TetResult` without tetrahedra whose ``delta`` is the triangles' (the swept
    tetrahedra's, see :func:`_is_swept`) and whose ``info["elements"]`` is the number of
    tetrahedra the sweep makes (a vertex on the axis of a revolution merges: a triangle with
    k vertices on it gives 3 - k tetrahedra per step)."""
    solid = model.solid
    check_estimate(h, estimate_uniform(solid, h), max_elements)
    m2, delta2 = sections(h, min_angle=min_angle, max_elements=max_elements)
    p2, t2 = np.asarray(m2.points), np.asarray(m2.cells)
    if _is_revolution(solid):
        chord = (CHORD if chord_tol is None else float(chord_tol)) * solid.diameter
        n = _angular_steps(solid, p2, h, chord)
        on_axis = np.abs(p2[:, 0]) <= 1e-12 * solid.profile.diameter
        count = int((3 - on_axis[t2].sum(axis=1)).clip(0).sum()) * n
    else:
        count = 3 * len(t2) * max(1, int(math.ceil(solid.length / h - 1e-9)))
    check_count(h, count, max_elements)
    return TetResult(np.empty((0, 3)), np.empty((0, 4), dtype=np.int32),
                     np.empty((0, 3), dtype=np.int32), np.empty(0, dtype=np.int32),
                     tuple(solid.face_names), np.asarray(delta2), float(threshold),
                     {"size": float(h), "elements": count})


# -- remeshed solids without a section: triangulated surfaces, voxel masks ----------------

def estimate_remeshed(solid, h: float) -> float:
    """A-priori tetrahedron count of a remeshed uniform mesh of size ``h``: regular
    tetrahedra of edge ``h`` over the solid's volume (:data:`REGULAR_PER_H3`), plus, for a
    voxel mask, its boundary at the voxel size (as :func:`hetmesh.tet.masked.estimate_masked`
    adds it: a number per voxel face of the contour), plus 100
    (:func:`hetmesh.tet.general.estimate_regular`)."""
    est = estimate_regular(solid, h)
    if isinstance(solid, VoxelSolid):
        est += boundary_estimate(solid)
    return est


def _check_estimate(solid, h: float, max_elements: int | None) -> float:
    """:func:`hetmesh.tet.general.check_estimate` of :func:`estimate_remeshed`."""
    return check_estimate(h, estimate_remeshed(solid, h), max_elements)


def surface_start(solid: SurfaceSolid, chord: float):
    """The adaptive surface mesher's start (:func:`hetmesh.tet.surface_mesh.initial_volume`:
    the builtin fill of the input triangles) with its boundary triangles and their faces:
    ``(points, tets, faces, markers)``, shared by every size of the search."""
    from .surface_mesh import initial_volume, keep_markers

    p, t = initial_volume(solid)
    none = np.zeros((0, 3), dtype=np.int64)
    return (p, t) + keep_markers(solid, p, t, none, np.zeros(0, dtype=np.int64), chord)


def uniform_surface_at(solid: SurfaceSolid, field, h: float, threshold: float, *,
                       chord_tol: float | None = None, max_elements: int | None = None,
                       start=None) -> TetResult:
    """The uniform baseline's mesh of a solid inside a closed triangulated surface at size
    ``h``, not verified: the adaptive mesher's start (:func:`surface_start`, or ``start``)
    remeshed once by MMG to the constant size ``h`` with the Hausdorff distance half the
    chord tolerance ``chord_tol`` (absolute; default 2e-3 x the diameter), as the adaptive
    mesh is (MMG keeps the sharp edges as ridges and refines where the surface curves).
    Nothing is refined for the material: ``delta`` over the vertices is measured,
    ``threshold`` recorded but not required."""
    from .jumps import has_jumps
    from .surface_mesh import keep_markers, uniform_surface_jumps

    chord = CHORD * solid.diameter if chord_tol is None else float(chord_tol)
    est = _check_estimate(solid, h, max_elements)
    p, t, faces, markers = surface_start(solid, chord) if start is None else start
    if has_jumps(field):  # cut along the jumps, kept through the remeshing, delta per side
        p, t, faces, markers, phase, delta = uniform_surface_jumps(
            solid, field, h, threshold, (p, t, faces, markers), chord,
            max_elements=max_elements)
        check_count(h, len(t), max_elements)
        info = {"placement": "uniform remeshed", "size": float(h), "estimate": est,
                "chord_tol": chord, "composition": field.composition(p), "hgrad": HGRAD,
                "regions": np.asarray(phase, dtype=np.int32)}
        return with_interfaces(TetResult(p, t.astype(np.int32), faces.astype(np.int32),
                                         (markers + 1).astype(np.int32),
                                         tuple(solid.face_names), delta, float(threshold),
                                         info), field, len(solid.face_names))
    p, t, fm, rm, _, _ = mmg_remesh(p, t, faces, markers, np.full(len(p), float(h)),
                                 0.5 * chord)
    check_count(h, len(t), max_elements)
    faces, markers = keep_markers(solid, p, t, fm, rm, chord)
    comp = field.composition(p)
    info = {"placement": "uniform remeshed", "size": float(h), "estimate": est,
            "chord_tol": chord, "composition": comp, "hgrad": HGRAD}
    return TetResult(p, t.astype(np.int32), faces.astype(np.int32),
                     (markers + 1).astype(np.int32), tuple(solid.face_names),
                     delta_vertices(comp, t), float(threshold), info)


def uniform_mask_at(solid: VoxelSolid, field, h: float, threshold: float, *,
                    max_elements: int | None = None, start=None) -> TetResult:
    """The uniform baseline's mesh of the non-zero voxels of a mask at size ``h``: the
    adaptive mask mesher's start (:func:`hetmesh.tet.masked.cut_mask`, or ``start``)
    remeshed once by MMG to the constant size ``h``, then MMG's optimisation pass with the
    surface kept and the polish of thin tetrahedra (:func:`hetmesh.tet.masked.polish`), as
    in the adaptive mesh; the Hausdorff distances of :data:`hetmesh.tet.masked.HAUSD` are
    tried in turn until the voxel claims of :func:`hetmesh.tet.masked.mask_problems` hold
    (every centre on its side, the boundary and the interfaces between unlike centres;
    delta is not required here). Nothing is refined for the material: ``delta`` over the
    vertices (each tetrahedron in its phase) is measured, ``threshold`` recorded."""
    est = _check_estimate(solid, h, max_elements)
    p0, t0, ph0 = cut_mask(solid) if start is None else start
    probs: list[str] = []
    for hv in HAUSD:
        hausd = hv * solid.voxel
        p, t, phase, _ = remesh_phases(p0, t0, ph0, np.full(len(p0), float(h)), hausd)
        check_count(h, len(t), max_elements)
        p, t, phase, _ = remesh_phases(p, t, phase, None, hausd, optim=1, nosurf=1)
        check_count(h, len(t), max_elements)
        comp = field.composition(p)
        p, comp = polish(p, t, phase, comp, field, threshold)
        t = t.astype(np.int32)
        faces, _ = boundary_faces(t)
        markers = solid.classify_faces(p[faces])
        info = {"placement": "uniform remeshed", "size": float(h), "estimate": est,
                "hausd": hausd, "composition": comp}
        if solid.n_phases > 1:
            info["regions"] = phase.astype(np.int32)
        res = TetResult(p, t, faces.astype(np.int32), (markers + 1).astype(np.int32),
                        tuple(solid.face_names), phase_delta(field, p, t, phase, comp),
                        float(threshold), info)
        # the voxel claims alone: delta is measured, not required, at a trial size
        probs = mask_problems(dataclasses.replace(res, threshold=math.inf), solid, None)
        if not probs:
            return res
        log.info("uniform mask: h = %.4g, Hausdorff distance %.3g voxels: %s; again with "
                 "less", h, hv, probs[0])
    raise_problems(probs)
    return res  # not reached: raise_problems raised


def uniform_carved_at(solid: CarvedSolid, field, h: float, threshold: float, start, *,
                      chord_tol: float | None = None,
                      max_elements: int | None = None) -> TetResult:
    """The uniform baseline's mesh of a carved solid at size ``h``, not verified: the
    adaptive mesher's start (:func:`hetmesh.tet.carve.carved_start`, shared by every size)
    remeshed once by MMG to the constant size ``h``, capped on curved faces for the chord
    tolerance ``chord_tol`` (absolute; default :data:`CHORD` x the
    diameter) exactly as in the adaptive mesh, the boundary vertices projected onto their
    faces with the untangling of :func:`hetmesh.tet.carve.remesh_carved`, the slivers
    removed as in the adaptive mesh (:func:`hetmesh.tet.carve.remove_slivers`, no new
    tetrahedron reaching ``threshold``). Nothing is refined for the material: ``delta``
    over the vertices is measured, ``threshold`` recorded but not required
    (:func:`uniform_model` searches ``h`` and verifies the result with
    :func:`hetmesh.tet.carve.carved_problems`)."""
    chord = CHORD * solid.diameter if chord_tol is None else float(chord_tol)
    est = _check_estimate(solid, h, max_elements)
    p, t, faces, markers = start[:4]
    size = cap_curved(solid, np.full(len(p), float(h)), faces, markers, chord)
    p, t, faces, markers, _ = remesh_carved(solid, p, t, faces, markers, size, 0.5 * chord,
                                            max(0.25 * h, 10 * chord))
    check_count(h, len(t), max_elements)
    p, t, faces, markers, comp = remove_slivers(solid, p, t, faces, markers,
                                                field.composition(p), threshold, chord)
    info = {"placement": "uniform remeshed", "size": float(h), "estimate": est,
            "chord_tol": chord, "composition": comp}
    return TetResult(p, t.astype(np.int32), faces.astype(np.int32),
                     (markers + 1).astype(np.int32), tuple(solid.face_names),
                     delta_vertices(comp, t), float(threshold), info)


def _remeshed_start(model, threshold: float, chord: float, max_elements: int | None):
    """The adaptive mesher's start that every size of a remeshed solid's search shares: a
    surface's first volume mesh (:func:`surface_start`), a mask's cut voxel-centre grid
    (:func:`hetmesh.tet.masked.cut_mask`), a carved solid's cut and projected background
    (:func:`hetmesh.tet.carve.carved_start`, swept from its section's or profile's field)."""
    from ..io.model import Model

    solid = model.solid
    if isinstance(solid, SurfaceSolid):
        return surface_start(solid, chord)
    if isinstance(solid, VoxelSolid):
        return cut_mask(solid)
    section = Model(name=model.name, domain=solid.domain,
                    material=section_field(solid, model.material))
    return carved_start(solid, model.material, threshold, section, chord_tol=chord,
                        max_elements=max_elements)


def _start_size(model, threshold: float) -> float:
    """delta_0 / max |grad f| over sample points (the size at which a straight edge along
    the steepest gradient varies by delta_0), at most a quarter of the section's diameter."""
    solid = model.solid
    p = solid.sample(16)
    g = np.linalg.norm(model.material.gradient(p), axis=2).max() if len(p) else 0.0
    if isinstance(solid, (CSGSolid, SurfaceSolid, VoxelSolid, CarvedSolid)):
        cap = solid.diameter / 4
    else:
        cap = (solid.profile if _is_revolution(solid) else solid.section).diameter / 4
    return float(min(threshold / g, cap)) if g > 0 else float(cap)


def uniform_model(model, threshold: float, *, chord_tol: float | None = None,
                  max_elements: int | None = DEFAULT_MAX_ELEMENTS, min_angle: float = 30.0,
                  tries: int = 14, progress=None) -> TetResult:
    """The coarsest uniform tetrahedral mesh of a 3D model with delta_max < ``threshold``,
    verified, as a :class:`~hetmesh.tet.mesher.TetResult` (as
    :func:`hetmesh.tet.api.mesh_model` returns; :func:`uniform_tets` wraps it as a
    :class:`~hetmesh.kernel.Result`): ``info["size"]`` the size used, ``info["history"]``
    every size tried, ``info["composition"]`` the vertex compositions, ``mesh`` the
    :class:`~hetmesh.mesh.Mesh`. Options as :func:`uniform_tets`.
    """
    if isinstance(threshold, bool) or not isinstance(threshold, (int, float)) \
            or not 0 < threshold < 1:
        raise OptionError(f"threshold must be in (0, 1), got {threshold!r}")
    if chord_tol is not None and not 1e-7 <= chord_tol <= 0.05:
        raise OptionError(f"chord_tol must be in [1e-7, 0.05], got {chord_tol!r}")
    if max_elements is not None and max_elements < 1:
        raise OptionError(f"max_elements must be positive, got {max_elements!r}")
    if not 0 < min_angle < 35:
        raise OptionError(f"min_angle must be in (0, 35) degrees, got {min_angle!r}")
    t0 = time.perf_counter()
    threshold = float(threshold)
    solid = model.solid
    remeshed = isinstance(solid, (CSGSolid, SurfaceSolid, VoxelSolid, CarvedSolid))
    if not (remeshed or _is_revolution(solid) or hasattr(solid, "section")):
        raise OptionError(f"a uniform mesh of {model.name} is not available: the uniform "
                          f"tetrahedral mesher takes prisms (boxes, cylinders, extrusions), "
                          f"solids of revolution, solids of primitives, extrusions and "
                          f"revolutions minus primitives, triangulated surfaces and voxel "
                          f"masks, not {type(solid).__name__}")
    sections = None if remeshed else SectionMesher(model, threshold,
                                                   section_chord(solid, chord_tol))
    chord_abs = (CHORD if chord_tol is None else float(chord_tol)) * solid.diameter
    start = None  # the remeshed start of a surface, a mask or a carved solid, shared by
    # every size
    h = _start_size(model, threshold)
    best: TetResult | None = None
    best_count = 0
    h_pass = h_fail = None
    history = []
    swept = _is_swept(model)
    for i in range(tries):
        try:
            if start is None and isinstance(solid, (SurfaceSolid, VoxelSolid, CarvedSolid)):
                _check_estimate(solid, h, max_elements)  # the budget before the start
                start = _remeshed_start(model, threshold, chord_abs, max_elements)
            if isinstance(solid, SurfaceSolid):
                res = uniform_surface_at(solid, model.material, h, threshold,
                                         chord_tol=chord_abs, max_elements=max_elements,
                                         start=start)
            elif isinstance(solid, VoxelSolid):
                res = uniform_mask_at(solid, model.material, h, threshold,
                                      max_elements=max_elements, start=start)
            elif isinstance(solid, CarvedSolid):
                res = uniform_carved_at(solid, model.material, h, threshold, start,
                                        chord_tol=chord_abs, max_elements=max_elements)
            elif remeshed:
                res = uniform_solid_at(solid, model.material, h, threshold,
                                       chord_tol=chord_abs, max_elements=max_elements)
            elif swept:
                res = _section_trial(model, h, threshold, sections, chord_tol, max_elements,
                                     min_angle)
            else:
                res = uniform_tets_at(model, h, threshold, sections=sections,
                                      chord_tol=chord_tol, max_elements=max_elements,
                                      min_angle=min_angle)
        except BudgetError as exc:
            if h_pass is None:
                raise BudgetError(f"no uniform tetrahedral mesh meets delta_max < "
                                  f"{threshold:g} within the budget: {exc}") from None
            h_fail = h if h_fail is None else min(h_fail, h)  # above the budget: too fine
            history.append({"round": i, "h": h, "elements": None, "delta_max": None,
                            "pass": False})
            res = None
        if res is not None:
            dmax = float(res.delta.max())
            ok = dmax < threshold
            n_el = int(res.info.get("elements", len(res.tets)))
            history.append({"round": i, "h": h, "elements": n_el,
                            "delta_max": dmax, "pass": bool(ok)})
            log.info("uniform 3D: h = %.4g, %d tetrahedra, delta_max = %.4g (%s)", h,
                     n_el, dmax, "pass" if ok else "fail")
            if ok:
                if remeshed and h_fail is None and best is not None and n_el >= best_count:
                    break  # a larger size no longer coarsens: the chords set the mesh
                if best is None or n_el < best_count:
                    best, best_count = res, n_el
                h_pass = h if h_pass is None else max(h_pass, h)
            else:
                h_fail = h if h_fail is None else min(h_fail, h)
        if progress:
            progress("uniform", (i + 1) / tries)
        if h_pass is None:
            h *= 0.8
        elif h_fail is None:
            h *= 1.25
        else:
            if h_fail / h_pass < BRACKET:
                break
            h = math.sqrt(h_pass * h_fail)
    if best is None:
        raise BudgetError(f"no uniform tetrahedral mesh met delta_max < {threshold:g} within "
                          f"{tries} sizes (the last {history[-1]['h']:.4g})")
    if swept:  # the search ran on the section: sweep the coarsest passing size once
        best = uniform_tets_at(model, best.info["size"], threshold, sections=sections,
                               chord_tol=chord_tol, max_elements=max_elements,
                               min_angle=min_angle)
    if isinstance(solid, SurfaceSolid):  # as the adaptive mesh of each kind is verified
        from .surface_mesh import surface_problems
        raise_problems(surface_problems(best, solid, model.material, chord_abs))
    elif isinstance(solid, VoxelSolid):
        raise_problems(mask_problems(best, solid, model.material))
    elif isinstance(solid, CarvedSolid):
        raise_problems(carved_problems(best, solid, model.material, chord_abs))
    elif remeshed:  # with the field: delta per phase and the jumps' claims
        raise_problems(solid_problems(best, solid, model.material, chord_abs))
    else:
        verify_uniform(best, solid, model.material)
    best.info["composition"] = np.asarray(model.material.composition(best.points),
                                          dtype=np.float64)
    best.mesh = to_mesh(best, model.constituents)
    best.info["history"] = history
    best.info["time_total"] = time.perf_counter() - t0
    return best


def uniform_tets(model, threshold: float, *, chord_tol: float | None = None,
                 max_elements: int | None = DEFAULT_MAX_ELEMENTS, min_angle: float = 30.0,
                 tries: int = 14, progress=None, **options) -> Result:
    """The coarsest uniform tetrahedral mesh of a 3D model with delta_max < ``threshold``
    (the 3D counterpart of :func:`hetmesh.tri.uniform.uniform`), verified.

    Parameters
    ----------
    model : Model3D
    threshold : float
        delta_0 in (0, 1).
    chord_tol : float, optional
        Largest distance between a curved face and its triangles, relative to the solid's
        diameter (default 0.002, as :func:`hetmesh.tet.api.mesh_model`).
    max_elements : int, optional
        Budget: a size whose estimate or mesh exceeds it ends the search with
        :class:`BudgetError`.
    min_angle : float
        Smallest angle of the section's triangles (degrees).
    tries : int
        Most sizes tried.
    progress : callable ``(stage, fraction)``, optional
    **options
        ``seed`` and ``sampling="vertices"`` are accepted (the mesh does not depend on a
        seed; delta is over the vertices); anything else raises.

    Returns
    -------
    Result
        ``options["size"]`` the size used, ``history`` every size tried.

    Examples
    --------
    >>> r = hetmesh.uniform(hetmesh.load_model("graded_cylinder.toml"), 0.1)   # doctest: +SKIP
    """
    for key, value in options.items():
        if key == "seed":
            continue
        if key == "sampling" and value in (None, "vertices"):
            continue
        if key in ("sampling", "max_size", "method", "row_spacing", "min_quality",
                   "optimize"):
            if value is None:
                continue
            raise OptionError(f"{key}={value!r} is not available for uniform 3D meshes")
        raise TypeError(f"uniform() got an unexpected keyword argument {key!r}")
    t0 = time.perf_counter()
    best = uniform_model(model, threshold, chord_tol=chord_tol, max_elements=max_elements,
                         min_angle=min_angle, tries=tries, progress=progress)
    seconds = time.perf_counter() - t0
    stats = result_statistics(best, best.delta)
    opts = dict(threshold=threshold, size=float(best.info["size"]), chord_tol=chord_tol,
                max_elements=max_elements, min_angle=min_angle,
                placement=best.info["placement"])
    return Result(mesh=best.mesh, stats=stats, threshold=float(threshold),
                  history=best.info["history"],
                  timings={"total": seconds}, options=opts, model=model)
