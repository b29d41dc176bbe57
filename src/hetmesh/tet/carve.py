"""Extrusions and revolutions minus primitives that are not through-holes: a blind bore, a
pocket (box) or a spherical cavity cut into a swept 2D section.

A :class:`CarvedSolid` is a swept solid (a :class:`~hetmesh.tet.solid.Prism` or a
:class:`~hetmesh.tet.revolve.Revolution`) minus boxes, cylinders and spheres of
:mod:`hetmesh.tet.implicit`. Its faces are the swept solid's (the caps or the ends and one
per section or profile curve, under their names) and the faces of the subtracted primitives
that bound it (``name`` for a sphere or a cylinder's side, ``name.bottom``, ``name.top``,
``name.xmin`` ... for the others). Every face lies on a *surface* with a signed function
``g`` (zero on it) and its gradient: axis-aligned planes, cylinders and spheres
(:class:`~hetmesh.tet.implicit.Surface`), tilted planes (:class:`FlatSurface`: a section
segment swept along the axis, the end of a partial revolution) and the cones and tori of
profile curves turned about the axis (:class:`MeridianSurface`).

:func:`generate_carved` meshes it in the general mesher's steps
(:mod:`hetmesh.tet.general`, whose public functions it calls), with the swept mesh as the
background instead of a grid:

1. *Background*: the swept mesh of the solid without the subtractions
   (:func:`hetmesh.tet.extrude.generate_extruded`, :func:`hetmesh.tet.revolve.generate_revolved`):
   planar faces exact, curved ones within the chord tolerance. MMG remeshes it (up to
   :data:`PRE_ROUNDS` times) with the size capped near each subtracted primitive
   (:func:`feature_size`, growing by :data:`SLOPE` x the distance), until its level sets are
   resolved (:data:`RESOLVED`).
2. *Cuts*: MMG's level-set mode splits the tetrahedra along every surface of every
   subtracted primitive in turn (planes exactly, curved surfaces within interpolation
   error; vertices within :data:`SNAP` x the size of a surface count as on it); the
   references say on which side of each surface a tetrahedron lies, and the tetrahedra
   inside the primitive are dropped (:func:`carve`).
3. *Faces*: every boundary triangle is given the face its corners lie on
   (:meth:`CarvedSolid.classify`) and every boundary vertex is projected onto the exact
   surfaces of its faces; where that turns tetrahedra over, flips, untangling and the
   collapse of short boundary edges repair it (:func:`project_untangled`).
4. *Size* and 5. *repair*: MMG remeshing to ``S delta_0 / |grad f|`` (capped for the chord
   tolerance on curved faces, MMG's Hausdorff distance :data:`HAUSD` x that tolerance),
   repeated while it still coarsens (:func:`remesh_settled`), size rounds shrinking the
   size at the violators (:func:`round_size`, :func:`next_shrink`), edge bisection,
   projection (:func:`hetmesh.tet.refine.repair`), as for solids of primitives.
6. *Slivers*: short boundary edges of tetrahedra under :data:`SLIVER_COLLAPSE` degrees
   collapsed (:func:`collapse_boundary`), flips and edge removals of those under
   :data:`SLIVER` (:func:`hetmesh.tet.flips.flip_improve`), delta kept below delta_0.
7. *Verification* (:func:`carved_problems`): :func:`hetmesh.tet.general.solid_problems`
   (validity, conformity, a closed boundary, planar faces exact and curved ones within the
   chord tolerance at 12 points per triangle, the volume, every centroid inside, delta)
   and every boundary triangle within the extent of its face (a bore's bottom triangle in
   its disk, a section segment's in its strip).

The same input gives the same mesh (the 2D mesher is seeded, MMG deterministic).

>>> from hetmesh.tet.solid import box
>>> from hetmesh.tet.implicit import Cylinder
>>> s = CarvedSolid(box((0, 0, 0), (2, 1, 1)),
...                 (Cylinder((1, 0.5), 0.25, 2, 0.5, 2.0, ("bore", "bore.bottom", "bore.top")),))
>>> s.face_names[-2:]
('bore', 'bore.bottom')
>>> round(s.volume, 9) == round(2 - 3.141592653589793 * 0.0625 * 0.5, 9)
True
"""

from __future__ import annotations

import logging
import math
import time
from dataclasses import dataclass
from functools import cached_property, partial

import numpy as np

from ..errors import BudgetError, MeshingError
from ..mesh import simplex_measures
from ..metrics import delta_vertices
from ..topology import unique
from .collapse import collapse_edges
from .faces import boundary_faces
from .flips import flip_improve, flip_slivers
from .general import (
    REPROJECT,
    SHRINK,
    SIZE_ROUNDS,
    cap_curved,
    check_positive,
    estimate_solid,
    face_keeper,
    keep_positive,
    levelset_cut,
    orient_positive,
    project,
    remesh_solid,
    remesh_until_settled,
    size_field,
    solid_problems,
    split_bits,
)
from .implicit import Box, Cylinder, Sphere, Surface, surface_sample
from .levelset import split_across
from .mesher import CHORD, TetResult
from .quality import min_dihedral
from .refine import repair
from .solid import Prism, grid_inside
from .verify import raise_problems

__all__ = ["CarvedSolid", "FlatSurface", "MeridianSurface", "generate_carved",
           "carved_problems", "carve_refusal", "carved_start",
           "snap_onto", "split_across", "remove_slivers", "remesh_settled", "round_size",
           "shrink_at", "next_shrink", "HAUSD"]

log = logging.getLogger(__name__)

#: the background's size near a subtracted primitive: its smallest radius or extent over this
CELLS_PER_FEATURE = 3.0
#: growth of that size with the distance to the primitive
SLOPE = 0.5
#: remeshings of the background towards the primitives' sizes, at most
PRE_ROUNDS = 3
#: the level sets are resolved when the edges near a primitive are at most this x its size
RESOLVED = 2.5
#: vertices within this x the primitive's size of a surface count as on it in its cut
SNAP = 0.1
#: a vertex within SNAP of a surface is not snapped onto it where that would leave a
#: tetrahedron at this fraction of its volume or less (:func:`snap_onto`)
CRUSH = 0.02
#: ... checked for the vertices within this x the primitive's size of the face's extent
SNAP_REACH = 1.0
#: tetrahedra with a smaller dihedral angle (degrees) lose a short boundary edge at the end
SLIVER_COLLAPSE = 5.0
#: tetrahedra with a smaller dihedral angle (degrees) are flipped at the end where that helps
SLIVER = 15.0
#: samples per direction of a primitive's surface (which faces bound the solid)
FACE_SAMPLES = 40
#: the grid of the volume estimate when it has no closed form (within 1 %)
VOLUME_GRID = 96
#: rounds of untangling (interior vertices to their neighbours' mean) after a projection
UNTANGLE = 8
#: MMG's Hausdorff distance in the size rounds, x the chord tolerance: at half of it, MMG
#: made the bore's and the dimple's edges of carved_plate half the chord-limited size
#: (:func:`hetmesh.tet.general.cap_curved`), and the gradation carried that into the volume
HAUSD = 1.0
#: a size round's MMG remeshing is repeated while it removes more than
#: :data:`~hetmesh.tet.general.SETTLE` of the tetrahedra, up to this many remeshings in all
SETTLE_PASSES = 4


# -- surfaces ---------------------------------------------------------------------------

@dataclass(frozen=True)
class FlatSurface:
    """The plane ``normal . p = offset`` (``normal`` a unit 3-vector): a section segment swept
    along a prism's axis, the end of a partial revolution. ``g`` is the signed distance."""

    normal: tuple
    offset: float
    kind = "flat"
    curved = False
    radius = math.inf

    def g(self, points) -> np.ndarray:
        p = np.asarray(points, dtype=float).reshape(-1, 3)
        return p @ np.asarray(self.normal) - self.offset

    def grad(self, points) -> np.ndarray:
        p = np.asarray(points, dtype=float).reshape(-1, 3)
        return np.broadcast_to(np.asarray(self.normal, dtype=float), p.shape).copy()


@dataclass(frozen=True)
class MeridianSurface:
    """A profile line or circle turned about the z axis: a cone (``kind`` "cone": the line
    ``a . (r, z) = b``, ``a`` unit) or a torus ("torus": the circle of centre ``a`` and radius
    ``b`` in the ``(r, z)`` half-plane). ``g`` is the signed distance in the meridian
    half-plane (the distance to the surface); ``radius`` the smallest principal radius of
    curvature over the face (for the chord-limited size)."""

    kind: str
    a: tuple
    b: float
    radius: float
    curved = True

    def _rz(self, p):
        r = np.hypot(p[:, 0], p[:, 1])
        return r, p[:, 2]

    def g(self, points) -> np.ndarray:
        p = np.asarray(points, dtype=float).reshape(-1, 3)
        r, z = self._rz(p)
        if self.kind == "cone":
            return self.a[0] * r + self.a[1] * z - self.b
        return np.hypot(r - self.a[0], z - self.a[1]) - self.b

    def grad(self, points) -> np.ndarray:
        p = np.asarray(points, dtype=float).reshape(-1, 3)
        r, z = self._rz(p)
        if self.kind == "cone":
            gr, gz = np.full(len(p), self.a[0]), np.full(len(p), self.a[1])
        else:
            d = np.hypot(r - self.a[0], z - self.a[1])
            d = np.where(d > 0, d, 1.0)
            gr, gz = (r - self.a[0]) / d, (z - self.a[1]) / d
        rs = np.where(r > 0, r, 1.0)
        return np.column_stack([gr * p[:, 0] / rs, gr * p[:, 1] / rs, gz])


def _plane(normal, offset: float):
    """An axis-aligned :class:`~hetmesh.tet.implicit.Surface` plane when ``normal`` is a
    coordinate direction (then its coordinate is set exactly), else a :class:`FlatSurface`."""
    n = np.asarray(normal, dtype=float)
    n = n / np.linalg.norm(n)
    a = int(np.argmax(np.abs(n)))
    if np.abs(np.delete(n, a)).max() <= 1e-14:
        sign = 1.0 if n[a] > 0 else -1.0
        return Surface("plane", axis=a, value=float(sign * offset), sign=sign)
    return FlatSurface(tuple(float(c) for c in n), float(offset))


@dataclass(frozen=True)
class CarvedFace:
    """Face ``name`` on ``surface``: ``role`` "cap" (a prism's end, ``index`` 0 or 1),
    "end" (a partial revolution's, ``index`` 0 or 1), "curve" (section or profile curve
    ``index``) or "primitive" (surface ``k`` of subtracted primitive ``index``)."""

    name: str
    surface: object
    role: str
    index: int
    k: int = 0


# -- the solid ----------------------------------------------------------------------------

@dataclass(frozen=True, eq=False)
class CarvedSolid:
    """``swept`` (a :class:`~hetmesh.tet.solid.Prism` or a
    :class:`~hetmesh.tet.revolve.Revolution`) minus the ``subtract`` primitives
    (:mod:`hetmesh.tet.implicit`); ``where`` prefixes errors."""

    swept: object
    subtract: tuple
    where: str = ""

    @property
    def prism(self) -> bool:
        return isinstance(self.swept, Prism)

    @cached_property
    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        lo, hi = self.swept.bounds
        return np.asarray(lo, float), np.asarray(hi, float)

    @property
    def diameter(self) -> float:
        return float(self.swept.diameter)

    @property
    def domain(self):
        """The section of a prism, the profile of a revolution."""
        return self.swept.section if self.prism else self.swept.profile

    # -- faces
    @cached_property
    def faces(self) -> tuple[CarvedFace, ...]:
        """The swept solid's faces, then the subtracted primitives' that bound the solid."""
        out = list(self._swept_faces())
        for i, prim in enumerate(self.subtract):
            for k, (s, name) in enumerate(zip(prim.surfaces, prim.names)):
                if self._present(i, k):
                    out.append(CarvedFace(name, s, "primitive", i, k))
        return tuple(out)

    @cached_property
    def face_names(self) -> tuple[str, ...]:
        return tuple(f.name for f in self.faces)

    @property
    def curved(self) -> tuple:
        return tuple(f.surface for f in self.faces if f.surface.curved)

    def _swept_faces(self):
        sw = self.swept
        if self.prism:
            a, (u, v) = sw.axis, sw.uv
            for j, (name, s, sign) in enumerate(zip(sw.cap_names, (sw.s0, sw.s1), (-1, 1))):
                yield CarvedFace(name, Surface("plane", axis=a, value=float(s), sign=sign),
                                 "cap", j)
            for i, c in enumerate(sw.section.curves):
                cv = c.curve
                if hasattr(cv, "radius"):
                    c3 = [0.0, 0.0, 0.0]
                    c3[u], c3[v] = float(cv.center[0]), float(cv.center[1])
                    s = Surface("cylinder", axis=a, center=tuple(c3), radius=float(cv.radius))
                else:
                    d = np.asarray(cv.end) - np.asarray(cv.start)
                    n3 = np.zeros(3)
                    n3[u], n3[v] = d[1], -d[0]
                    n3 /= np.linalg.norm(n3)
                    s = _plane(n3, float(n3[u] * cv.start[0] + n3[v] * cv.start[1]))
                yield CarvedFace(c.name, s, "curve", i)
            return
        if not sw.full:
            th = sw.sweep
            yield CarvedFace("start", _plane((0.0, 1.0, 0.0), 0.0), "end", 0)
            yield CarvedFace("end", _plane((-math.sin(th), math.cos(th), 0.0), 0.0), "end", 1)
        small = 1e-3 * sw.profile.diameter
        for i, c in enumerate(sw.profile.curves):
            if i in sw.axis_curves:
                continue
            yield CarvedFace(c.name, _meridian(c.curve, small), "curve", i)

    def _present(self, i: int, k: int) -> bool:
        """Whether face ``k`` of subtracted primitive ``i`` bounds the solid somewhere
        (at sample points strictly inside the swept solid, outside the other primitives)."""
        prim = self.subtract[i]
        pts = surface_sample(prim.surfaces[k], prim, FACE_SAMPLES)
        tol = 1e-9 * self.diameter
        ok = prim.on_face(k, pts, tol) & self._in_swept(pts, -tol)
        for j, other in enumerate(self.subtract):
            if j != i:
                ok &= ~_strictly_in(other, pts, -tol)
        return bool(ok.any())

    # -- queries
    def _coords(self, points):
        """Section or profile coordinates ``q (N, 2)`` and the axis value or the angle."""
        return self.swept.to2d(points)

    def _in_swept(self, points, tol: float) -> np.ndarray:
        """Whether ``points`` lie in the swept solid widened by ``tol`` (narrowed if
        negative)."""
        p = np.asarray(points, dtype=float).reshape(-1, 3)
        q, s = self._coords(p)
        ok = _in_domain(self.domain, q, tol)
        sw = self.swept
        if self.prism:
            ok &= (s >= sw.s0 - tol) & (s <= sw.s1 + tol)
        elif not sw.full:
            # angles past the middle of the gap count from the start backwards
            th = np.where(s > 0.5 * sw.sweep + math.pi, s - 2 * math.pi, s)
            arc = np.maximum(q[:, 0], 0.0)
            ok &= (th * arc >= -tol) & ((th - sw.sweep) * arc <= tol) | (q[:, 0] <= tol)
        return ok

    def contains(self, points, tol: float | None = None) -> np.ndarray:
        """Whether each point ``(N, 3)`` lies in the solid (closed, widened by ``tol``,
        default 1e-9 x the diameter)."""
        tol = 1e-9 * self.diameter if tol is None else tol
        p = np.asarray(points, dtype=float).reshape(-1, 3)
        ok = self._in_swept(p, tol)
        for prim in self.subtract:
            ok &= ~_strictly_in(prim, p, tol)
        return ok

    def sample(self, n: int = 24) -> np.ndarray:
        """About ``n**3`` points of a regular grid over the bounds, those in the solid."""
        return grid_inside(self, n)

    def face_distance(self, fi: int, points) -> np.ndarray:
        """The distance of ``points`` to face ``fi``'s surface: to a section or profile
        curve itself (a finite curve), else ``|g|``."""
        f = self.faces[fi]
        p = np.asarray(points, dtype=float).reshape(-1, 3)
        if f.role == "curve":
            q, _ = self._coords(p)
            return self.domain.curves[f.index].curve.distance(q)
        return np.abs(f.surface.g(p))

    def on_face(self, fi: int, points, tol: float) -> np.ndarray:
        """Whether ``points`` (on face ``fi``'s surface) lie within ``tol`` of the face's
        extent: a cap's or an end's domain, a curve face's length or angle, a primitive
        face's other constraints."""
        f = self.faces[fi]
        p = np.asarray(points, dtype=float).reshape(-1, 3)
        if f.role == "primitive":
            return self.subtract[f.index].on_face(f.k, p, tol)
        q, s = self._coords(p)
        sw = self.swept
        if f.role == "curve":
            if self.prism:
                return (s >= sw.s0 - tol) & (s <= sw.s1 + tol)
            return self._in_swept(p, tol)
        if f.role == "end":  # the half-plane's signed radius, then the profile
            th = 0.0 if f.index == 0 else sw.sweep
            q = np.column_stack([p[:, 0] * math.cos(th) + p[:, 1] * math.sin(th), p[:, 2]])
        return _in_domain(self.domain, q, tol)

    def classify(self, tri, tol: float) -> np.ndarray:
        """Face index of boundary triangles ``tri (K, 3, 3)``: the face closest to all three
        corners (within ``tol``) whose extent holds the centroid; -1 where none (a tie goes
        to the swept solid's face)."""
        tri = np.asarray(tri, dtype=float).reshape(-1, 3, 3)
        k = len(tri)
        best = np.full(k, np.inf)
        out = np.full(k, -1, dtype=np.int64)
        cen = tri.mean(axis=1)
        for fi in range(len(self.faces)):
            d = self.face_distance(fi, tri.reshape(-1, 3)).reshape(k, 3).max(axis=1)
            cand = np.flatnonzero((d <= tol) & (d < best))
            if not len(cand):
                continue
            ok = self.on_face(fi, cen[cand], tol)
            cand = cand[ok]
            best[cand], out[cand] = d[cand], fi
        return out

    def classify_faces(self, tri_points) -> np.ndarray:
        """:meth:`classify` within 1 % of the diameter."""
        return self.classify(tri_points, 0.01 * self.diameter)

    # -- volume
    @cached_property
    def exact_volume(self) -> float | None:
        """The volume when it has a closed form: the swept solid's less each primitive's
        part in it, when the primitives' boxes are apart and each part has one (in a prism:
        the primitive's shadow on the section inside the section, so only the caps cut it;
        in a revolution: the primitive inside it). Else None."""
        subs = self.subtract
        for a in range(len(subs)):
            for b in range(a + 1, len(subs)):
                alo, ahi = subs[a].bounds
                blo, bhi = subs[b].bounds
                if (np.minimum(ahi, bhi) > np.maximum(alo, blo)).all():
                    return None
        v = float(self.swept.volume)
        for prim in subs:
            part = _prism_part(self.swept, prim) if self.prism else \
                _revolution_part(self, prim)
            if part is None:
                return None
            v -= part
        return float(v)

    @cached_property
    def volume(self) -> float:
        """The exact volume if known (:attr:`exact_volume`), else a midpoint-rule estimate
        on a :data:`VOLUME_GRID`^3 grid."""
        if self.exact_volume is not None:
            return self.exact_volume
        lo, hi = self.bounds
        n = VOLUME_GRID
        h = (hi - lo) / n
        g = [lo[k] + h[k] * (np.arange(n) + 0.5) for k in range(3)]
        yy, zz = np.meshgrid(g[1], g[2], indexing="ij")
        count = 0
        for x in g[0]:
            p = np.column_stack([np.full(yy.size, x), yy.ravel(), zz.ravel()])
            count += int(self.contains(p).sum())
        return count * float(np.prod(h))


def _in_domain(dom, q, tol: float) -> np.ndarray:
    """Whether 2D points ``q`` lie in the domain widened by ``tol`` (narrowed if negative);
    the distance to its boundary is computed only where it decides."""
    ok = dom.contains(q)
    sel = ~ok if tol >= 0 else ok
    if sel.any():
        d = dom.distance_to_boundary(q[sel])
        ok[sel] = d <= tol if tol >= 0 else d > -tol
    return ok


def _meridian(curve, small: float):
    """The surface a profile curve sweeps about the z axis."""
    pts = curve.point(np.linspace(0.0, 1.0, 65))
    r = np.maximum(pts[:, 0], small)
    if hasattr(curve, "radius"):
        c, a = np.asarray(curve.center, float), float(curve.radius)
        if abs(c[0]) <= 1e-12 * max(a, 1.0):  # centred on the axis: a sphere
            return Surface("sphere", center=(0.0, 0.0, float(c[1])), radius=a)
        nr = np.abs(pts[:, 0] - c[0]) / a
        rad = float(min(a, np.min(r / np.maximum(nr, 1e-12))))
        return MeridianSurface("torus", (float(c[0]), float(c[1])), a, rad)
    d = np.asarray(curve.end, float) - np.asarray(curve.start, float)
    n = np.array([d[1], -d[0]]) / np.hypot(*d)
    off = float(n @ np.asarray(curve.start, float))
    if abs(n[0]) <= 1e-14:  # horizontal: a plane z = const
        return _plane((0.0, 0.0, n[1]), off)
    if abs(n[1]) <= 1e-14:  # vertical: a cylinder about the axis
        return Surface("cylinder", axis=2, center=(0.0, 0.0, 0.0),
                       radius=float(abs(curve.start[0])))
    rad = float(np.min(r) / abs(n[0]))
    return MeridianSurface("cone", (float(n[0]), float(n[1])), off, rad)


def _strictly_in(prim, p, tol: float) -> np.ndarray:
    """Inside ``prim`` by more than ``tol`` (outside it by less than ``-tol``)."""
    ok = np.ones(len(p), dtype=bool)
    for s in prim.surfaces:
        ok &= s.g(p) < -tol
    return ok


def _overlap(a0, a1, b0, b1) -> tuple[float, float]:
    return float(max(a0, b0)), float(min(a1, b1))


def _prism_part(prism: Prism, prim) -> float | None:
    """The volume of ``prim`` inside ``prism`` when the primitive's shadow on the section
    lies strictly inside the section (then only the caps cut it), else None."""
    a, (u, v) = prism.axis, prism.uv
    lo, hi = (np.asarray(b, float) for b in prim.bounds)
    sec = prism.section
    tol = 1e-9 * prism.diameter
    if isinstance(prim, Sphere) or (isinstance(prim, Cylinder) and prim.axis == a):
        c = np.asarray(prim.bounds[0]) + prim.radius
        q = np.array([[c[u], c[v]]])
        if not (sec.contains(q)[0] and sec.distance_to_boundary(q)[0] > prim.radius + tol):
            return None
    else:
        from shapely.geometry import box as rect
        if not sec.polygon(tol).buffer(-tol).contains(rect(lo[u], lo[v], hi[u], hi[v])):
            return None
    s0, s1 = _overlap(lo[a], hi[a], prism.s0, prism.s1)
    if s1 <= s0:
        return 0.0
    if isinstance(prim, Box):
        return float((hi[u] - lo[u]) * (hi[v] - lo[v]) * (s1 - s0))
    if isinstance(prim, Sphere):
        c, r = float(prim.center[a]), prim.radius
        x0, x1 = s0 - c, s1 - c
        return math.pi * (r * r * (x1 - x0) - (x1 ** 3 - x0 ** 3) / 3.0)
    if prim.axis == a:
        return math.pi * prim.radius ** 2 * (s1 - s0)
    # a cylinder across the axis: its disk's strip between the caps, times its length
    c, r = 0.5 * (lo[a] + hi[a]), prim.radius
    x0, x1 = (s0 - c) / r, (s1 - c) / r

    def prim_area(x):  # integral of 2 sqrt(1 - x^2) from -1 to x, times r^2
        return r * r * (x * math.sqrt(max(1 - x * x, 0.0)) + math.asin(x) + math.pi / 2)
    return float((prim_area(x1) - prim_area(x0)) * (prim.s1 - prim.s0))


def _revolution_part(solid: CarvedSolid, prim) -> float | None:
    """The volume of ``prim`` when it lies inside the revolution (at sample points of every
    surface, by more than 1e-9 x the diameter), else None."""
    tol = 1e-9 * solid.diameter
    for k in range(len(prim.surfaces)):
        pts = surface_sample(prim.surfaces[k], prim, FACE_SAMPLES)
        pts = pts[prim.on_face(k, pts, tol)]
        if not solid._in_swept(pts, -tol).all():
            return None
    return float(prim.volume)


def carve_refusal(swept, field) -> tuple[str, str] | None:
    """Why a swept solid cannot be carved, as ``(key, message)``, or None: interface curves
    (the remeshing does not keep embedded surfaces) or a composition ``field`` (2D or 3D)
    with jumps (its subregions)."""
    from ..material import has_subregions
    dom = swept.section if isinstance(swept, Prism) else swept.profile
    if dom.interfaces:
        return ("domain.interfaces", "interfaces are not available with subtractions that are "
                                     "not through-holes (the remeshing does not keep them)")
    if field is not None and has_subregions(field):
        return ("material", "a composition with jumps (subregions) is not available with "
                            "subtractions that are not through-holes (the remeshing does not "
                            "keep its discontinuities)")
    return None


# -- the mesher ---------------------------------------------------------------------------

def section_field(solid: CarvedSolid, field):
    """The 2D field the swept background is meshed with: an extruded or revolved 2D
    material's own (``field.field2d``), else the composition on the middle section
    (:func:`hetmesh.tet.extrude.mid_section_field`) or at angle 0
    (:func:`hetmesh.tet.revolve.profile_field`)."""
    f2 = getattr(field, "field2d", None)
    if f2 is not None:
        return f2
    if solid.prism:
        from .extrude import mid_section_field
        return mid_section_field(solid.swept, field)
    from .revolve import profile_field
    return profile_field(field, solid.swept)


def _background(solid: CarvedSolid, field, threshold, section_model, seed, chord, max_size,
                max_elements):
    """The swept mesh of the solid without its subtractions: ``(points, tets)``;
    ``section_model`` the 2D model of its section or profile (:func:`section_field`)."""
    sw = solid.swept
    if solid.prism:
        from .extrude import generate_extruded
        res = generate_extruded(sw, field, threshold, section_model, swept=True, seed=seed,
                                chord_tol=chord, max_size=max_size,
                                max_elements=max_elements, check=False)
    else:
        from .revolve import generate_revolved
        res = generate_revolved(sw, field, threshold, section_model, axisymmetric=True,
                                seed=seed, chord_tol=chord, max_size=max_size,
                                max_elements=max_elements, check=False)
    return res.points.astype(np.float64), res.tets.astype(np.int64)


def feature_size(prim, chord: float) -> float:
    """The background's size at a subtracted primitive: its smallest radius or extent over
    :data:`CELLS_PER_FEATURE`, at most the chord-limited edge on its curved surface."""
    lo, hi = (np.asarray(b, float) for b in prim.bounds)
    h = float((hi - lo).min())
    radius = getattr(prim, "radius", None)
    if radius is not None:
        h = min(h, radius)
        h = min(h / CELLS_PER_FEATURE, math.sqrt(6.0 * radius * chord))
        return h
    return h / CELLS_PER_FEATURE


def _feature_cap(solid: CarvedSolid, points, chord) -> np.ndarray:
    """The size cap at ``points`` near the subtracted primitives: :func:`feature_size`
    growing by :data:`SLOPE` x the (approximate) distance to each."""
    cap = np.full(len(points), np.inf)
    for prim in solid.subtract:
        d = np.max([s.g(points) for s in prim.surfaces], axis=0)
        cap = np.minimum(cap, feature_size(prim, chord) + SLOPE * np.maximum(d, 0.0))
    return cap


def _resolved(solid, p, t, chord) -> bool:
    """Whether the edges of the tetrahedra at the primitives are within :data:`RESOLVED` x
    their size
    (the level sets are resolved)."""
    e = np.concatenate([t[:, [0, 1]], t[:, [0, 2]], t[:, [0, 3]], t[:, [1, 2]], t[:, [1, 3]],
                        t[:, [2, 3]]])
    length = np.linalg.norm(p[e[:, 0]] - p[e[:, 1]], axis=1)
    mid = 0.5 * (p[e[:, 0]] + p[e[:, 1]])
    for prim in solid.subtract:
        d = np.max([s.g(mid) for s in prim.surfaces], axis=0)
        h = feature_size(prim, chord)
        near = np.abs(d) <= h
        if near.any() and float(length[near].max()) > RESOLVED * h:
            return False
    return True


def _cut(p, t, ls, refs, bit: int):
    """MMG's level-set split of ``(p, t)`` along the zero set of the vertex values ``ls``
    (no remeshing): every tetrahedron's reference gets ``2**(2 bit + 1)`` on the negative
    side, ``2**(2 bit + 2)`` on the positive one. ``(points, tets, refs)``: the points are
    ``p`` (as given, not MMG's rounding of them) followed by the new ones."""
    q, tt, rr = levelset_cut(p, t, refs, ls, split_bits(refs, bit), "a subtracted primitive")
    scale = 1e-12 * (1.0 + float(np.abs(p).max()))
    if len(q) < len(p) or not np.abs(q[:len(p)] - p).max() <= scale:
        raise MeshingError("MMG's level-set cut did not keep the vertices in their order")
    q[:len(p)] = p  # MMG's scaling rounds them
    return q, tt, rr


def snap_onto(prim, k: int, p, t, snap: float) -> tuple[np.ndarray, np.ndarray]:
    """The level set of surface ``k`` of ``prim`` at the vertices ``p`` for its cut: its
    function ``g``, zero within ``snap`` of the surface (such a vertex counts as on it, and
    moved there), except where that move would crush a tetrahedron:
    vertices near the face's extent (within :data:`SNAP_REACH` x ``snap / SNAP``) are moved
    onto the surface (one step along the gradient, exact for a plane) and in every
    tetrahedron whose volume falls to :data:`CRUSH` x its own or less (two vertices on a
    line across the surface, one of them an earlier cut's, would meet), the snapped vertex
    farthest from the surface keeps its value, until none does. MMG's cut then splits the
    edges from that vertex across the surface exactly. ``(levels, points)``: the points with
    the snapped vertices near the face's extent moved onto the surface, so that the cuts of
    the primitive's other surfaces interpolate between points on it (a vertex snapped but
    left where it was put those cuts' new vertices off the face too, up to 0.0175 on a
    pocket's walls, which the projection could then not move without crushing
    tetrahedra)."""
    s = prim.surfaces[k]
    g = s.g(p)
    snapped = np.abs(g) < snap
    ls = np.where(snapped, 0.0, g)
    near = snapped & prim.on_face(k, p, SNAP_REACH * snap / SNAP)
    if not near.any():
        return ls, p
    grad = s.grad(p[near])
    q = p.copy()
    q[near] = p[near] - (g[near] / np.maximum((grad * grad).sum(axis=1), 1e-300))[:, None] * grad
    ts = t[near[t].any(axis=1)]
    v0 = simplex_measures(p, ts)
    dist = np.abs(g)
    while True:
        bad = simplex_measures(q, ts) <= CRUSH * v0
        if not bad.any():
            break
        tb = ts[bad]
        far_d = np.where(near[tb], dist[tb], -1.0)
        has = far_d.max(axis=1) >= 0
        if not has.any():
            break
        far = tb[has, np.argmax(far_d[has], axis=1)]
        near[far] = False
        ls[far] = g[far]
        q[far] = p[far]
    kept = snapped & (ls != 0)
    if kept.any():
        log.debug("cut of surface %d: %d vertices near it not snapped (they would crush a "
                  "tetrahedron)", k, int(kept.sum()))
    return ls, q


def _carve_one(prim, p, t, chord: float):
    """The tetrahedra of ``(p, t)`` cut along the surfaces of one subtracted primitive,
    those inside it dropped (the points not used any more stay). The vertices within
    :data:`SNAP` x :func:`feature_size` of a surface count as on it and those near its face
    are moved onto it (:func:`snap_onto`)."""
    snap = SNAP * feature_size(prim, chord)
    refs = np.ones(len(t), dtype=np.int64)
    cut = []
    for k in range(len(prim.surfaces)):
        ls, snapped = snap_onto(prim, k, p, t, snap)
        if (ls >= 0).all():  # the mesh is outside this surface: nothing to drop
            return p, t
        if (ls < 0).all():  # the mesh is on the primitive's side of it
            continue
        p = snapped
        n = len(p)
        p, t, refs = _cut(p, t, ls, refs, k)
        # those left across it outside another of the primitive's surfaces are outside it
        # whatever their side of this one: they stay whole
        outside = np.zeros(len(t), dtype=bool)
        for j, other in enumerate(prim.surfaces):
            if j != k:
                outside |= (other.g(p)[t] >= 0).all(axis=1)
        p, t, refs, _ = split_across(p, t, refs, np.r_[ls, np.zeros(len(p) - n)], k,
                                     ~outside)
        cut.append(k)
    inside = np.ones(len(t), dtype=bool)
    for k in cut:
        inside &= ((refs >> (2 * k + 1)) & 1).astype(bool)
    return p, t[~inside]


def carve(solid: CarvedSolid, p, t, chord: float) -> tuple[np.ndarray, np.ndarray]:
    """The tetrahedra of ``(p, t)`` cut along every surface of every subtracted primitive,
    those inside one dropped (:func:`_carve_one`): ``(points, tets)``."""
    for prim in solid.subtract:
        p, t = _carve_one(prim, p, t, chord)
        used = unique(t)
        remap = np.full(len(p), -1, dtype=np.int64)
        remap[used] = np.arange(len(used))
        p, t = p[used], orient_positive(p[used], remap[t])
    if not len(t):
        raise MeshingError("the subtractions leave no tetrahedra")
    return p, t


def _signed_angle(points, tets) -> np.ndarray:
    """The smallest dihedral angle of each tetrahedron, -1 where its volume is not
    positive (the flips' measure: an inverted tetrahedron is the worst)."""
    return np.where(simplex_measures(points, tets) > 0, min_dihedral(points, tets), -1.0)


def project_untangled(solid: CarvedSolid, p, t, faces, markers, ok=None):
    """Every boundary vertex onto the exact surfaces of its faces
    (:func:`hetmesh.tet.general.project`), then, where that leaves tetrahedra without a
    positive volume (a tetrahedron on three vertices of a curved ridge whose middle one moved
    out), flips and edge removals inside the solid (:func:`hetmesh.tet.flips.flip_improve`,
    the new tetrahedra passing ``ok(tets)``, default all), then the interior vertices of the
    tetrahedra still tangled moved to their neighbours' mean, up to :data:`UNTANGLE` rounds,
    then short boundary edges of theirs collapsed (:func:`collapse_boundary`); the vertices
    of whatever is still tangled go back (:func:`hetmesh.tet.general.keep_positive`), and if
    that does not settle it, the projection alone on the old tetrahedra with the blocked
    vertices back (the verification names a vertex left off its face). ``(points, tets,
    faces, markers, kept)``: the points no longer used removed, ``kept`` the old indices of
    those left."""
    q = project(solid, p, faces, markers)
    moved = (q != p).any(axis=1)
    first = (q.copy(), t, faces, markers, moved.copy())
    if (simplex_measures(q, t) <= 0).any():
        check = (lambda tets, phase: np.ones(len(tets), dtype=bool)) if ok is None else \
            (lambda tets, phase: ok(tets))
        t, _ = flip_improve(q, t, np.zeros(len(t), dtype=np.int64), check, bound=1e-9,
                            measure=_signed_angle)
    bnd = np.zeros(len(p), dtype=bool)
    bnd[faces.ravel()] = True
    e = np.concatenate([t[:, [a, b]] for a in range(4) for b in range(4) if a != b])
    deg = np.maximum(np.bincount(e[:, 0], minlength=len(p)), 1).astype(float)
    for _ in range(UNTANGLE):
        bad = simplex_measures(q, t) <= 0
        if not bad.any():
            break
        free = unique(t[bad])
        free = free[~bnd[free]]
        if not len(free):
            break
        mean = np.zeros_like(q)
        np.add.at(mean, e[:, 0], q[e[:, 1]])
        q[free] = mean[free] / deg[free, None]
        moved[free] = True
    if (simplex_measures(q, t) <= 0).any():
        t, faces, markers = collapse_boundary(q, t, faces, markers, ok)
    q = keep_positive(p, q, t, moved)
    if (simplex_measures(q, t) <= 0).any():
        # the flips and collapses suit the projected places, not the old ones: back to the
        # old tetrahedra, the blocked vertices where they were
        q0, t, faces, markers, moved = first
        q = keep_positive(p, q0, t, moved)
    check_positive(q, t, "after projecting the boundary")
    kept = unique(t)
    remap = np.full(len(p), -1, dtype=np.int64)
    remap[kept] = np.arange(len(kept))
    return q[kept], remap[t], remap[faces], markers, kept


def collapse_boundary(q, t, faces, markers, ok=None, bound: float = 0.0, keeps=None):
    """Boundary edges of the tetrahedra whose :func:`_signed_angle` is at most ``bound``
    (0: those without a positive volume) collapsed, the shortest first
    (:func:`hetmesh.tet.collapse.collapse_edges`: the triangles moved stay on their faces,
    the tetrahedra changed get a better smallest angle and pass ``ok(tets)``, the boundary
    triangles at the kept end ``keeps(faces, markers)``): ``(tets, faces, markers)``."""
    return collapse_edges(q, t, faces, markers, angle=_signed_angle,
                          bad=lambda ang: ang <= bound, ok=ok, keeps=keeps)


def remesh_carved(solid: CarvedSolid, p, t, faces, markers, size, hausd: float, tol: float):
    """One MMG remeshing with the boundary named again and projected
    (:func:`hetmesh.tet.general.remesh_solid`), the vertices that projection left where MMG
    put them projected again with flips and untangling (:func:`project_untangled`):
    ``(points, tets, faces, markers, size MMG interpolated)``."""
    p, t, faces, markers, h_mmg = remesh_solid(solid, p, t, faces, markers, size, hausd, tol)
    p, t, faces, markers, kept = project_untangled(solid, p, t, faces, markers)
    return p, t, faces, markers, h_mmg[kept]


def remesh_settled(solid: CarvedSolid, p, t, faces, markers, size_of, hausd: float,
                   tol: float, least: int = 1):
    """:func:`remesh_carved` to ``size_of(points, faces, markers)`` (the size per vertex),
    at least ``least`` times, then again to the size at the new vertices while a remeshing
    removes more than :data:`~hetmesh.tet.general.SETTLE` of the tetrahedra, up to
    :data:`SETTLE_PASSES` remeshings (:func:`~hetmesh.tet.general.remesh_until_settled`).
    One MMG pass coarsens a finer mesh only part of the way: on carved_plate at
    0.3 the first pass from the cut start left 9,996 tetrahedra, a second one to the same
    size 6,567; the first pass can also refine the boundary as much as it coarsens the
    inside, so that its count alone does not show it (``least`` 2 from a start). ``(points,
    tets, faces, markers, size MMG interpolated, remeshings)``."""
    def once(state, _k):
        p, t, faces, markers, _ = state
        return remesh_carved(solid, p, t, faces, markers, size_of(p, faces, markers), hausd,
                             tol)

    (p, t, faces, markers, h_mmg), passes = remesh_until_settled(
        once, (p, t, faces, markers, None), most=SETTLE_PASSES, least=least)
    return p, t, faces, markers, h_mmg, passes


def shrink_at(ref, factor, points) -> np.ndarray:
    """The factor of the nearest of the points ``ref (K, 3)`` at each of ``points``: the
    size rounds' shrinking carried over to a new mesh (ones where ``ref`` is None)."""
    if ref is None:
        return np.ones(len(points))
    from scipy.spatial import cKDTree
    _, j = cKDTree(ref).query(points)
    return factor[j]


def round_size(solid: CarvedSolid, field, threshold: float, h_max: float, h_min: float,
               chord: float, ref, factor, points, faces, markers) -> np.ndarray:
    """The size of a size round at ``points``: the material's (:func:`size_field`) times the
    rounds' shrinking (:func:`shrink_at`), at least ``h_min``, capped on the curved faces
    (:func:`hetmesh.tet.general.cap_curved`). MMG grades it itself; the graded size it
    returns is not fed back, which would keep the earlier meshes' gradation from their finer
    boundaries."""
    h = size_field(field, points, threshold, h_max, h_min) * shrink_at(ref, factor, points)
    return cap_curved(solid, np.maximum(h, h_min), faces, markers, chord)


def next_shrink(ref, factor, field, points, tets, bad, h_mmg, threshold: float,
                h_max: float, h_min: float) -> np.ndarray:
    """The shrinking after a size round on ``(points, tets)`` with violators ``bad``: the
    earlier rounds' (:func:`shrink_at`), and at the violators' vertices at most
    :data:`~hetmesh.tet.general.SHRINK` x the size MMG used there (``h_mmg``) over the
    material's, so that it bites where the gradation had already made the size smaller."""
    f = shrink_at(ref, factor, points)
    v = unique(tets[bad])
    h = size_field(field, points[v], threshold, h_max, h_min)
    f[v] = np.minimum(f[v], SHRINK * np.minimum(h_mmg[v], h) / h)
    return f


def _limits(solid: CarvedSolid, chord_tol: float | None, max_size: float | None):
    """``(chord, h_max, h_min)``: the absolute chord tolerance (default :data:`CHORD` x the
    diameter), the longest edge (a quarter of the largest extent, at most ``max_size``) and
    the shortest size (1e-4 x the diameter)."""
    chord = CHORD * solid.diameter if chord_tol is None else float(chord_tol)
    lo, hi = solid.bounds
    h_max = float((hi - lo).max()) / 4
    if max_size is not None:
        h_max = min(h_max, float(max_size))
    return chord, h_max, 1e-4 * solid.diameter


def carved_start(solid: CarvedSolid, field, threshold: float, section_model, *,
                 seed: int = 0, chord_tol: float | None = None, max_size: float | None = None,
                 max_elements: int | None = None):
    """Steps 1-3 of :func:`generate_carved` (the module docstring): the swept background
    remeshed towards the primitives' sizes, cut along their surfaces, its boundary named and
    projected: ``(points, tets, faces, markers, background remeshings)``, ``markers`` the
    face indices (from 0). The adaptive mesh and the uniform baseline
    (:func:`uniform_carved_at`) both start from it."""
    chord, h_max, h_min = _limits(solid, chord_tol, max_size)
    hausd = 0.5 * chord
    exact = 1e-9 * solid.diameter
    # 1. the swept background, remeshed towards the primitives' sizes
    p, t = _background(solid, field, threshold, section_model, seed, chord, max_size,
                       max_elements)
    faces, _ = boundary_faces(t)
    markers = solid.classify(p[faces], max(exact, chord))
    if (markers < 0).any():
        raise MeshingError(f"{int((markers < 0).sum())} triangles of the swept mesh on no face")
    pre = 0
    while pre < PRE_ROUNDS:
        pre += 1
        size = np.minimum(size_field(field, p, threshold, h_max, h_min),
                          _feature_cap(solid, p, chord))
        size = cap_curved(solid, np.maximum(size, h_min), faces, markers, chord)
        p, t, faces, markers, _ = remesh_carved(solid, p, t, faces, markers, size, hausd,
                                               max(10 * chord, exact))
        if _resolved(solid, p, t, chord):
            break
    # 2. cuts; 3. faces
    p, t = carve(solid, p, t, chord)
    tol = 0.5 * max(feature_size(prim, chord) for prim in solid.subtract)
    faces, _ = boundary_faces(t)
    markers = solid.classify(p[faces], tol)
    if (markers < 0).any():
        c = p[faces[markers < 0][0]].mean(axis=0)
        raise MeshingError(f"{int((markers < 0).sum())} boundary triangles on no face of the "
                           f"solid after the cuts (e.g. at ({c[0]:.6g}, {c[1]:.6g}, "
                           f"{c[2]:.6g}))")
    p, t, faces, markers, _ = project_untangled(solid, p, t, faces, markers)
    return p, t, faces, markers, pre


def remove_slivers(solid: CarvedSolid, p, t, faces, markers, comp, threshold: float,
                   chord: float):
    """Step 6 of :func:`generate_carved`: short boundary edges of the tetrahedra under
    :data:`SLIVER_COLLAPSE` degrees collapsed (:func:`collapse_boundary`; the triangles at
    the kept end pass the verification's checks of their faces,
    :func:`hetmesh.tet.general.face_keeper`: a collapse along a curved face can leave a
    triangle whose middle is farther from the surface than ``chord``), then flips and
    edge removals of those under :data:`SLIVER` inside the solid
    (:func:`hetmesh.tet.flips.flip_slivers`), every new tetrahedron's delta over the vertex
    compositions ``comp`` below ``threshold``: ``(points, tets, faces, markers, comp)``, the
    vertices no longer used removed."""
    t, faces, markers = collapse_boundary(p, t, faces, markers,
                                          lambda tets: delta_vertices(comp, tets) < threshold,
                                          bound=SLIVER_COLLAPSE,
                                          keeps=face_keeper(solid, p, chord))
    p, t, faces, comp = flip_slivers(p, t, faces, comp, threshold, SLIVER)
    return p, t, faces, markers, comp


def generate_carved(solid: CarvedSolid, field, threshold: float, section_model, *,
                    seed: int = 0, chord_tol: float | None = None,
                    max_elements: int | None = None, max_size: float | None = None,
                    check: bool = True) -> TetResult:
    """Tetrahedralise a :class:`CarvedSolid` with every element's delta below ``threshold``
    (see the module docstring); ``section_model`` the 2D model (``hetmesh.io.model.Model``)
    of its section or profile with :func:`section_field`, which the background is swept
    from; ``chord_tol`` absolute (default :data:`CHORD` x the diameter), ``max_size`` the
    longest edge."""
    t0 = time.perf_counter()
    chord, h_max, h_min = _limits(solid, chord_tol, max_size)
    est = estimate_solid(solid, field, threshold)
    if max_elements is not None and est > max_elements:
        raise BudgetError(f"about {est:.0f} tetrahedra are needed for delta_0 = {threshold} "
                          f"but the budget is {max_elements}")
    # 1. the swept background, remeshed towards the primitives' sizes; 2. cuts; 3. faces
    p, t, faces, markers, pre = carved_start(solid, field, threshold, section_model,
                                             seed=seed, chord_tol=chord, max_size=max_size,
                                             max_elements=max_elements)
    # 4. size rounds
    mtol = max(0.25 * h_max, 10 * chord)
    ref = factor = None
    rounds = remeshings = 0
    for rounds in range(SIZE_ROUNDS + 1):
        size_of = partial(round_size, solid, field, threshold, h_max, h_min, chord, ref,
                          factor)
        p, t, faces, markers, h_mmg, n = remesh_settled(solid, p, t, faces, markers, size_of,
                                                        HAUSD * chord, mtol,
                                                        least=2 if rounds == 0 else 1)
        remeshings += n
        if max_elements is not None and len(t) > max_elements:
            raise BudgetError(f"the mesh has {len(t)} tetrahedra, over the budget of "
                              f"{max_elements}")
        bad = delta_vertices(field.composition(p), t) >= threshold
        log.info("carved: size round %d: %d tetrahedra, %d over delta_0", rounds, len(t),
                 int(bad.sum()))
        if not bad.any() or rounds == SIZE_ROUNDS:
            break
        factor = next_shrink(ref, factor, field, p, t, bad, h_mmg, threshold, h_max, h_min)
        ref = p
    t_place = time.perf_counter() - t0
    # 5. repair: bisection, the new boundary vertices onto their curved faces
    passes = 0
    comp = field.composition(p)
    for _ in range(REPROJECT):
        p, t, comp, delta, n = repair(p, t, field, threshold, comp=comp,
                                      max_elements=max_elements)
        passes += n
        faces, _ = boundary_faces(t)
        markers = solid.classify(p[faces], mtol)
        if n == 0:
            break
        q, t, faces, markers, kept = project_untangled(
            solid, p, t, faces, markers,
            ok=lambda tets, c=comp[:, :]: delta_vertices(c, tets) < threshold)
        p, comp = p[kept], comp[kept]
        moved = np.flatnonzero((q != p).any(axis=1))
        if not len(moved):
            break
        p = q
        comp = comp.copy()
        comp[moved] = field.composition(p[moved])
    else:
        raise MeshingError(f"the delta repair and the projection onto curved faces did not "
                           f"settle in {REPROJECT} rounds")
    # 6. slivers
    p, t, faces, markers, comp = remove_slivers(solid, p, t, faces, markers, comp, threshold,
                                                chord)
    delta = delta_vertices(comp, t)
    info = {"placement": "carved", "estimate": est, "background_rounds": pre,
            "size_rounds": rounds, "remeshings": remeshings, "repair_passes": passes,
            "composition": comp, "time_place": t_place, "h_max": h_max}
    res = TetResult(p, t.astype(np.int32), faces.astype(np.int32),
                    (markers + 1).astype(np.int32), tuple(solid.face_names), delta,
                    float(threshold), info)
    if check:
        raise_problems(carved_problems(res, solid, field, chord))
    res.info["time_total"] = time.perf_counter() - t0
    log.info("carved mesh: %d points, %d tetrahedra, %d size rounds, %d repair passes, "
             "%.2f s", len(p), len(t), rounds, passes, res.info["time_total"])
    return res


def carved_problems(res, solid: CarvedSolid, field, chord_tol: float) -> list[str]:
    """Every broken claim of a mesh of a carved solid, one line each (empty: valid):
    :func:`hetmesh.tet.general.solid_problems`, and every boundary triangle's centroid
    within the chord tolerance of its face's extent."""
    out = solid_problems(res, solid, field, chord_tol)
    markers = res.face_markers.astype(np.int64) - 1
    if (markers < 0).any():
        return out
    cen = res.points[res.faces].mean(axis=1)
    for fi, f in enumerate(solid.faces):
        sel = markers == fi
        if sel.any():
            off = ~solid.on_face(fi, cen[sel], chord_tol)
            if off.any():
                c = cen[sel][off][0]
                out.append(f"face {f.name!r}: {int(off.sum())} triangles outside the face "
                           f"(e.g. at ({c[0]:.6g}, {c[1]:.6g}, {c[2]:.6g}))")
    return out

