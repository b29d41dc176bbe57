"""Sweeps whose composition varies along the sweep, with their interfaces and subregions kept.

An extrusion (or revolution) whose composition depends on the axial coordinate (the angle)
is swept through columns and repaired by edge bisection (:mod:`hetmesh.tet.extrude`,
:mod:`hetmesh.tet.revolve`). Its section may hold interface curves (``[domain]
interfaces``) and, for a piecewise formula field (``where``, ``sign``), material
discontinuities: curves where the subregion changes. Both are kept through the repair:

* the section is meshed with the composition on one plane as a 2D field that keeps the 3D
  field's subregions (:class:`PlaneField`), so the 2D mesher embeds the discontinuity curves
  (as ``discontinuity[k]``) and gives every triangle its subregion; the subregions must not
  change along the sweep (:func:`check_swept_regions`) except on planes across it (half-planes
  through a revolution's axis), found by :func:`axial_cuts`, which become levels of the
  sweep; so every discontinuity is the sweep of a curve or one of those planes
  (:func:`plane_faces`);
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
from ..topology import unique
from ..tri.discontinuity import DISCONTINUITY
from .columns import (
    carried_strip_faces,
    carriers,
    section_interfaces,
    strip_faces,
    swept_interfaces,
)
from .quality import TET_FACES
from .refine import corner_compositions, repair
from .smooth import smooth

__all__ = ["PlaneField", "check_swept_regions", "axial_cuts", "plane_faces", "plane_problems",
           "on_axial_planes", "area", "section_grid", "warn_thin_layers", "THIN_LAYER",
           "interface_edges", "repaired_sweep", "sweep_faces", "MAX_CUTS",
           "interface_faces", "surface_problems", "region_problems"]


#: planes across a sweep's axis its jumps may lie on, at most (more: an inclined surface)
MAX_CUTS = 64
#: the grid over the section along whose lines the jump planes are found
CUT_GRID = 24
#: samples of the subregion along each line (the thinnest layer found: length / 512)
CUT_SAMPLES = 513
#: bisection steps of every change (from length / 512: down to the rounding error)
BISECT_STEPS = 48


class PlaneField(Shiftable):
    """A 3D material field on one plane of a sweep, as a 2D field of the section's
    coordinates that keeps the 3D field's subregions (``region``, ``n_regions``,
    ``composition(q, region=r)``): what the 2D mesher embeds the discontinuities of.

    ``to3d(q (N, 2)) -> (N, 3)`` places section points on the plane; ``axes`` are the
    directions of the section's coordinates there: two coordinate axes (``(0, 1)``), or
    two unit vectors ``(2, 3)`` (a revolution's profile at an angle: the radial direction
    and z)."""

    dim = 2

    def __init__(self, field3d, to3d, axes):
        self.field3d = field3d
        self._to3d = to3d
        a = np.asarray(axes)
        self.dirs = np.eye(3)[a.astype(np.int64)] if a.ndim == 1 else a.astype(float)
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
        return np.ascontiguousarray(g @ self.dirs.T)


def section_grid(section, n: int) -> np.ndarray:
    """The points of an ``n`` x ``n`` grid over ``section``'s bounding box inside it."""
    x0, y0, x1, y1 = section.bounds
    gx, gy = np.meshgrid(np.linspace(x0, x1, n), np.linspace(y0, y1, n), indexing="ij")
    q = np.column_stack([gx.ravel(), gy.ravel()])
    return q[section.contains(q)]


def check_swept_regions(field3d, section, place, params: np.ndarray, what: str, *,
                        planes: bool = False) -> None:
    """:class:`MaterialError` if the subregions of a piecewise ``field3d`` change along the
    sweep: at a grid of 48 x 48 points of ``section`` (those inside), placed at every sweep
    parameter of ``params`` by ``place(q (N, 2), s (N,)) -> (N, 3)``; ``what`` names the
    sweep coordinate in the message ("z", "the angle"), ``planes`` whether jumps on planes
    across it are embedded too (the message says so)."""
    if not has_subregions(field3d):
        return
    q = section_grid(section, 48)
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
            kinds = f"swept section curves or planes across {what}" if planes else \
                "swept section curves"
            raise MaterialError(f"{head}: the "
                                f"subregion changes with {what} near ({x:.6g}, {y:.6g}, "
                                f"{z:.6g}); in a sweep the jumps must not move with {what} "
                                f"(they are embedded as {kinds})")


def axial_cuts(field3d, section, place, s0: float, s1: float, what: str) -> np.ndarray:
    """The sweep parameters in ``(s0, s1)`` of the planes across the axis on which a
    piecewise ``field3d``'s jumps lie, sorted (none for a field without subregions, or
    whose subregions do not change along the sweep).

    A coating over a substrate (``where(z < 1, ...)``) has one; a laminate one per layer
    boundary. Found along the sweep at the points of a :data:`CUT_GRID` x :data:`CUT_GRID`
    grid of ``section`` (``place`` as in :func:`check_swept_regions`): the subregion is
    sampled at :data:`CUT_SAMPLES` parameters, every change bisected to the rounding
    error, and the changes gathered into planes (within ``1e-9`` of the length). A layer
    thinner than the sampling's step (the length / 512) may be missed; its jumps are then
    caught below.

    :class:`MaterialError` (one line, naming the condition and a point) if the jumps are not
    so: more than :data:`MAX_CUTS` planes (a jump surface inclined to the axis), a change
    along the sweep between two planes (:func:`check_swept_regions` on each layer), or
    layers whose section jumps differ (then they are not swept curves; with a formula's
    conditions, each in either the section's coordinates or the axis', they never do).

    >>> from hetmesh.material import AnalyticField
    >>> from hetmesh.tri.geometry import Domain, Loop
    >>> f = AnalyticField({"metal": "where(z < 1.25, 0.2, 0.7 + 0.1*x)"},
    ...                   ["ceramic", "metal"], dim=3)
    >>> sq = Domain(Loop.polygon([(0, 0), (1, 0), (1, 1), (0, 1)]))
    >>> to3d = lambda q, s: np.column_stack([q, s])
    >>> axial_cuts(f, sq, to3d, 0.0, 2.0, "z").round(12).tolist()
    [1.25]
    """
    if not has_subregions(field3d):
        return np.zeros(0)
    q = section_grid(section, CUT_GRID)
    if not len(q):
        return np.zeros(0)
    length = float(s1 - s0)
    s = s0 + length * np.linspace(0.0, 1.0, CUT_SAMPLES)
    s[-1] = s1
    reg = np.asarray(field3d.region(place(np.tile(q, (len(s), 1)), np.repeat(s, len(q)))))
    reg = reg.reshape(len(s), len(q))
    i, j = np.nonzero(reg[1:] != reg[:-1])
    lo, hi = s[i], s[i + 1]
    qj, r0 = q[j], reg[i, j]
    for _ in range(BISECT_STEPS):  # the last parameter still in the first subregion
        mid = 0.5 * (lo + hi)
        same = np.asarray(field3d.region(place(qj, mid))) == r0
        lo, hi = np.where(same, mid, lo), np.where(same, hi, mid)
    tol = 1e-9 * length
    pos = np.sort(0.5 * (lo + hi))
    pos = pos[(pos > s0 + tol) & (pos < s1 - tol)]
    if not len(pos):
        cuts = np.zeros(0)
    else:
        split = np.flatnonzero(np.diff(pos) > tol) + 1
        cuts = np.array([float(np.median(g)) for g in np.split(pos, split)])
    if len(cuts) > MAX_CUTS:
        x, y, z = place(qj[[0]], lo[[0]])[0]
        describe = getattr(field3d, "describe_jump", None)
        head = describe(int(r0[0]), int(reg[i[0] + 1, j[0]])) if callable(describe) else \
            "material.composition"
        raise MaterialError(f"{head}: the subregion changes with {what} at {len(cuts)} "
                            f"levels or more, e.g. near ({x:.6g}, {y:.6g}, {z:.6g}); in a "
                            f"sweep the jumps must not move with {what} (they are embedded "
                            f"as swept section curves or at most {MAX_CUTS} planes across "
                            f"{what})")
    edges = np.concatenate([[s0], cuts, [s1]])
    mids = []
    for a, b in zip(edges[:-1], edges[1:]):
        params = a + (b - a) * np.linspace(0.01, 0.99, 9)
        check_swept_regions(field3d, section, place, params, what, planes=True)
        mids.append(0.5 * (a + b))
    if len(mids) > 1:
        _same_partitions(field3d, section, place, np.array(mids), what)
    return cuts


#: a layer between jump planes thinner than this x the section's median edge is warned of
THIN_LAYER = 0.25


def warn_thin_layers(thickness: np.ndarray, edge, levels: np.ndarray, what: str,
                     log) -> bool:
    """Log one warning if a layer between jump planes (``thickness (K,)``, between
    ``levels (K + 1,)``) is thinner than :data:`THIN_LAYER` x the section's edge there
    (``edge``: one length, or one per layer): its tetrahedra are flat (their smallest
    dihedral angles fall with the ratio), as an isotropic mesh cannot be coarser than the
    layer is thin without them. Whether one is."""
    t = np.asarray(thickness, dtype=float)
    e = np.broadcast_to(np.asarray(edge, dtype=float), t.shape)
    thin = np.flatnonzero(t < THIN_LAYER * e)
    if not len(thin):
        return False
    k = int(thin[np.argmin(t[thin] / e[thin])])
    log.warning("the layer between the jumps at %s = %.6g and %.6g is %.3g thick, under "
                "the section's edge %.3g there: its tetrahedra are flat; a --max-size "
                "about its thickness shapes them better, at many more tetrahedra", what,
                levels[k], levels[k + 1], t[k], e[k])
    return True


def _same_partitions(field3d, section, place, mids: np.ndarray, what: str) -> None:
    """:class:`MaterialError` unless the section's subregions divide it the same way in
    every layer (at the layers' middles ``mids``): one labelling, renamed."""
    q = section_grid(section, 48)
    if not len(q):
        return
    ref = np.asarray(field3d.region(place(q, np.full(len(q), mids[0]))))
    for s in mids[1:]:
        r = np.asarray(field3d.region(place(q, np.full(len(q), s))))
        pairs, inv = unique(np.column_stack([ref, r]), axis=0, return_inverse=True)
        _, ia = unique(pairs[:, 0], return_inverse=True)
        _, ib = unique(pairs[:, 1], return_inverse=True)
        shared = (np.bincount(ia)[ia] > 1) | (np.bincount(ib)[ib] > 1)  # per pair
        if not shared.any():
            continue
        k = int(np.flatnonzero(shared[np.ravel(inv)])[0])
        a, b = int(ref[k]), int(r[k])
        x, y, z = place(q[[k]], np.array([s]))[0]
        describe = getattr(field3d, "describe_jump", None)
        head = describe(int(a), int(b)) if callable(describe) else "material.composition"
        raise MaterialError(f"{head}: the section's jumps differ between the layers "
                            f"across {what} (near ({x:.6g}, {y:.6g}, {z:.6g})); in a sweep "
                            f"the jumps must be swept section curves or planes across "
                            f"{what}")


def plane_faces(tets: np.ndarray, on: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The faces of ``tets`` on jump planes and the plane ``k`` of each: ``on (P, K)`` tells
    which planes every point lies on (a point of a revolution's axis lies on them all).
    ``(faces (F, 3), k (F,))``, every face once, oriented as a face of its first
    tetrahedron."""
    t = np.asarray(tets, dtype=np.int64)
    on = np.asarray(on, dtype=bool)
    if not on.shape[1] or not len(t):
        return np.zeros((0, 3), np.int64), np.zeros(0, np.int64)
    f = t[:, TET_FACES].reshape(-1, 3)
    all3 = on[f[:, 0]] & on[f[:, 1]] & on[f[:, 2]]  # (F, K)
    hit = all3.any(axis=1)
    f, k = f[hit], np.argmax(all3[hit], axis=1)
    _, first = unique(np.sort(f, axis=1), axis=0, return_index=True)
    first = np.sort(first)
    return f[first], k[first]


def on_axial_planes(points: np.ndarray, axis: int, cuts: np.ndarray) -> np.ndarray:
    """``(P, K)``: whether every point is on the plane ``points[:, axis] == cuts[k]``,
    exactly (a prism's layers put their points there, and a bisection keeps them)."""
    return np.asarray(points)[:, axis][:, None] == np.asarray(cuts, dtype=float)[None, :]


def area(points: np.ndarray, faces: np.ndarray) -> float:
    """The total area of the triangles ``faces (F, 3)``."""
    f = np.asarray(faces, dtype=np.int64).reshape(-1, 3)
    p = np.asarray(points)
    return 0.5 * float(np.linalg.norm(np.cross(p[f[:, 1]] - p[f[:, 0]], p[f[:, 2]] - p[f[:, 0]]),
                                      axis=1).sum())


def plane_problems(points: np.ndarray, faces: np.ndarray, k: np.ndarray, distance,
                   cuts: np.ndarray, section_area: float, tol: float) -> list[str]:
    """One line per jump plane whose recorded triangles leave it (``distance(points, c) ->
    (N,)`` over ``tol``) or do not cover the section (their area off ``section_area`` by
    more than 1e-9 of it: the planes reach the sweep's boundary everywhere)."""
    out = []
    p = np.asarray(points)
    for j, c in enumerate(cuts):
        f = np.asarray(faces, dtype=np.int64)[np.asarray(k) == j]
        off = float(np.max(distance(p[np.unique(f)], c), initial=0.0))
        a = area(p, f)
        if off > tol or abs(a - section_area) > 1e-9 * section_area:
            out.append(f"the jump plane at {c:.9g} along the sweep: its triangles are "
                       f"{off:.3g} off it and cover {a:.9g} of the section's "
                       f"{section_area:.9g}")
    return out


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
