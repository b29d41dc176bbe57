"""Sweeps whose composition varies along the sweep, with their interfaces and subregions kept.

An extrusion (or revolution) whose composition depends on the axial coordinate (the angle)
is swept through columns and repaired by edge bisection (:mod:`hetmesh.tet.extrude`,
:mod:`hetmesh.tet.revolve`). Its section may hold interface curves (``[domain]
interfaces``) and, for a piecewise formula field (``where``, ``sign``), material
discontinuities: curves where the subregion changes. Both are kept through the repair:

* the section is meshed with the composition on one plane as a 2D field that keeps the 3D
  field's subregions (:class:`PlaneField`), so the 2D mesher embeds the discontinuity curves
  (as ``discontinuity[k]``) and gives every triangle its subregion; the subregions must not
  change along the sweep (:func:`check_swept_regions`), so every discontinuity is the sweep
  of a curve;
* every tetrahedron keeps its triangle's subregion, and the repair carries it to the
  children (:func:`hetmesh.tet.refine.repair` with ``regions``: a child lies in its parent)
  and evaluates every tetrahedron's corners in its subregion;
* the interface and discontinuity surfaces are found again after the repair from where
  every point lies (:func:`hetmesh.tet.columns.carriers`), and the quality pass moves no
  point on them and runs in each subregion on its own (a vertex it moves has all its
  tetrahedra in one subregion).

>>> import numpy as np
>>> from hetmesh.material import AnalyticField
>>> f3 = AnalyticField({"metal": "where(x < 1, 0.1 + z/10, 0.6 - z/10)"},
...                    ["ceramic", "metal"], dim=3)
>>> f2 = PlaneField(f3, lambda q: np.column_stack([q, np.full(len(q), 2.0)]), (0, 1))
>>> f2.region(np.array([[0.5, 0.0], [1.5, 0.0]])).tolist()
[1, 0]
>>> f2.composition(np.array([[1.5, 0.0]]), region=1)[:, 1].round(12).tolist()
[0.3]
"""

from __future__ import annotations

import numpy as np

from ..errors import MaterialError
from ..material import has_subregions
from ..material.analytic import Shiftable
from ..material.field import thread_safe
from ..metrics import delta_vertices
from ..tri.discontinuity import DISCONTINUITY
from .columns import (
    carried_strip_faces,
    carriers,
    section_interfaces,
    strip_faces,
    swept_interfaces,
)
from .refine import corner_compositions, repair
from .smooth import smooth

__all__ = ["PlaneField", "check_swept_regions", "interface_edges", "repaired_sweep",
           "sweep_faces",
           "interface_faces", "surface_problems", "region_problems"]


class PlaneField(Shiftable):
    """A 3D material field on one plane of a sweep, as a 2D field of the section's
    coordinates that keeps the 3D field's subregions (``region``, ``n_regions``,
    ``composition(q, region=r)``): what the 2D mesher embeds the discontinuities of.

    ``to3d(q (N, 2)) -> (N, 3)`` places section points on the plane; ``axes`` are the two
    components of the 3D gradient along the section's coordinates there."""

    dim = 2

    def __init__(self, field3d, to3d, axes: tuple[int, int]):
        self.field3d = field3d
        self._to3d = to3d
        self.axes = (int(axes[0]), int(axes[1]))
        self.constituents = tuple(field3d.constituents)
        self.thread_safe = thread_safe(field3d)
        self._offset_xy = np.zeros(2)

    @property
    def n_regions(self) -> int:
        return int(getattr(self.field3d, "n_regions", 1))

    @property
    def region_names(self):
        return self.field3d.region_names

    def describe_jump(self, ra: int, rb: int) -> str:
        return self.field3d.describe_jump(ra, rb)

    def _p3(self, points) -> np.ndarray:
        return self._to3d(self._global(points))

    def region(self, points) -> np.ndarray:
        return np.asarray(self.field3d.region(self._p3(points)), dtype=np.int64)

    def composition(self, points, region=None) -> np.ndarray:
        p = self._p3(points)
        if region is None:
            return self.field3d.composition(p)
        return self.field3d.composition(p, region=region)

    def gradient(self, points, region=None) -> np.ndarray:
        p = self._p3(points)
        g = self.field3d.gradient(p) if region is None else \
            self.field3d.gradient(p, region=region)
        return np.ascontiguousarray(g[..., list(self.axes)])


def check_swept_regions(field3d, section, place, params: np.ndarray, what: str) -> None:
    """:class:`MaterialError` if the subregions of a piecewise ``field3d`` change along the
    sweep: at a grid of 48 x 48 points of ``section`` (those inside), placed at every sweep
    parameter of ``params`` by ``place(q (N, 2), s (N,)) -> (N, 3)``; ``what`` names the
    sweep coordinate in the message ("z", "the angle")."""
    if not has_subregions(field3d):
        return
    x0, y0, x1, y1 = section.bounds
    gx, gy = np.meshgrid(np.linspace(x0, x1, 48), np.linspace(y0, y1, 48), indexing="ij")
    q = np.column_stack([gx.ravel(), gy.ravel()])
    q = q[section.contains(q)]
    if not len(q):
        return
    ref = np.asarray(field3d.region(place(q, np.full(len(q), params[0]))))
    for s in params[1:]:
        p = place(q, np.full(len(q), s))
        r = np.asarray(field3d.region(p))
        bad = np.flatnonzero(r != ref)
        if len(bad):
            i = int(bad[0])
            x, y, z = p[i]
            describe = getattr(field3d, "describe_jump", None)
            head = describe(int(ref[i]), int(r[i])) if callable(describe) else \
                "material.composition"
            raise MaterialError(f"{head}: the "
                                f"subregion changes with {what} near ({x:.6g}, {y:.6g}, "
                                f"{z:.6g}); in a sweep the jumps must not depend on {what} "
                                f"(they are embedded as swept section curves)")


def interface_edges(section, domain2, points2: np.ndarray, tris2: np.ndarray,
                    facets: np.ndarray, tol: float, chord: float, n_faces: int
                    ) -> tuple[np.ndarray, np.ndarray, tuple[str, ...]]:
    """The section mesh's edges on interface curves and the face marker of each: ``3 +``
    the curve's index in ``section.curves`` for the section's own interfaces, then the
    discontinuity curves the 2D mesher embedded (curves of ``domain2``, its domain, named
    ``discontinuity[k]``), marker ``n_faces + 1 + j`` for the ``j``-th distinct name.
    ``(edges (E, 2), markers (E,), names of the discontinuity faces)``."""
    e1, c1 = section_interfaces(section, points2, tris2, facets, tol, chord)
    m1 = 3 + c1
    disc = [i for i, c in enumerate(domain2.curves)
            if c.kind == "interface" and c.name.startswith(DISCONTINUITY + "[")]
    if not disc:
        return e1, m1, ()
    e2, c2 = section_interfaces(domain2, points2, tris2, facets, tol, chord, only=set(disc))
    names = tuple(dict.fromkeys(domain2.curves[i].name for i in disc))
    m2 = np.array([n_faces + 1 + names.index(domain2.curves[int(i)].name) for i in c2],
                  dtype=np.int64)
    if len(e1) and len(e2):  # an edge on the section's own interface stays there
        n = int(max(e1.max(), e2.max())) + 1
        new = ~np.isin(e2[:, 0] * n + e2[:, 1], e1[:, 0] * n + e1[:, 1])
        e2, m2 = e2[new], m2[new]
    return np.concatenate([e1, e2]), np.concatenate([m1, m2]), names


def repaired_sweep(points, tets, column, field3d, threshold: float, regions, edges,
                   *, max_elements: int | None = None):
    """Repair a swept mesh (``column (N,)``: the section vertex of every point) by edge
    bisection and smooth it, its interface strips (``edges (E, 2)``) and the subregions
    ``regions (M,)`` (or None) kept: ``(points, tets, regions, delta, comp, carrier,
    passes)``, ``comp`` the vertex compositions (None with subregions: a vertex on a
    discontinuity has two), ``carrier`` as :func:`~hetmesh.tet.columns.carriers`."""
    points, tets, comp, delta, passes, tr = repair(points, tets, field3d, threshold,
                                                   max_elements=max_elements,
                                                   regions=regions, trace=True)
    e = np.sort(np.asarray(edges, dtype=np.int64).reshape(-1, 2), axis=1)
    carrier = carriers(column, tr.ends, e)
    on_iface = np.zeros(int(np.max(column, initial=0)) + 1, dtype=bool)
    on_iface[e.ravel()] = True
    c0 = carrier[:, 0]
    fixed = (c0 >= 0) & ((c0 != carrier[:, 1]) | on_iface[np.maximum(c0, 0)])
    if regions is None:
        points, comp, _ = smooth(points, tets, field3d, threshold, comp=comp, fixed=fixed)
        delta = delta_vertices(comp, tets)
        return points, tets, None, delta, comp, carrier, passes
    regions = np.asarray(regions)[tr.parent]
    for r in np.unique(regions):  # each subregion on its own: its border stays
        sub = tets[regions == r]
        points, _, _ = smooth(points, sub, _InRegion(field3d, int(r)), threshold, fixed=fixed)
    cc = corner_compositions(field3d, points, tets, regions)
    delta = (cc.max(axis=1) - cc.min(axis=1)).max(axis=1)
    return points, tets, regions, delta, None, carrier, passes


class _InRegion:
    """``field`` evaluated in one subregion everywhere (the quality pass's field)."""

    def __init__(self, field, region: int):
        self.field, self.r = field, region
        self.constituents = field.constituents

    def composition(self, points):
        return self.field.composition(points, region=self.r)


def interface_faces(tets, carrier, edges, markers) -> tuple[np.ndarray, np.ndarray]:
    """The faces of a repaired sweep on its interface strips and their markers."""
    f, k = carried_strip_faces(tets, carrier, edges)
    return f, np.asarray(markers, dtype=np.int64)[k]


def surface_problems(q2: np.ndarray, faces: np.ndarray, markers: np.ndarray, curves,
                     tol: float, chord: float, *, chord_all: bool = False) -> list[str]:
    """One line if an interface triangle leaves its surface: ``q2 (N, 2)`` the points in
    section coordinates, ``curves`` a mapping of marker to the section curves of its surface;
    every corner and edge midpoint within ``tol`` of one of them (segments of an
    extrusion), or ``chord + tol`` (arcs; every curve with ``chord_all``: a revolution's
    angular chords)."""
    out = []
    f = np.asarray(faces, dtype=np.int64)
    for m, cs in curves.items():
        sel = f[markers == m]
        if not len(sel):
            continue
        q = q2[sel]
        pts = np.concatenate([q.reshape(-1, 2), (0.5 * (q + q[:, [1, 2, 0]])).reshape(-1, 2)])
        d = np.min([c.curve.distance(pts) for c in cs], axis=0)
        arcs = chord_all or any(hasattr(c.curve, "radius") for c in cs)
        lim = tol + (chord if arcs else 0.0)
        if d.max() > lim:
            i = int(np.argmax(d))
            out.append(f"{int((d > lim).sum())} points of interface triangles (marker {m}) "
                       f"are {d.max():.3g} from their surface (at most {lim:.3g}; e.g. at "
                       f"section point ({pts[i, 0]:.6g}, {pts[i, 1]:.6g}))")
    return out


def region_problems(field3d, points, tets, regions) -> list[str]:
    """One line if a tetrahedron's centroid is not in the subregion it is labelled with (it
    straddles a discontinuity), else nothing."""
    if regions is None:
        return []
    c = np.asarray(points)[np.asarray(tets, dtype=np.int64)].mean(axis=1)
    bad = np.flatnonzero(np.asarray(field3d.region(c)) != np.asarray(regions))
    if not len(bad):
        return []
    i = int(bad[0])
    return [f"{len(bad)} tetrahedra straddle a discontinuity (e.g. tetrahedron {i}, "
            f"labelled {int(regions[i])}, centroid in {int(field3d.region(c[[i]])[0])})"]


def sweep_faces(section, points2, tris2, facets, tets, column, tol: float, chord: float, *,
                edges, markers, n_faces: int, discontinuities: tuple, traced: bool,
                carrier=None) -> tuple[np.ndarray, np.ndarray]:
    """The inner faces of a swept mesh, recorded after its boundary: with ``traced`` the
    interface strips found again after the repair (:func:`interface_faces`, ``carrier``);
    otherwise the sweeps of the section's interface curves, then those of the embedded
    discontinuities (``edges``, ``markers`` of :func:`interface_edges`, whose markers above
    ``n_faces`` are the discontinuities'). ``(faces (F, 3), markers (F,))``."""
    if traced:
        return interface_faces(tets, carrier, edges, markers)
    if not (section.interfaces or discontinuities):
        return np.zeros((0, 3), np.int64), np.zeros(0, np.int64)
    inter, im = swept_interfaces(section, points2, tris2, facets, tets, column, tol, chord)
    if discontinuities:
        d = markers > n_faces
        f2, k2 = strip_faces(tets, column, edges[d])
        inter, im = np.concatenate([inter, f2]), np.concatenate([im, markers[d][k2]])
    return inter, im
