"""Extrusions of 2D models: the section meshed by the 2D mesher, swept along the axis.

For a prism whose composition does not depend on the axis coordinate (the extrusion of a 2D
model: a plate, a blade with its cooling holes, a feature-tree field), the verified 2D mesh
of the section (delta < delta_0 over every triangle, subregions kept, curved boundaries
within the chord tolerance) is swept along the axis through columns of points, one per
section vertex, spaced :data:`COLUMN_RATIO` x the mean edge length at the vertex
(:func:`hetmesh.tet.columns.column_tets`: the cells stay about as tall as wide whatever the
section's range of sizes). Each tetrahedron's vertices are copies of vertices of one
triangle (at several heights, the same compositions), so its delta is at most its
triangle's: the 2D guarantee carries over exactly; its subregion is its triangle's, so no
tetrahedron straddles a material discontinuity (the discontinuity curves become embedded
surfaces). The section's interface curves (``[domain] interfaces``), embedded in the 2D mesh,
sweep into interface surfaces of tetrahedron faces (:func:`hetmesh.tet.columns.swept_interfaces`),
recorded with the boundary faces under their curves' names (markers ``3 +`` the curve's
index in ``section.curves``, as the side faces), so every format writes them and the
verification checks their areas; the discontinuity curves the 2D mesher embedded follow as
faces ``discontinuity[k]`` (markers after the solid's faces). With a composition that also
varies along the axis, :mod:`hetmesh.tet.sweep_regions` keeps interfaces and subregions
through the repair.

:func:`prism_tets` is the sweep through common layers (every triangular prism cut in three
tetrahedra: on each side quadrilateral the diagonal from the lower-numbered bottom vertex to
the higher-numbered top vertex, which the prism on the other side chooses too).

When the composition also varies along the axis, the columns' spacing is at most
:data:`BETA` delta_0 / max |df/ds| and the tetrahedra still over delta_0 are repaired by edge
bisection; if the repaired mesh misses a quality target, MMG remeshes it
(:func:`hetmesh.tet.sweep_mmg.improve_result`, kept only if verified and better).

>>> import numpy as np
>>> p2 = np.array([[0, 0], [1, 0], [0, 1.0]]); t2 = np.array([[0, 1, 2]])
>>> p3, t3, layer = prism_tets(p2, t2, np.array([0.0, 1.0]))
>>> len(p3), len(t3)
(6, 3)
"""

from __future__ import annotations

import logging
import time
from dataclasses import replace

import numpy as np

from ..errors import BudgetError
from ..material import has_subregions
from ..mesh import simplex_measures
from ..metrics import delta_vertices
from ..tri.discontinuity import DISCONTINUITY
from .columns import (
    column_counts,
    layered_column_tets,
    strip_problems,
    vertex_size,
)
from .faces import boundary_faces
from .mesher import BETA, TetResult
from .refine import repair
from .smooth import smooth
from .sweep_mmg import improve_result
from .sweep_regions import (
    PlaneField,
    area,
    axial_cuts,
    interface_edges,
    on_axial_planes,
    plane_faces,
    plane_problems,
    region_problems,
    repaired_sweep,
    surface_problems,
    sweep_faces,
    warn_thin_layers,
)
from .verify import tet_problems

__all__ = ["prism_tets", "generate_extruded", "SectionField", "mid_section_field", "prism_cuts",
           "cut_face_names"]

log = logging.getLogger(__name__)

#: column spacing / mean edge length at the vertex: 1.25 gives the swept examples fewer
#: tetrahedra than common layers at the median edge, and a better shape (1.0: more
#: tetrahedra, about the same shape; 1.5: mean radius ratio under 0.8)
COLUMN_RATIO = 1.25
#: whether the swept + repaired meshes (compositions varying along the axis) get the MMG
#: pass (:mod:`hetmesh.tet.sweep_mmg`), kept where it verifies and is better
MMG_PASS = True


class SectionField:
    """A 2D material field seen in 3D: the composition of ``field2d`` at the section
    coordinates of the point (constant along the prism's axis)."""

    dim = 3

    def __init__(self, field2d, solid):
        self.field2d = field2d
        self.solid = solid
        self.constituents = tuple(field2d.constituents)

    def composition(self, points, region=None) -> np.ndarray:
        q, _ = self.solid.to2d(points)
        if region is None:
            return self.field2d.composition(q)
        return self.field2d.composition(q, region=region)

    def region(self, points) -> np.ndarray:
        """The subregion of every point (a piecewise 2D field's, at its section point)."""
        q, _ = self.solid.to2d(points)
        return self.field2d.region(q)

    def gradient(self, points) -> np.ndarray:
        q, _ = self.solid.to2d(points)
        g2 = self.field2d.gradient(q)
        out = np.zeros(g2.shape[:2] + (3,))
        u, v = self.solid.uv
        out[..., u], out[..., v] = g2[..., 0], g2[..., 1]
        return out


def prism_tets(points2: np.ndarray, tris2: np.ndarray, levels: np.ndarray
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Sweep a triangulation through ``levels (L,)``: ``(points (N L, 3) with the level as
    third coordinate, tets (3 T (L - 1), 4) positively oriented, layer (3 T (L - 1),))``.

    Point ``i`` of level ``j`` has id ``j N + i``; the tetrahedra of the prism over triangle
    ``(a, b, c)`` (sorted: ``a < b < c``) between levels ``j`` and ``j + 1`` are
    ``(a, b, c, c')``, ``(a, b, b', c')``, ``(a, a', b', c')`` (primes: level ``j + 1``).
    """
    n = len(points2)
    nl = len(levels)
    pts = np.empty((n * nl, 3))
    pts[:, :2] = np.tile(points2, (nl, 1))
    pts[:, 2] = np.repeat(levels, n)
    s = np.sort(tris2.astype(np.int64), axis=1)
    a, b, c = s[:, 0], s[:, 1], s[:, 2]
    base = np.stack([np.stack([a, b, c, c + n], 1), np.stack([a, b, b + n, c + n], 1),
                     np.stack([a, a + n, b + n, c + n], 1)], axis=1).reshape(-1, 4)
    off = (np.arange(nl - 1, dtype=np.int64) * n)[:, None, None]
    tets = (base[None] + off).reshape(-1, 4)
    layer = np.repeat(np.arange(nl - 1), len(base))
    return pts, tets, layer


def _orient(points, tets):
    v = simplex_measures(points, tets)
    neg = v < 0
    t = tets.copy()
    t[neg, 2], t[neg, 3] = tets[neg, 3], tets[neg, 2]
    return t


def _axial_gradient(field3d, solid, n: int = 24) -> float:
    p = solid.sample(n)
    g = field3d.gradient(p)[:, :, solid.axis]
    return float(np.abs(g).max()) if g.size else 0.0


def mid_section_field(solid, field3d):
    """The composition on the prism's middle section as a 2D field (section coordinates):
    what the section is meshed with when the composition also varies along the axis. A
    piecewise field's keeps its subregions (:class:`~hetmesh.tet.sweep_regions.PlaneField`),
    so that the 2D mesher embeds its jumps."""
    from ..material import CallableField

    s_mid = 0.5 * (solid.s0 + solid.s1)
    if has_subregions(field3d):
        levels = np.concatenate([[solid.s0], prism_cuts(solid, field3d), [solid.s1]])
        k = int(np.argmax(np.diff(levels)))  # the thickest layer's middle, off any cut
        if len(levels) > 2:
            s_mid = 0.5 * (levels[k] + levels[k + 1])
        return PlaneField(field3d, lambda q: solid.to3d(q, np.full(len(q), s_mid)), solid.uv)

    def f2(x, y):
        q = np.column_stack([np.ravel(x), np.ravel(y)])
        return field3d.composition(solid.to3d(q, np.full(len(q), s_mid)))
    return CallableField(f2, field3d.constituents)


def prism_cuts(solid, field3d) -> np.ndarray:
    """The axis values of the planes across a prism on which its piecewise composition's
    jumps lie (:func:`~hetmesh.tet.sweep_regions.axial_cuts`; :class:`MaterialError` if
    its jumps are neither those nor swept section curves)."""
    return axial_cuts(field3d, solid.section, solid.to3d, solid.s0, solid.s1, "z")


def generate_extruded(solid, field3d, threshold: float, section_model, *, swept: bool,
                      seed: int = 0, chord_tol: float | None = None,
                      max_elements: int | None = None, min_angle: float = 30.0,
                      max_size: float | None = None, check: bool = True) -> TetResult:
    """Tetrahedralise a prism by sweeping the 2D mesh of its section.

    Parameters
    ----------
    solid : Prism
    field3d : material field on ``(N, 3)`` points
    threshold : float
        delta_0.
    section_model : 2D model (``hetmesh.io.model.Model``)
        The section (``solid.section``) and the 2D field to mesh it with: the swept field
        when ``swept``, else e.g. :func:`mid_section_field`.
    swept : bool
        Whether ``field3d`` is the section's field, the same along the axis (then the 2D
        guarantee carries over exactly); otherwise thin layers and edge-bisection repair.
    chord_tol : float, optional
        Absolute chord tolerance of curved faces (default: the 2D mesher's).
    max_size : float, optional
        Longest edge of the section's mesh and widest column spacing: fewer sizes in the
        section, more tetrahedra.
    """
    from ..options import DEFAULT_CHORD_TOL as CHORD_TOL
    from ..tri.pipeline import SWEEP_STARTS, generate

    t0 = time.perf_counter()
    sec = solid.section
    cuts = np.zeros(0)
    if not swept and has_subregions(field3d):  # its jumps embedded in the section's mesh
        cuts = prism_cuts(solid, field3d)  # and on planes across the axis
        if len(cuts) or not has_subregions(section_model.material):
            section_model = replace(section_model,
                                    material=mid_section_field(solid, field3d))
    field2d = section_model.material
    kw = {}
    if chord_tol is not None:
        kw["chord_tol"] = min(max(chord_tol / sec.diameter, 1e-7), 0.05)
    if max_size is not None:
        kw["max_size"] = float(max_size)
    r2 = generate(section_model, threshold, seed=seed, min_angle=min_angle,
                  starts=SWEEP_STARTS, **kw)
    m2 = r2.mesh
    p2, t2 = m2.points, m2.triangles.astype(np.int64)
    size = vertex_size(p2, t2)
    cap = None if max_size is None else float(max_size)
    gs = 0.0 if swept else _axial_gradient(field3d, solid)
    if gs > 0:
        cap = min(cap if cap is not None else np.inf, BETA * threshold / gs)
    levels = np.concatenate([[solid.s0], cuts, [solid.s1]])  # the layers between cuts
    # a thin layer's flat tetrahedra stay flat through MMG, which keeps the jump planes
    # (a 3 x 2 x 2 box with a coating 0.01 thick at 0.3: its pass took 4 s, not kept)
    thin = bool(len(cuts)) and warn_thin_layers(np.diff(levels), float(np.median(size)),
                                                levels, "z", log)
    counts = np.stack([column_counts(float(b - a), size, ratio=COLUMN_RATIO, cap=cap)
                       for a, b in zip(levels[:-1], levels[1:])])
    ntet = int(counts[:, t2].sum())
    if max_elements is not None and ntet > max_elements:
        raise BudgetError(f"about {ntet} tetrahedra are needed for delta_0 = {threshold} "
                          f"({len(t2)} triangles in the section, {int(counts.min())} to "
                          f"{int(counts.max())} layers) but the budget is {max_elements}")
    # col: the section vertex of every point
    pl, tets, tri_of, col = layered_column_tets(p2, t2, counts, levels)
    points = solid.to3d(pl[:, :2], pl[:, 2])
    tets = _orient(points, tets)
    ntri = len(t2)
    sub2 = m2.cell_data.get("subregion") if m2.cell_data else None
    regions = None if sub2 is None else np.asarray(sub2)[tri_of]
    if len(cuts):  # every layer's own subregions (no tetrahedron crosses a cut)
        regions = np.asarray(field3d.region(points[tets].mean(axis=1)), dtype=np.int64)
    comp = None
    chord_abs = _chord_abs(kw.get("chord_tol", CHORD_TOL), sec)
    tol = 1e-9 * solid.diameter
    ie, imark, disc = interface_edges(sec, r2.model.domain, p2, t2, m2.facets, tol, chord_abs,
                                      len(solid.face_names))
    traced = not swept and len(ie) + (regions is not None) > 0
    nb = len(solid.face_names) + len(disc)
    cut_names = cut_face_names(disc, len(cuts))
    planes = {nb + 1 + k: float(c) for k, c in enumerate(cuts)}  # marker -> axis value
    carrier = None
    if swept:
        delta = _swept_delta(field2d, p2, col[tets], regions)
    elif traced:  # interfaces or subregions kept through the repair
        points, tets, regions, delta, comp, carrier, _ = repaired_sweep(
            points, tets, col, field3d, threshold, regions, ie, max_elements=max_elements)
    else:
        points, tets, comp, delta, _ = repair(points, tets, field3d, threshold,
                                              max_elements=max_elements)
        points, comp, _ = smooth(points, tets, field3d, threshold, comp=comp)
        delta = delta_vertices(comp, tets)
    tets = tets.astype(np.int32)
    faces, _ = boundary_faces(tets)
    markers = solid.classify_faces(points[faces]) + 1
    inter, im = sweep_faces(sec, p2, t2, m2.facets, tets, col, tol, chord_abs, edges=ie,
                            markers=imark, n_faces=len(solid.face_names),
                            discontinuities=disc, traced=traced, carrier=carrier)
    if len(cuts):  # the jump planes across the axis, after the swept interfaces
        pf, pk = plane_faces(tets, on_axial_planes(points, solid.axis, cuts))
        inter, im = np.concatenate([inter, pf]), np.concatenate([im, nb + 1 + pk])
    if len(inter):
        faces = np.concatenate([faces, inter])
        markers = np.concatenate([markers, im])
    res = TetResult(points, tets, faces.astype(np.int32), markers.astype(np.int32),
                    tuple(solid.face_names) + disc + cut_names, delta, float(threshold),
                    {"placement": "swept" if swept else "swept+repair",
                     "layers": (int(counts.sum(axis=0).min()), int(counts.sum(axis=0).max())),
                     "section_triangles": ntri, "time_total": 0.0})
    if len(cuts):
        res.info["jump_planes"] = tuple(float(c) for c in cuts)
    if regions is not None:
        res.info["regions"] = regions.astype(np.int32)
    if comp is not None:
        res.info["composition"] = comp
    curves = _surface_curves(sec, r2.model.domain, solid.face_names, disc) if traced else {}

    def problems(r: TetResult, inter, im) -> list[str]:
        out = tet_problems(r.points, r.tets, r.faces, r.face_markers, solid, r.delta,
                           threshold, chord_abs) + strip_problems(r.tets, inter)
        if traced:  # every tetrahedron in its subregion, the strips on their surfaces
            out += region_problems(field3d, r.points, r.tets, r.info.get("regions"))
            out += surface_problems(solid.to2d(r.points)[0], inter, im, curves, tol, chord_abs)
        if planes:  # the jump planes, whole and flat (an end face is the same polygon)
            on = np.isin(im, list(planes))
            out += plane_problems(r.points, inter[on], im[on] - nb - 1,
                                  lambda p, c: np.abs(p[:, solid.axis] - c), cuts,
                                  area(r.points, r.faces[r.face_markers == 1]), tol)
        return out

    if check:
        probs = problems(res, inter, im)
        if probs:
            from ..errors import VerificationError
            raise VerificationError(f"tetrahedral mesh verification failed: {probs[0]}")
    if not swept and MMG_PASS and not thin:
        res = _mmg_pass(res, solid, sec, field3d, threshold, curves, planes, chord_abs,
                        problems, max_elements)
    res.info["time_total"] = time.perf_counter() - t0
    log.info("swept tet mesh: %d triangles, %d to %d layers -> %d tetrahedra, %.2f s", ntri,
             int(counts.min()), int(counts.max()),
             len(res.tets), res.info["time_total"])
    return res


def _mmg_pass(res: TetResult, solid, sec, field3d, threshold: float, curves: dict,
              planes: dict, chord_abs: float, problems, max_elements) -> TetResult:
    """:func:`hetmesh.tet.sweep_mmg.improve_result` of a verified swept + repaired prism
    mesh: the triangles of arcs' sweeps required, the others' vertices snapped back
    (:func:`_snap`). ``curves``: the section curves of every interface marker; ``planes``:
    the axis value of every jump plane's marker."""
    nb = len(solid.face_names)
    curved = {m for m in range(3, nb + 1)
              if hasattr(sec.curves[m - 3].curve, "radius")}
    curved |= {m for m, cs in curves.items() if any(hasattr(c.curve, "radius") for c in cs)}
    return improve_result(res, field3d, threshold, curved=curved,
                          interfaces=set(curves) | set(planes), hausd=chord_abs,
                          snap=lambda p, f, m: _snap(solid, curves, planes, p, f, m),
                          classify=lambda p, f: solid.classify_faces(p[f]) + 1,
                          problems=problems, max_elements=max_elements)


def _snap(solid, curves: dict, planes: dict, points, faces, markers) -> np.ndarray:
    """``points`` with the vertices of the triangles ``faces`` on the caps (markers 1, 2)
    and on the jump planes (``planes``: marker -> axis value) at their axis value and
    those on straight side faces or interfaces (``curves``: the section curves of every
    interface marker) projected onto their segment, in section coordinates (exact for the
    axis-aligned planes)."""
    q, s = solid.to2d(points)
    q, s = q.copy(), s.copy()
    s[np.unique(faces[markers == 1])] = solid.s0
    s[np.unique(faces[markers == 2])] = solid.s1
    for m, c in planes.items():
        s[np.unique(faces[markers == m])] = c
    sec = solid.section
    on = {m: [sec.curves[m - 3]] for m in range(3, len(solid.face_names) + 1)}
    on.update(curves)
    for m, cs in on.items():
        lines = [c.curve for c in cs if not hasattr(c.curve, "radius")]
        ids = np.unique(faces[markers == m])
        if not lines or not len(ids):
            continue
        d = np.array([c.distance(q[ids]) for c in lines])
        near = np.argmin(d, axis=0)
        for k, c in enumerate(lines):
            sel = ids[near == k]
            q[sel] = c.point(c.project(q[sel]))
    return solid.to3d(q, s)


def _surface_curves(sec, domain2, names, disc) -> dict:
    """The section curves of every interface face marker: a section interface's own curve,
    a discontinuity's curves in the 2D mesher's domain."""
    out = {3 + i: [c] for i, c in enumerate(sec.curves) if c.kind == "interface"}
    for j, name in enumerate(disc):
        out[len(names) + 1 + j] = [c for c in domain2.curves if c.name == name]
    return out


def cut_face_names(disc: tuple, n: int) -> tuple[str, ...]:
    """Names of ``n`` jump planes: the discontinuity faces' after the section's ``disc``."""
    used = [int(d[len(DISCONTINUITY) + 1:-1]) for d in disc
            if d.startswith(DISCONTINUITY + "[") and d[len(DISCONTINUITY) + 1:-1].isdigit()]
    first = max(used, default=-1) + 1
    return tuple(f"{DISCONTINUITY}[{first + k}]" for k in range(n))


def _chord_abs(rel, sec) -> float:
    return float(rel) * float(sec.diameter) * (1 + 1e-6)


def _swept_delta(field2d, p2, ids, regions) -> np.ndarray:
    """delta of swept tetrahedra (``ids (M, 4)``: their vertices' section vertices) from the
    section field, each vertex evaluated in its tetrahedron's subregion (a vertex on a
    discontinuity takes its element's side)."""
    if regions is None:
        comp = field2d.composition(p2)
        return delta_vertices(comp, ids)
    c = field2d.composition(p2[ids.ravel()], region=np.repeat(regions, 4))
    c = c.reshape(len(ids), 4, -1)
    return (c.max(axis=1) - c.min(axis=1)).max(axis=1)
