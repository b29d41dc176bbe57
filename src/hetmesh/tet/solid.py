"""Solids: the 3D domains the tetrahedral mesher fills.

A :class:`Prism` is a 2D :class:`~hetmesh.geometry.Domain` (its *section*) extruded along a
coordinate axis from ``s0`` to ``s1``: boxes, cylinders and the extrusions of any 2D model
domain (outer loop, holes, interfaces). Its faces are the two caps (``bottom`` at ``s0``,
``top`` at ``s1``, or the names given) and one face per curve of the section, named after
the curve (an interface curve's lies inside the solid: the extrusion mesher embeds it).
Coordinates: the axis coordinate ``s`` and the section coordinates ``(u, v)`` in the cyclic
order (axis z: ``(x, y)``; axis x: ``(y, z)``; axis y: ``(z, x)``), so the map is a rotation
and keeps orientations.

>>> b = box((0, 0, 0), (1, 2, 3))
>>> b.volume, b.face_names
(6.0, ('zmin', 'zmax', 'ymin', 'xmax', 'ymax', 'xmin'))
>>> b.contains([[0.5, 0.5, 0.5], [2, 0, 0]]).tolist()
[True, False]
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from functools import cached_property

import numpy as np

from ..errors import GeometryError
from ..tri.geometry import Arc, Loop, Segment, make_domain

__all__ = ["Prism", "box", "cylinder", "grid_inside", "AXES"]

AXES = {"x": 0, "y": 1, "z": 2}
#: section coordinates (u, v) of each axis, cyclic so that (u, v, s) is right-handed
_UV = {0: (1, 2), 1: (2, 0), 2: (0, 1)}


def grid_inside(solid, n: int = 24) -> np.ndarray:
    """The points of the regular ``n x n x n`` grid over ``solid.bounds`` that
    ``solid.contains``: sample points of any solid (prism, revolution, primitives)."""
    lo, hi = solid.bounds
    g = [np.linspace(lo[k], hi[k], n) for k in range(3)]
    p = np.stack(np.meshgrid(*g, indexing="ij"), axis=-1).reshape(-1, 3)
    return p[solid.contains(p)]


def _fmt(v: float) -> str:
    return f"{v:.6g}"


@dataclass(frozen=True, eq=False)
class Prism:
    """A 2D domain extruded along axis ``axis`` (0, 1, 2) from ``s0`` to ``s1``.

    Parameters
    ----------
    section : Domain
        The cross-section in the ``(u, v)`` coordinates of the axis.
    axis : int
    s0, s1 : float
        The extent along the axis, ``s0 < s1``.
    cap_names : (str, str)
        Names of the faces at ``s0`` and ``s1``.
    """

    section: object
    axis: int
    s0: float
    s1: float
    cap_names: tuple[str, str] = ("bottom", "top")
    where: str = field(default="", compare=False)

    def __post_init__(self):
        pre = f"{self.where}: " if self.where else ""
        if self.axis not in (0, 1, 2):
            raise GeometryError(f"{pre}axis must be 0, 1 or 2, got {self.axis!r}")
        if not (math.isfinite(self.s0) and math.isfinite(self.s1)) or self.s1 <= self.s0:
            raise GeometryError(f"{pre}extrusion length must be positive, got "
                                f"{_fmt(self.s1 - self.s0)} (from {_fmt(self.s0)} to "
                                f"{_fmt(self.s1)})")

    # -- coordinates
    @property
    def uv(self) -> tuple[int, int]:
        return _UV[self.axis]

    def to3d(self, q: np.ndarray, s: np.ndarray) -> np.ndarray:
        """Points ``(N, 3)`` from section coordinates ``q (N, 2)`` and axis values ``s (N,)``."""
        q = np.asarray(q, dtype=float).reshape(-1, 2)
        out = np.empty((len(q), 3))
        u, v = self.uv
        out[:, u], out[:, v] = q[:, 0], q[:, 1]
        out[:, self.axis] = s
        return out

    def to2d(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(q (N, 2), s (N,))`` of ``points (N, 3)``."""
        p = np.asarray(points, dtype=float).reshape(-1, 3)
        u, v = self.uv
        return np.column_stack([p[:, u], p[:, v]]), p[:, self.axis]

    # -- measures
    @property
    def length(self) -> float:
        return float(self.s1 - self.s0)

    @cached_property
    def volume(self) -> float:
        """Exact volume: section area x length."""
        return float(self.section.area) * self.length

    @cached_property
    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """``(lo (3,), hi (3,))``."""
        b = self.section.bounds
        lo, hi = np.empty(3), np.empty(3)
        u, v = self.uv
        lo[u], lo[v], hi[u], hi[v] = b[0], b[1], b[2], b[3]
        lo[self.axis], hi[self.axis] = self.s0, self.s1
        return lo, hi

    @property
    def diameter(self) -> float:
        lo, hi = self.bounds
        return float(np.linalg.norm(hi - lo))

    @cached_property
    def convex(self) -> bool:
        """Whether the solid is convex (a convex section without holes) and has no
        interfaces (the layered placement of convex prisms does not embed them)."""
        if self.section.holes or self.section.interfaces:
            return False
        poly = self.section.polygon()
        return bool(poly.convex_hull.area <= poly.area * (1 + 1e-9))

    @cached_property
    def face_names(self) -> tuple[str, ...]:
        """Face names: the two caps, then one per section curve (marker = index + 1)."""
        return tuple(self.cap_names) + tuple(c.name for c in self.section.curves)

    def contains(self, points) -> np.ndarray:
        """Whether each point ``(N, 3)`` lies in the solid (closed)."""
        q, s = self.to2d(points)
        tol = 1e-9 * self.diameter
        ok = (s >= self.s0 - tol) & (s <= self.s1 + tol)
        inside = self.section.contains(q)
        edge = ok & ~inside
        if edge.any():  # the section's boundary belongs to it
            inside[edge] = self.section.distance_to_boundary(q[edge]) <= tol
        return ok & inside

    def sample(self, n: int = 24) -> np.ndarray:
        """About ``n**3`` points of a regular grid inside the solid, plus its corners."""
        return grid_inside(self, n)

    def classify_faces(self, tri_points: np.ndarray) -> np.ndarray:
        """The face marker (index in :attr:`face_names`) of boundary triangles given by
        their corners ``(K, 3, 3)``; -1 where a triangle lies on no face (to within
        1e-9 x the diameter)."""
        tol = 1e-9 * self.diameter
        k = len(tri_points)
        q, s = self.to2d(tri_points.reshape(-1, 3))
        q, s = q.reshape(k, 3, 2), s.reshape(k, 3)
        out = np.full(k, -1, dtype=np.int64)
        out[(np.abs(s - self.s0) <= tol).all(axis=1)] = 0
        out[(np.abs(s - self.s1) <= tol).all(axis=1)] = 1
        rest = np.flatnonzero(out < 0)
        if len(rest):
            best = np.full(len(rest), np.inf)
            arg = np.full(len(rest), -1)
            for i, c in enumerate(self.section.curves):
                d = np.max([c.curve.distance(q[rest, j]) for j in range(3)], axis=0)
                better = d < best
                best[better], arg[better] = d[better], i
            # a chord of an arc is within its sagitta of the curve: the caller checks the
            # chord tolerance; here the curve nearest to all three corners is the face
            ok = best <= tol
            out[rest[ok]] = 2 + arg[ok]
        return out


def box(lo, hi, *, axis: int = 2, where: str = "") -> Prism:
    """The box ``[lo, hi]`` (three coordinates each), faces ``xmin, xmax, ...``.

    A prism along ``axis`` (default z) whose section is the rectangle across it; the face
    names do not depend on the axis.

    >>> box((0, 0, 0), (1, 2, 3), axis=0).face_names
    ('xmin', 'xmax', 'zmin', 'ymax', 'zmax', 'ymin')
    """
    lo = np.asarray(lo, dtype=float)
    hi = np.asarray(hi, dtype=float)
    pre = f"{where}: " if where else ""
    if lo.shape != (3,) or hi.shape != (3,) or not (np.isfinite(lo).all()
                                                    and np.isfinite(hi).all()):
        raise GeometryError(f"{pre}box corners must be three finite numbers each")
    size = hi - lo
    if (size <= 0).any():
        k = int(np.argmax(size <= 0))
        raise GeometryError(f"{pre}box size along {'xyz'[k]} must be positive, got "
                            f"{_fmt(size[k])}")
    u, v = _UV[axis]
    corners = [(lo[u], lo[v]), (hi[u], lo[v]), (hi[u], hi[v]), (lo[u], hi[v])]
    names = (f"{'xyz'[v]}min", f"{'xyz'[u]}max", f"{'xyz'[v]}max", f"{'xyz'[u]}min")
    loop = Loop(tuple(Segment(a, b, name=n) for (a, b), n in
                      zip(zip(corners, corners[1:] + corners[:1]), names)), "outer")
    c = "xyz"[axis]
    return Prism(make_domain(loop), axis, float(lo[axis]), float(hi[axis]),
                 (f"{c}min", f"{c}max"), where=where)


def cylinder(center, radius: float, s0: float, s1: float, axis: int = 2, *,
             where: str = "", name: str = "side") -> Prism:
    """The circular cylinder of ``radius`` about the line through ``center`` (section
    coordinates) along ``axis``, from ``s0`` to ``s1``."""
    pre = f"{where}: " if where else ""
    if not (math.isfinite(radius) and radius > 0):
        raise GeometryError(f"{pre}cylinder radius must be positive, got {radius!r}")
    loop = Loop((replace(Arc.circle(tuple(center), float(radius)), name=name),), "outer")
    return Prism(make_domain(loop), axis, float(s0), float(s1), where=where)
