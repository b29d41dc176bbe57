"""Solids built from primitives: a box, a cylinder or a sphere, optionally clipped by a box,
minus any number of boxes, cylinders and spheres (fully or partly inside).

Every face is a piece of a *surface*: an axis-aligned plane (box faces, cylinder caps) or a
curved surface (a sphere, a cylinder's side) given by a smooth function ``g`` that is zero on
it and negative on the primitive's side. A primitive is the intersection of its surfaces'
negative sides; the solid is ``base ∩ clip − subtract[0] − subtract[1] − ...``.
:mod:`hetmesh.tet.general` meshes it: the planes are planes of its background grid (exact),
the curved surfaces are cut by level sets and their vertices projected onto ``g = 0``.

>>> s = CSGSolid(Sphere((0, 0, 0), 2.0), clip=Box((0, 0, 0), (2, 2, 2)),
...              subtract=(Sphere((0, 0, 0), 1.0, names=("inner",)),))
>>> s.face_names
('outer', 'xmin', 'ymin', 'zmin', 'inner')
>>> round(s.volume, 6) == round(4 / 3 * 3.141592653589793 * 7 / 8, 6)
True
>>> s.contains([[1.0, 1.0, 0.5], [0.2, 0.2, 0.2], [-0.1, 1.0, 1.0]]).tolist()
[True, False, False]
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from ..errors import GeometryError
from .solid import grid_inside

__all__ = ["Surface", "Box", "Cylinder", "Sphere", "CSGSolid", "BOX_FACES", "EDGE_SAMPLES",
           "surface_sample", "onto_surfaces"]

#: the face names of a box, in the order of its planes (x = lo, x = hi, y = lo, ...)
BOX_FACES = ("xmin", "xmax", "ymin", "ymax", "zmin", "zmax")
#: samples per parameter direction when looking for curved faces that meet
EDGE_SAMPLES = 120


def _fmt(v: float) -> str:
    return f"{v:.6g}"


@dataclass(frozen=True)
class Surface:
    """A surface of a primitive: ``kind`` "plane" (``axis``, ``value``; ``sign`` +1 when the
    primitive lies at coordinates below ``value``), "sphere" (``center``, ``radius``) or
    "cylinder" (``center`` the axis' point in the section, ``axis``, ``radius``).
    ``g(p)`` is a signed function, negative on the primitive's side, of unit gradient norm."""

    kind: str
    axis: int = 0
    value: float = 0.0
    sign: float = 1.0
    center: tuple = (0.0, 0.0, 0.0)
    radius: float = 0.0

    @property
    def curved(self) -> bool:
        return self.kind != "plane"

    def _rel(self, p: np.ndarray) -> np.ndarray:
        d = p - np.asarray(self.center, dtype=float)
        if self.kind == "cylinder":
            d[:, self.axis] = 0.0
        return d

    def g(self, points) -> np.ndarray:
        p = np.asarray(points, dtype=float).reshape(-1, 3)
        if self.kind == "plane":
            return self.sign * (p[:, self.axis] - self.value)
        return np.linalg.norm(self._rel(p), axis=1) - self.radius

    def grad(self, points) -> np.ndarray:
        p = np.asarray(points, dtype=float).reshape(-1, 3)
        if self.kind == "plane":
            out = np.zeros_like(p)
            out[:, self.axis] = self.sign
            return out
        d = self._rel(p)
        n = np.linalg.norm(d, axis=1)
        return d / np.where(n > 0, n, 1.0)[:, None]


def onto_surfaces(x: np.ndarray, surfs, iters: int = 30) -> np.ndarray:
    """Points ``x (n, 3)`` moved onto every surface of ``surfs`` at once (at most three;
    anything with ``g(points)``, ``grad(points)`` and ``kind``: a :class:`Surface`, a jump
    surface of :mod:`hetmesh.tet.jumps`) by Gauss-Newton with the least-norm step; plane
    coordinates set exactly at the end.

    >>> s = Surface("sphere", center=(0.0, 0.0, 0.0), radius=2.0)
    >>> onto_surfaces(np.array([[3.0, 0.0, 0.0]]), [s]).tolist()
    [[2.0, 0.0, 0.0]]
    """
    x = np.array(x, dtype=np.float64).reshape(-1, 3)
    for _ in range(iters):
        g = np.stack([s.g(x) for s in surfs], axis=1)            # (n, k)
        J = np.stack([s.grad(x) for s in surfs], axis=1)         # (n, k, 3)
        JJ = np.einsum("nki,nli->nkl", J, J)
        try:
            lam = np.linalg.solve(JJ, g[..., None])[..., 0]
        except np.linalg.LinAlgError:
            lam = np.linalg.lstsq(JJ.reshape(-1, len(surfs)), g.reshape(-1),
                                  rcond=None)[0].reshape(g.shape)
        step = np.einsum("nki,nk->ni", J, lam)
        x = x - step
        if np.abs(step).max() <= 1e-15 * max(1.0, float(np.abs(x).max())):
            break
    for s in surfs:
        if s.kind == "plane":
            x[:, s.axis] = s.value
    return x


def _cyl_center3(center2, axis: int) -> tuple:
    c = [0.0, 0.0, 0.0]
    u, v = {0: (1, 2), 1: (2, 0), 2: (0, 1)}[axis]
    c[u], c[v] = float(center2[0]), float(center2[1])
    return tuple(c)


class _Primitive:
    """Shared by the primitives: ``surfaces`` and ``names`` (one per surface)."""

    surfaces: tuple[Surface, ...]
    names: tuple[str, ...]

    def contains(self, points, tol: float = 0.0) -> np.ndarray:
        p = np.asarray(points, dtype=float).reshape(-1, 3)
        ok = np.ones(len(p), dtype=bool)
        for s in self.surfaces:
            ok &= s.g(p) <= tol
        return ok

    def on_face(self, k: int, points, tol: float) -> np.ndarray:
        """Whether ``points`` lie within ``tol`` of the primitive's constraints other than
        surface ``k`` (a point of surface ``k`` is then on face ``k``)."""
        p = np.asarray(points, dtype=float).reshape(-1, 3)
        ok = np.ones(len(p), dtype=bool)
        for j, s in enumerate(self.surfaces):
            if j != k:
                ok &= s.g(p) <= tol
        return ok


@dataclass(frozen=True, eq=False)
class Box(_Primitive):
    """The box ``[lo, hi]``; faces :data:`BOX_FACES` (or ``names``)."""

    lo: tuple
    hi: tuple
    names: tuple[str, ...] = BOX_FACES

    def __post_init__(self):
        lo, hi = np.asarray(self.lo, float), np.asarray(self.hi, float)
        if lo.shape != (3,) or hi.shape != (3,) or not np.isfinite(np.r_[lo, hi]).all():
            raise GeometryError("box corners must be three finite numbers each")
        if (hi - lo <= 0).any():
            k = int(np.argmax(hi - lo <= 0))
            raise GeometryError(f"a primitive's size must be positive, got "
                                f"{_fmt(hi[k] - lo[k])} along {'xyz'[k]} (max - min)")

    @cached_property
    def surfaces(self) -> tuple[Surface, ...]:
        out = []
        for a in range(3):
            out.append(Surface("plane", axis=a, value=float(self.lo[a]), sign=-1.0))
            out.append(Surface("plane", axis=a, value=float(self.hi[a]), sign=1.0))
        return tuple(out)

    @property
    def bounds(self):
        return np.asarray(self.lo, float), np.asarray(self.hi, float)

    @property
    def volume(self) -> float:
        return float(np.prod(np.asarray(self.hi, float) - np.asarray(self.lo, float)))


@dataclass(frozen=True, eq=False)
class Cylinder(_Primitive):
    """The circular cylinder of ``radius`` about the line through ``center`` (section
    coordinates of ``axis``: axis z, ``(x, y)``; x, ``(y, z)``; y, ``(z, x)``), from ``s0``
    to ``s1`` along it; faces ``side``, ``bottom``, ``top`` (or ``names``)."""

    center: tuple
    radius: float
    axis: int
    s0: float
    s1: float
    names: tuple[str, ...] = ("side", "bottom", "top")

    def __post_init__(self):
        if not (math.isfinite(self.radius) and self.radius > 0):
            raise GeometryError(f"a primitive's size must be positive, got radius "
                                f"{_fmt(self.radius)}")
        if not (math.isfinite(self.s0) and math.isfinite(self.s1)) or self.s1 <= self.s0:
            raise GeometryError(f"a primitive's size must be positive, got length "
                                f"{_fmt(self.s1 - self.s0)} (to - from)")

    @cached_property
    def surfaces(self) -> tuple[Surface, ...]:
        c3 = _cyl_center3(self.center, self.axis)
        return (Surface("cylinder", axis=self.axis, center=c3, radius=float(self.radius)),
                Surface("plane", axis=self.axis, value=float(self.s0), sign=-1.0),
                Surface("plane", axis=self.axis, value=float(self.s1), sign=1.0))

    @property
    def bounds(self):
        c = np.asarray(_cyl_center3(self.center, self.axis))
        lo, hi = c - self.radius, c + self.radius
        lo[self.axis], hi[self.axis] = self.s0, self.s1
        return lo, hi

    @property
    def volume(self) -> float:
        return math.pi * self.radius ** 2 * (self.s1 - self.s0)


@dataclass(frozen=True, eq=False)
class Sphere(_Primitive):
    """The ball of ``radius`` about ``center``; face ``outer`` (or ``names``)."""

    center: tuple
    radius: float
    names: tuple[str, ...] = ("outer",)

    def __post_init__(self):
        if not (math.isfinite(self.radius) and self.radius > 0):
            raise GeometryError(f"a primitive's size must be positive, got radius "
                                f"{_fmt(self.radius)}")

    @cached_property
    def surfaces(self) -> tuple[Surface, ...]:
        return (Surface("sphere", center=tuple(float(c) for c in self.center),
                        radius=float(self.radius)),)

    @property
    def bounds(self):
        c = np.asarray(self.center, float)
        return c - self.radius, c + self.radius

    @property
    def volume(self) -> float:
        return 4.0 / 3.0 * math.pi * self.radius ** 3


@dataclass(frozen=True)
class Face:
    """Face ``name`` of the solid: surface ``surface`` of primitive ``primitive`` (index in
    :attr:`CSGSolid.primitives`), ``k`` its index among the primitive's surfaces."""

    name: str
    primitive: int
    k: int
    surface: Surface


@dataclass(frozen=True, eq=False)
class CSGSolid:
    """``base ∩ clip − subtract...``: see the module docstring. ``where`` prefixes errors."""

    base: object
    clip: Box | None = None
    subtract: tuple = ()
    where: str = ""

    @cached_property
    def primitives(self) -> tuple:
        return (self.base,) + ((self.clip,) if self.clip is not None else ()) \
            + tuple(self.subtract)

    @property
    def n_kept(self) -> int:
        """Primitives intersected (base, clip); the rest are subtracted."""
        return 1 + (self.clip is not None)

    @cached_property
    def faces(self) -> tuple[Face, ...]:
        """The faces that bound the solid somewhere (checked on a sample of each surface)."""
        out = []
        for i, prim in enumerate(self.primitives):
            for k, (s, name) in enumerate(zip(prim.surfaces, prim.names)):
                if self._face_present(i, k, s):
                    out.append(Face(name, i, k, s))
        return tuple(out)

    @cached_property
    def face_names(self) -> tuple[str, ...]:
        return tuple(f.name for f in self.faces)

    @property
    def curved(self) -> tuple[Surface, ...]:
        """The curved surfaces, each once."""
        out = []
        for prim in self.primitives:
            out.extend(s for s in prim.surfaces if s.curved)
        return tuple(out)

    @cached_property
    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        lo, hi = self.base.bounds
        if self.clip is not None:
            clo, chi = self.clip.bounds
            lo, hi = np.maximum(lo, clo), np.minimum(hi, chi)
        return np.asarray(lo, float), np.asarray(hi, float)

    @property
    def diameter(self) -> float:
        lo, hi = self.bounds
        return float(np.linalg.norm(hi - lo))

    def classify(self, tri, tol: float) -> np.ndarray:
        """Face index (into :attr:`faces`) of boundary triangles ``tri (K, 3, 3)``: the face
        whose surface is closest to all three corners (within ``tol``) and whose
        primitive's other constraints hold at the centroid; -1 where none."""
        tri = np.asarray(tri, dtype=float).reshape(-1, 3, 3)
        k = len(tri)
        best = np.full(k, np.inf)
        out = np.full(k, -1, dtype=np.int64)
        cen = tri.mean(axis=1)
        for fi, f in enumerate(self.faces):
            g = np.abs(f.surface.g(tri.reshape(-1, 3))).reshape(k, 3).max(axis=1)
            ok = (g <= tol) & self.primitives[f.primitive].on_face(f.k, cen, tol)
            better = ok & (g < best)
            best[better], out[better] = g[better], fi
        return out

    def classify_faces(self, tri_points) -> np.ndarray:
        """:meth:`classify` within 1 % of the diameter (any chord tolerance allowed): the
        face index of each boundary triangle ``(K, 3, 3)``, -1 where none."""
        return self.classify(tri_points, 0.01 * self.diameter)

    def contains(self, points, tol: float | None = None) -> np.ndarray:
        """Whether each point ``(N, 3)`` lies in the solid (closed, widened by ``tol``,
        default 1e-9 x the diameter)."""
        tol = 1e-9 * self.diameter if tol is None else tol
        p = np.asarray(points, dtype=float).reshape(-1, 3)
        ok = self.base.contains(p, tol)
        if self.clip is not None:
            ok &= self.clip.contains(p, tol)
        for s in self.subtract:
            ok &= ~_open_contains(s, p, tol)
        return ok

    def sample(self, n: int = 24) -> np.ndarray:
        """About ``n**3`` points of a regular grid over the bounds, those in the solid."""
        return grid_inside(self, n)

    def _face_present(self, i: int, k: int, s: Surface) -> bool:
        pts = surface_sample(s, self.primitives[i], 40)
        if not len(pts):
            return False
        tol = 1e-9 * self.diameter
        ok = self.primitives[i].on_face(k, pts, tol) & self.contains(pts, tol)
        # a face of a subtracted primitive bounds the solid where it is not inside another
        # subtracted one; one of the base's where no subtracted primitive covers it
        for j, prim in enumerate(self.primitives):
            if j >= self.n_kept and j != i:
                ok &= ~_open_contains(prim, pts, -tol)
        return bool(ok.any())

    @cached_property
    def curved_edges(self) -> tuple[tuple[int, int], ...]:
        """Pairs ``(i, j)``, ``i < j``, of faces (indices into :attr:`faces`) on two
        different curved surfaces that may meet on the solid's boundary: a sample of face
        ``i``'s points (:data:`EDGE_SAMPLES` squared over its surface) has one within a
        sample step of surface ``j`` where face ``j``'s primitive's other constraints hold
        (within that step). The sample steps bound the distance from any point of the
        surface to the nearest sample, so two faces that do meet are always found; two
        that only come within a step of each other are listed too (harmless: their meshes
        then take the path for meeting faces)."""
        out = []
        curved = [fi for fi, f in enumerate(self.faces) if f.surface.curved]
        for a, i in enumerate(curved):
            for j in curved[a + 1:]:
                if self.faces[i].surface == self.faces[j].surface:
                    continue
                if self._faces_meet(i, j) or self._faces_meet(j, i):
                    out.append((i, j))
        return tuple(out)

    def _faces_meet(self, i: int, j: int) -> bool:
        fi, fj = self.faces[i], self.faces[j]
        prim = self.primitives[fi.primitive]
        pts, step = _surface_sample_step(fi.surface, prim, EDGE_SAMPLES)
        ok = prim.on_face(fi.k, pts, step) & self.contains(pts, step)
        ok &= np.abs(fj.surface.g(pts)) <= step
        ok &= self.primitives[fj.primitive].on_face(fj.k, pts, step)
        return bool(ok.any())

    @cached_property
    def exact_volume(self) -> float | None:
        """The volume when it has a closed form (no clip, or a sphere clipped to an octant-
        aligned box through its centre; subtracted primitives inside the base and apart):
        else None."""
        lo, hi = self.bounds
        base = self.base
        if self.clip is None:
            v = base.volume
        elif isinstance(base, Sphere):
            c, r = np.asarray(base.center, float), base.radius
            frac = 1.0
            for a in range(3):
                if lo[a] <= c[a] - r and hi[a] >= c[a] + r:
                    continue
                if (abs(lo[a] - c[a]) <= 1e-12 * r and hi[a] >= c[a] + r) or \
                        (abs(hi[a] - c[a]) <= 1e-12 * r and lo[a] <= c[a] - r):
                    frac *= 0.5
                    continue
                return None
            v = frac * base.volume
        else:
            return None
        subs = list(self.subtract)
        for s in subs:
            slo, shi = s.bounds
            corners = np.stack(np.meshgrid(*zip(slo, shi), indexing="ij"), -1).reshape(-1, 3)
            if isinstance(s, Sphere) and self.clip is not None and isinstance(base, Sphere) \
                    and np.allclose(s.center, base.center):
                # a concentric inner sphere of a clipped sphere: the same fraction of it
                v -= s.volume * (v / base.volume)
                continue
            if not (base.contains(corners).all() and (self.clip is None or
                                                       self.clip.contains(corners).all())):
                return None
            v -= s.volume
        for a in range(len(subs)):
            for b in range(a + 1, len(subs)):
                alo, ahi = subs[a].bounds
                blo, bhi = subs[b].bounds
                if (np.minimum(ahi, bhi) > np.maximum(alo, blo)).all():
                    return None
        return float(v)

    @cached_property
    def volume(self) -> float:
        """The exact volume if known (:attr:`exact_volume`), else a midpoint-rule estimate on
        a 96^3 grid."""
        if self.exact_volume is not None:
            return self.exact_volume
        return _grid_volume(self, 96)


def _open_contains(prim, p, tol: float) -> np.ndarray:
    """Strictly inside ``prim`` (by more than ``tol``)."""
    ok = np.ones(len(p), dtype=bool)
    for s in prim.surfaces:
        ok &= s.g(p) < -tol
    return ok


def _grid_volume(solid, n: int) -> float:
    lo, hi = solid.bounds
    h = (hi - lo) / n
    vol = 0.0
    gx = lo[0] + h[0] * (np.arange(n) + 0.5)
    gy = lo[1] + h[1] * (np.arange(n) + 0.5)
    gz = lo[2] + h[2] * (np.arange(n) + 0.5)
    yy, zz = np.meshgrid(gy, gz, indexing="ij")
    for x in gx:
        p = np.column_stack([np.full(yy.size, x), yy.ravel(), zz.ravel()])
        vol += float(solid.contains(p).sum())
    return vol * float(np.prod(h))


def _surface_sample_step(s: Surface, prim, n: int) -> tuple[np.ndarray, float]:
    """:func:`surface_sample` and a bound on the distance from any point of the sampled
    piece of the surface to its nearest sample (the diagonal of a parameter cell)."""
    lo, hi = prim.bounds
    ext = float((np.asarray(hi, float) - np.asarray(lo, float)).max())
    if s.kind == "sphere":
        # a cell spans pi R / n in the polar direction (at most: arccos spacing is finest at
        # the equator, coarsest at the poles, where the arc of 2/n in cos is about
        # R sqrt(2/n)) and 2 pi R / n around
        du = s.radius * max(math.pi / n, 2.0 * math.sqrt(1.0 / n))
        dv = 2.0 * math.pi * s.radius / n
    elif s.kind == "cylinder":
        du, dv = 2.0 * math.pi * s.radius / n, ext / n
    else:
        du = dv = ext / n
    return surface_sample(s, prim, n), math.hypot(du, dv)


def surface_sample(s: Surface, prim, n: int) -> np.ndarray:
    """Points on surface ``s`` over the primitive's extent (``n`` x ``n``, interior)."""
    lo, hi = prim.bounds
    t = (np.arange(n) + 0.5) / n
    if s.kind == "plane":
        a = s.axis
        o = [k for k in range(3) if k != a]
        u, v = np.meshgrid(lo[o[0]] + (hi[o[0]] - lo[o[0]]) * t,
                           lo[o[1]] + (hi[o[1]] - lo[o[1]]) * t, indexing="ij")
        p = np.empty((u.size, 3))
        p[:, a], p[:, o[0]], p[:, o[1]] = s.value, u.ravel(), v.ravel()
        return p
    c = np.asarray(s.center, float)
    th = 2 * np.pi * t
    if s.kind == "sphere":
        ph = np.arccos(1 - 2 * t)
        T, P = np.meshgrid(th, ph, indexing="ij")
        d = np.column_stack([np.sin(P).ravel() * np.cos(T).ravel(),
                             np.sin(P).ravel() * np.sin(T).ravel(), np.cos(P).ravel()])
        return c + s.radius * d
    u, v = {0: (1, 2), 1: (2, 0), 2: (0, 1)}[s.axis]
    T, S = np.meshgrid(th, lo[s.axis] + (hi[s.axis] - lo[s.axis]) * t, indexing="ij")
    p = np.empty((T.size, 3))
    p[:, u] = c[u] + s.radius * np.cos(T).ravel()
    p[:, v] = c[v] + s.radius * np.sin(T).ravel()
    p[:, s.axis] = S.ravel()
    return p
