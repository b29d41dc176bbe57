"""Solids of revolution: a 2D profile in the ``(r, z)`` half-plane turned about the z axis.

The profile is a :class:`~hetmesh.tri.geometry.Domain` whose first coordinate is the
distance ``r >= 0`` to the axis and whose second is ``z``; it may touch the axis (a sphere is
a half-disc turned a full turn) but not cross it. The faces are the surfaces swept by the
profile's curves (those lying on the axis sweep nothing) and, for a partial turn, the two
planar ends ``start`` (angle 0) and ``end``.

The mesh is the verified 2D mesh of the profile swept about the axis through columns of
points, one per profile vertex (:func:`hetmesh.tet.columns.column_tets`, as
:mod:`hetmesh.tet.extrude` sweeps along a straight axis): every column has its own angular
step (:func:`angular_counts`: arcs of about the local edge length, within the chord
tolerance), and a vertex on the axis is a column of one point, so the cells at the axis are
filled by the moves of their other corners. When the composition does not depend on the
angle (an axisymmetric field), every tetrahedron's vertices are copies of one triangle's:
its delta is at most the triangle's, exactly; otherwise the violators are repaired by edge
bisection. The profile's interface curves, embedded in the 2D mesh, sweep into interface
surfaces of tetrahedron faces (:func:`hetmesh.tet.columns.swept_interfaces`), recorded with the
boundary faces under their curves' names, then the embedded discontinuities as faces
``discontinuity[k]``; with a composition that varies with the angle,
:mod:`hetmesh.tet.sweep_regions` keeps them (and the subregions) through the repair. Jumps
on half-planes through the axis (a sector of another material) are the angles between
layers, each turned through its own steps (:func:`revolution_cuts`), recorded as faces
``discontinuity[k]`` after the profile's.

>>> from hetmesh.tri.geometry import Loop, make_domain
>>> ring = Revolution(make_domain(Loop.polygon([(1, 0), (2, 0), (2, 1), (1, 1)], "p")))
>>> round(ring.volume, 9) == round(3 * 3.141592653589793, 9)
True
"""

from __future__ import annotations

import logging
import math
import time
from dataclasses import dataclass, field, replace
from functools import cached_property

import numpy as np

from ..errors import GeometryError, VerificationError
from ..material import has_subregions
from ..mesh import simplex_measures
from ..metrics import delta_vertices
from ..topology import unique
from .columns import layered_column_tets, strip_problems, vertex_size
from .extrude import COLUMN_RATIO, SectionField, cut_face_names
from .faces import boundary_faces
from .mesher import TetResult
from .refine import corner_compositions, repair
from .smooth import smooth
from .solid import grid_inside
from .sweep_mmg import improve_result
from .sweep_regions import (
    PlaneField,
    area,
    axial_cuts,
    interface_edges,
    plane_faces,
    plane_problems,
    region_problems,
    repaired_sweep,
    section_grid,
    surface_problems,
    sweep_faces,
    warn_thin_layers,
)
from .verify import validity_problems

__all__ = ["Revolution", "RevolvedField", "generate_revolved", "is_axisymmetric",
           "profile_field", "profile_angle", "revolution_cuts", "on_half_planes",
           "half_plane_distance"]

log = logging.getLogger(__name__)

#: default chord tolerance of curved faces, x the solid's diameter
CHORD = 2e-3
#: widest angular step of a column (radians): the fronts of a cell stay nearly planar
MAX_STEP = math.pi / 6
#: whether the repaired revolutions (compositions varying with the angle) get the MMG pass
#: (:func:`hetmesh.tet.sweep_mmg.improve_result`), kept where it verifies and is better
MMG_PASS = True


@dataclass(frozen=True, eq=False)
class Revolution:
    """The profile ``(r, z)`` turned by ``angle`` degrees (0 < angle <= 360) about z."""

    profile: object
    angle: float = 360.0
    where: str = field(default="", compare=False)

    def __post_init__(self):
        pre = f"{self.where}: " if self.where else ""
        if not (math.isfinite(self.angle) and 0 < self.angle <= 360):
            raise GeometryError(f"{pre}revolution angle must be in (0, 360] degrees, got "
                                f"{self.angle:g}")
        x0 = self.profile.bounds[0]
        tol = 1e-9 * self.profile.diameter
        if x0 < -tol:
            poly = self.profile.polygon()
            xs, ys = np.asarray(poly.exterior.coords).T
            i = int(np.argmin(xs))
            raise GeometryError(f"{pre}the revolution profile crosses the axis (r = x < 0), "
                                f"e.g. at ({xs[i]:.6g}, {ys[i]:.6g})")

    @property
    def full(self) -> bool:
        return self.angle >= 360.0

    @property
    def sweep(self) -> float:
        """The angle in radians."""
        return math.radians(self.angle)

    @cached_property
    def volume(self) -> float:
        """Pappus: sweep x (area x centroid radius) of the profile (polygon within 1e-7 of
        the curves)."""
        poly = self.profile.polygon(1e-9 * self.profile.diameter)
        return float(self.sweep * poly.area * poly.centroid.x)

    @cached_property
    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        x0, y0, x1, y1 = self.profile.bounds
        return np.array([-x1, -x1, y0]), np.array([x1, x1, y1])

    @property
    def diameter(self) -> float:
        lo, hi = self.bounds
        return float(np.linalg.norm(hi - lo))

    @cached_property
    def axis_curves(self) -> tuple[int, ...]:
        """Indices of the profile curves lying on the axis (they sweep no face)."""
        out = []
        tol = 1e-9 * self.profile.diameter
        for i, c in enumerate(self.profile.curves):
            p = c.curve.point(np.linspace(0, 1, 5))
            if np.abs(p[:, 0]).max() <= tol:
                out.append(i)
        return tuple(out)

    @cached_property
    def face_names(self) -> tuple[str, ...]:
        """``start``, ``end`` (partial turns only; else unused), then one per profile curve
        (an interface curve's surface lies inside the solid)."""
        return ("start", "end") + tuple(c.name for c in self.profile.curves)

    def classify_faces(self, tri_points: np.ndarray) -> np.ndarray:
        """The face (index in :attr:`face_names`) of boundary triangles given by their
        corners ``(K, 3, 3)``; -1 where a triangle lies on no face."""
        k = len(tri_points)
        pts = np.asarray(tri_points, dtype=float).reshape(-1, 3)
        faces = np.arange(3 * k).reshape(k, 3)
        return _classify(self, pts, faces, 0.0) - 1

    def to3d(self, q: np.ndarray, theta: np.ndarray) -> np.ndarray:
        q = np.asarray(q, dtype=float).reshape(-1, 2)
        return np.column_stack([q[:, 0] * np.cos(theta), q[:, 0] * np.sin(theta), q[:, 1]])

    def to2d(self, points) -> tuple[np.ndarray, np.ndarray]:
        """``((r, z) (N, 2), angle (N,) in [0, 2 pi))``."""
        p = np.asarray(points, dtype=float).reshape(-1, 3)
        th = np.mod(np.arctan2(p[:, 1], p[:, 0]), 2 * np.pi)
        return np.column_stack([np.hypot(p[:, 0], p[:, 1]), p[:, 2]]), th

    def contains(self, points) -> np.ndarray:
        q, th = self.to2d(points)
        ok = self.profile.contains(q)
        edge = ~ok
        if edge.any():  # the profile's boundary belongs to it
            ok[edge] = self.profile.distance_to_boundary(q[edge]) <= 1e-9 * self.diameter
        if not self.full:
            ok &= (th <= self.sweep + 1e-12) | (q[:, 0] <= 1e-12 * self.diameter)
        return ok

    def sample(self, n: int = 24) -> np.ndarray:
        """About ``n**3`` points of a regular grid over the bounds, those in the solid."""
        return grid_inside(self, n)


class RevolvedField(SectionField):
    """A 2D material field of the profile's ``(r, z)`` seen in 3D: the same at every angle
    (a feature tree of a revolved model keeps its subregions: ``region`` as in 2D). The
    composition is :class:`~hetmesh.tet.extrude.SectionField`'s through the solid's
    ``to2d``; the gradient turns d/dr into the radial direction."""

    def gradient(self, points) -> np.ndarray:
        p = np.asarray(points, dtype=float).reshape(-1, 3)
        q, _ = self.solid.to2d(p)
        g2 = self.field2d.gradient(q)  # (N, m, 2): d/dr, d/dz
        r = np.maximum(q[:, 0], 1e-300)
        out = np.empty(g2.shape[:2] + (3,))
        out[..., 0] = g2[..., 0] * (p[:, 0] / r)[:, None]
        out[..., 1] = g2[..., 0] * (p[:, 1] / r)[:, None]
        out[..., 2] = g2[..., 1]
        return out


def is_axisymmetric(field, solid: Revolution, n: int = 16) -> bool:
    """Whether the composition is the same at every angle (at sample points)."""
    x0, y0, x1, y1 = solid.profile.bounds
    r, z = np.meshgrid(np.linspace(x0, x1, n), np.linspace(y0, y1, n), indexing="ij")
    q = np.column_stack([r.ravel(), z.ravel()])
    ref = field.composition(solid.to3d(q, np.zeros(len(q))))
    for th in np.linspace(0.3, solid.sweep, 5):
        if np.abs(field.composition(solid.to3d(q, np.full(len(q), th))) - ref).max() > 1e-12:
            return False
    return True


def revolution_cuts(solid: Revolution, field) -> np.ndarray:
    """The angles of the half-planes through the axis on which a piecewise composition's
    jumps lie, sorted (:func:`~hetmesh.tet.sweep_regions.axial_cuts` over the sweep; for a
    full turn also 0 if the subregions differ on either side of it).
    :class:`~hetmesh.errors.MaterialError` if the jumps are neither those nor swept profile
    curves."""
    cuts = axial_cuts(field, solid.profile, solid.to3d, 0.0, solid.sweep, "the angle")
    if solid.full and has_subregions(field):
        first = cuts[0] if len(cuts) else solid.sweep
        last = cuts[-1] if len(cuts) else 0.0
        q = section_grid(solid.profile, 48)
        if len(q):
            a = field.region(solid.to3d(q, np.full(len(q), 0.01 * first)))
            b = field.region(solid.to3d(q, np.full(len(q), solid.sweep - 0.01 *
                                                   (solid.sweep - last))))
            if (np.asarray(a) != np.asarray(b)).any():
                cuts = np.concatenate([[0.0], cuts])
    return cuts


def _layer_levels(solid: Revolution, cuts: np.ndarray) -> np.ndarray:
    """The angles between the layers of a revolution: 0, the cuts, the sweep."""
    return np.concatenate([[0.0], cuts[cuts > 0], [solid.sweep]])


def profile_angle(solid: Revolution, field) -> float:
    """The angle of the profile a piecewise composition is meshed with: 0, or with jumps on
    half-planes the middle of the widest layer between them (off every jump)."""
    if not has_subregions(field):
        return 0.0
    cuts = revolution_cuts(solid, field)
    if not len(cuts):
        return 0.0
    levels = _layer_levels(solid, cuts)
    k = int(np.argmax(np.diff(levels)))
    return float(0.5 * (levels[k] + levels[k + 1]))


def profile_field(field, solid):
    """The composition in the plane at angle 0 as a 2D field of ``(r, z)`` (a piecewise
    field's with its subregions, at :func:`profile_angle`:
    :class:`~hetmesh.tet.sweep_regions.PlaneField`)."""
    from ..material import CallableField

    if has_subregions(field):
        th = profile_angle(solid, field)
        dirs = np.array([[math.cos(th), math.sin(th), 0.0], [0.0, 0.0, 1.0]])
        return PlaneField(field, lambda q: solid.to3d(q, np.full(len(q), th)), dirs)

    def f2(x, y):
        q = np.column_stack([np.ravel(x), np.ravel(y)])
        return field.composition(solid.to3d(q, np.zeros(len(q))))
    return CallableField(f2, field.constituents)


def generate_revolved(solid: Revolution, field, threshold: float, profile_model, *,
                      axisymmetric: bool, seed: int = 0, chord_tol: float | None = None,
                      max_elements: int | None = None, max_size: float | None = None,
                      check: bool = True) -> TetResult:
    """Tetrahedralise a solid of revolution by sweeping the 2D mesh of its profile.

    ``profile_model``: the profile (``solid.profile``) and the 2D field of ``(r, z)`` to mesh
    it with (:func:`profile_field`); ``axisymmetric``: whether the composition is the same
    at every angle (:func:`is_axisymmetric`: then the 2D guarantee carries over exactly,
    else the sweep is repaired by edge bisection); ``chord_tol`` absolute (default
    :data:`CHORD` x the diameter).
    """
    from ..options import DEFAULT_CHORD_TOL as CHORD_TOL
    from ..tri.pipeline import SWEEP_STARTS, generate

    t0 = time.perf_counter()
    chord = CHORD * solid.diameter if chord_tol is None else float(chord_tol)
    axisym = axisymmetric
    f2 = profile_model.material
    prof = solid.profile
    cuts = np.zeros(0)
    if not axisym and has_subregions(field):  # its jumps embedded in the profile's mesh
        cuts = revolution_cuts(solid, field)  # and on half-planes through the axis
        if len(cuts) or not has_subregions(f2):
            profile_model = replace(profile_model, material=profile_field(field, solid))
            f2 = profile_model.material
    # half of the tolerance for the profile's chords, half for the angular steps: an edge
    # across both deviates by at most the sum
    kw = {"chord_tol": min(max(0.5 * chord / prof.diameter, 1e-7), CHORD_TOL)}
    if max_size is not None:  # the profile's longest edge and the widest angular step
        kw["max_size"] = float(max_size)
    r2 = generate(profile_model, threshold, seed=seed, starts=SWEEP_STARTS, **kw)
    m2 = r2.mesh
    p2, t2 = np.asarray(m2.points), np.asarray(m2.cells, dtype=np.int64)
    n2 = len(p2)
    on_axis = np.abs(p2[:, 0]) <= 1e-12 * prof.diameter
    levels = _layer_levels(solid, cuts)  # the layers between the jump half-planes
    thin = False
    if len(cuts) and (~on_axis).any():  # a layer's arc against the profile's edge at every
        # vertex off the axis, where it is thinnest (its flat tetrahedra stay flat through
        # MMG: no pass then)
        r, e2 = p2[~on_axis, 0], vertex_size(p2, t2)[~on_axis]
        i = int(np.argmin(r / e2))
        thin = warn_thin_layers(np.diff(levels) * r[i], e2[i], levels, "the angle", log)
    counts = angular_counts(solid, p2, t2, chord, on_axis, max_size, levels=levels)
    ntet = int(counts[:, t2].sum())
    if max_elements is not None and ntet > max_elements:
        from ..errors import BudgetError
        raise BudgetError(f"about {ntet} tetrahedra are needed for delta_0 = {threshold} "
                          f"({len(t2)} triangles in the profile, "
                          f"{int(counts.sum(axis=0).max())} angular steps at most) but the "
                          f"budget is {max_elements}")
    pl, tets, tri_of, col = layered_column_tets(p2, t2, counts, levels)
    ids = np.arange(len(pl))
    if solid.full:  # the last angle of a column is its first
        first = np.full(n2, -1, dtype=np.int64)
        first[col[::-1]] = ids[::-1]
        top = pl[:, 2] == solid.sweep
        ids[top] = first[col[top]]
    tets = ids[tets]
    used, inv = unique(tets, return_inverse=True)
    q = pl[used]
    points = solid.to3d(q[:, :2], q[:, 2])
    on_axis_pts = np.abs(q[:, 0]) <= 1e-12 * prof.diameter
    points[on_axis_pts, :2] = 0.0
    tets = inv.reshape(-1, 4)
    v = simplex_measures(points, tets)
    tets[v < 0] = tets[v < 0][:, [0, 1, 3, 2]]
    sub2 = m2.cell_data.get("subregion") if m2.cell_data else None
    regions = None if sub2 is None else np.asarray(sub2)[tri_of]
    if len(cuts):  # every layer's own subregions (no tetrahedron crosses a half-plane)
        regions = np.asarray(field.region(points[tets].mean(axis=1)), dtype=np.int64)
    prof_ids = col[used]  # the 2D vertex of every point
    tol = 1e-9 * solid.diameter
    pchord = kw["chord_tol"] * prof.diameter
    ie, imark, disc = interface_edges(prof, r2.model.domain, p2, t2, m2.facets, tol, pchord,
                                      len(solid.face_names))
    traced = not axisym and len(ie) + (regions is not None) > 0
    nb = len(solid.face_names) + len(disc)
    planes = {nb + 1 + k: float(c) for k, c in enumerate(cuts)}  # marker -> angle
    carrier = None
    if axisym:
        if regions is None:
            delta = delta_vertices(f2.composition(p2)[prof_ids], tets)
        else:
            c = f2.composition(p2[prof_ids[tets].ravel()], region=np.repeat(regions, 4))
            c = c.reshape(len(tets), 4, -1)
            delta = (c.max(axis=1) - c.min(axis=1)).max(axis=1)
        passes = 0
    elif traced:  # interfaces or subregions kept through the repair
        points, tets, regions, delta, comp, carrier, passes = repaired_sweep(
            points, tets, prof_ids, field, threshold, regions, ie, max_elements=max_elements)
    else:
        points, tets, comp, delta, passes = repair(points, tets, field, threshold,
                                                   max_elements=max_elements)
        points, comp, _ = smooth(points, tets, field, threshold, comp=comp)
        delta = delta_vertices(comp, tets)
        regions = None
    tets = tets.astype(np.int32)
    faces, _ = boundary_faces(tets)
    markers = _classify(solid, points, faces, chord)
    inter, im = sweep_faces(prof, p2, t2, m2.facets, tets, prof_ids, tol, pchord, edges=ie,
                            markers=imark, n_faces=len(solid.face_names),
                            discontinuities=disc, traced=traced, carrier=carrier)
    if len(cuts):  # the jump half-planes, after the swept interfaces
        pf, pk = plane_faces(tets, on_half_planes(points, cuts, tol))
        inter, im = np.concatenate([inter, pf]), np.concatenate([im, nb + 1 + pk])
    if len(inter):
        faces = np.concatenate([faces, inter])
        markers = np.concatenate([markers, im])
    steps = counts.sum(axis=0)
    res = TetResult(points, tets, faces.astype(np.int32), markers.astype(np.int32),
                    tuple(solid.face_names) + disc + cut_face_names(disc, len(cuts)), delta,
                    float(threshold),
                    {"placement": "revolved" if axisym else "revolved+repair",
                     "angular_steps": (int(steps[~on_axis].min()), int(steps.max())),
                     "section_triangles": len(t2),
                     "repair_passes": passes})
    if len(cuts):
        res.info["jump_planes"] = tuple(float(c) for c in cuts)
    profile_area = area(np.column_stack([p2, np.zeros(n2)]), t2)
    if regions is not None:
        res.info["regions"] = regions.astype(np.int32)
    if not axisym and comp is not None:
        res.info["composition"] = comp
    curves = {}
    if traced:
        curves = {3 + i: [c] for i, c in enumerate(prof.curves) if c.kind == "interface"}
        for j, name in enumerate(disc):
            curves[len(solid.face_names) + 1 + j] = [
                c for c in r2.model.domain.curves if c.name == name]

    def problems(r, inter, im) -> list[str]:
        out = revolution_problems(r, solid, field if not axisym else None, chord,
                                  regions=r.info.get("regions") if traced else None)
        if traced:  # every tetrahedron in its subregion, the strips on their surfaces
            out += region_problems(field, r.points, r.tets, r.info.get("regions"))
            out += surface_problems(solid.to2d(r.points)[0], inter, im, curves, tol, chord,
                                    chord_all=True)
        if planes:  # the jump half-planes, whole and flat
            on = np.isin(im, list(planes))
            out += plane_problems(r.points, inter[on], im[on] - nb - 1, half_plane_distance,
                                  cuts, profile_area, tol)
        return out

    if check:
        probs = problems(res, inter, im)
        if probs:
            raise VerificationError(f"tetrahedral mesh verification failed: {probs[0]}")
    if not axisym and MMG_PASS and not thin:  # the end planes' vertices snapped back, the
        # rest required
        res = improve_result(res, field, threshold,
                             curved=set(range(3, len(res.face_names) + 1)) - set(planes),
                             interfaces=set(curves) | set(planes), hausd=chord,
                             snap=lambda p, f, m: _snap_ends(solid, p, f, m, planes),
                             classify=lambda p, f: _classify(solid, p, f, chord),
                             problems=problems, max_elements=max_elements)
    res.info["time_total"] = time.perf_counter() - t0
    return res


def angular_counts(solid: Revolution, p2: np.ndarray, t2: np.ndarray, chord: float,
                   on_axis: np.ndarray, max_size: float | None = None, *,
                   levels: np.ndarray | None = None) -> np.ndarray:
    """Angular steps of every profile vertex's column ``(N,)``: arcs of :data:`COLUMN_RATIO`
    x the mean edge at the vertex, at most :data:`MAX_STEP`, and within half the chord
    tolerance ``chord`` at the largest radius among the vertex and its neighbours (an edge
    between two columns spans at most the larger of their steps); 0 on the axis. With the
    angles ``levels (K + 1,)`` between layers: ``(K, N)``, the steps of every layer."""
    r = p2[:, 0]
    e = np.concatenate([t2[:, [0, 1]], t2[:, [1, 2]], t2[:, [2, 0]]])
    r_nb = r.copy()
    np.maximum.at(r_nb, e[:, 0], r[e[:, 1]])
    np.maximum.at(r_nb, e[:, 1], r[e[:, 0]])
    rs = np.maximum(r, 1e-300)
    step = np.minimum(COLUMN_RATIO * vertex_size(p2, t2) / rs, MAX_STEP)
    step = np.minimum(step, 2.0 * np.arccos(np.clip(1.0 - 0.5 * chord / np.maximum(r_nb, 1e-300),
                                                    -1.0, 1.0)))
    if max_size is not None:
        step = np.minimum(step, float(max_size) / rs)
    if levels is None or len(levels) <= 2:
        n = np.ceil(solid.sweep / step - 1e-9).astype(np.int64)
        n = np.maximum(n, 3 if solid.full else 1)
        n[on_axis] = 0
        return n if levels is None else n[None, :]
    width = np.diff(np.asarray(levels, dtype=float))[:, None]
    n = np.maximum(np.ceil(width / step[None, :] - 1e-9).astype(np.int64), 1)
    n[:, on_axis] = 0
    return n


def _snap_ends(solid: Revolution, points, faces, markers, planes=None) -> np.ndarray:
    """``points`` with the vertices of the triangles ``faces`` on the end planes (markers 1
    at angle 0, 2 at the sweep's end) and on the jump half-planes (``planes``: marker ->
    angle) turned back onto them exactly."""
    ends = [] if solid.full else [(1, 0.0), (2, solid.sweep)]
    ends += list((planes or {}).items())
    if not ends:
        return points
    out = np.array(points, dtype=np.float64)
    for m, ang in ends:
        ids = np.unique(faces[markers == m])
        q, _ = solid.to2d(out[ids])
        out[ids] = solid.to3d(q, np.full(len(ids), ang))
    return out


def on_half_planes(points: np.ndarray, angles, tol: float) -> np.ndarray:
    """``(P, K)``: whether every point is within ``tol`` of the half-plane through the z
    axis at each angle (a point on the axis is on them all)."""
    p = np.asarray(points, dtype=float)
    a = np.asarray(angles, dtype=float)
    across = np.abs(-p[:, [0]] * np.sin(a) + p[:, [1]] * np.cos(a))
    along = p[:, [0]] * np.cos(a) + p[:, [1]] * np.sin(a)
    return (across <= tol) & (along >= -tol)


def half_plane_distance(points: np.ndarray, angle: float) -> np.ndarray:
    """The distance of every point from the half-plane through the z axis at ``angle``."""
    p = np.asarray(points, dtype=float)
    c, s = math.cos(angle), math.sin(angle)
    across = np.abs(-p[:, 0] * s + p[:, 1] * c)
    along = p[:, 0] * c + p[:, 1] * s
    return np.where(along >= 0, across, np.hypot(across, along))


def _classify(solid: Revolution, points, faces, chord) -> np.ndarray:
    """Face marker (1 + index in ``face_names``) of boundary triangles; 0 for none: the end
    planes' to 1e-9 of the diameter, else the nearest curve's surface within ``chord`` (a
    repair's midpoints of angular chords lie inside the surface by up to their sagitta)."""
    q, th = solid.to2d(points)
    tol = 1e-9 * solid.diameter
    k = len(faces)
    out = np.zeros(k, dtype=np.int64)
    axis_pt = q[:, 0] <= tol
    if not solid.full:
        for m, ang in ((1, 0.0), (2, solid.sweep)):
            d = np.abs(np.angle(np.exp(1j * (th - ang))))
            on = (d * np.maximum(q[:, 0], 1.0) <= 1e-9 * solid.diameter) | axis_pt
            out[(out == 0) & on[faces].all(axis=1)] = m
    rest = np.flatnonzero(out == 0)
    if len(rest):
        best = np.full(len(rest), np.inf)
        arg = np.zeros(len(rest), dtype=np.int64)
        for i, c in enumerate(solid.profile.curves):
            if i in solid.axis_curves or c.kind == "interface":
                continue
            d = np.max([c.curve.distance(q[faces[rest, j]]) for j in range(3)], axis=0)
            better = d < best
            best[better], arg[better] = d[better], i
        ok = best <= max(tol, chord)
        out[rest[ok]] = 3 + arg[ok]
    return out


def revolution_problems(res, solid: Revolution, field, chord: float, *,
                        regions: np.ndarray | None = None) -> list[str]:
    """Broken claims of a swept mesh of revolution: positive volumes, conformity, every
    point used, boundary triangles on the solid's faces with every edge's midpoint within
    the chord tolerance of its face, interface triangles faces of two tetrahedra, each
    edge's midpoint within the chord tolerance of its curve's surface, the volume within
    the chord tolerance, delta (recomputed from ``field``, every tetrahedron's corners in its
    subregion with ``regions``). Markers past the solid's faces (discontinuities) are
    interfaces."""
    p, t = res.points, res.tets
    out = validity_problems(p, t)
    kinds = ["", ""] + [c.kind for c in solid.profile.curves]
    kinds = np.array(kinds + ["interface"] * (len(res.face_names) - len(kinds)))
    out += strip_problems(t, res.faces[kinds[res.face_markers.clip(1) - 1] == "interface"])
    v = simplex_measures(p, t)
    if (res.face_markers <= 0).any():
        out.append(f"{int((res.face_markers <= 0).sum())} boundary triangles on no face")
    curved = res.face_markers > 2
    if curved.any():
        f = res.faces[curved]
        mids = 0.5 * (p[f] + p[f[:, [1, 2, 0]]])
        q, _ = solid.to2d(mids.reshape(-1, 3))
        cid = np.repeat(res.face_markers[curved] - 3, 3)
        dev = np.zeros(len(q))
        for i, c in enumerate(solid.profile.curves):
            sel = cid == i
            if sel.any():
                dev[sel] = c.curve.distance(q[sel])
        if dev.max() > chord * (1 + 1e-6):
            out.append(f"chord deviation {dev.max():.3g} over the tolerance {chord:.3g}")
    perim = sum(c.curve.length for c in solid.profile.curves)
    slack = chord * perim * solid.sweep * max(float(np.abs(p[:, :2]).max()), 1.0) + \
        1e-9 * solid.volume
    if abs(float(v.sum()) - solid.volume) > slack:
        out.append(f"volume {float(v.sum()):.9g} differs from the solid's "
                   f"{solid.volume:.9g} by more than the chord tolerance allows")
    if field is None:
        delta = res.delta
    elif regions is not None:
        cc = corner_compositions(field, p, t, regions)
        delta = (cc.max(axis=1) - cc.min(axis=1)).max(axis=1)
    else:
        delta = delta_vertices(field.composition(p), t)
    if not float(delta.max()) < res.threshold:
        out.append(f"delta_max = {float(delta.max()):.6g} is not below {res.threshold:g}")
    return out
