"""Node placement on iso-composition surfaces ("layers") in a prism.

Why: delta(T) of a small tetrahedron is |grad f| times its extent along the gradient. Nodes
on the level surfaces ``f = f_k`` (``f_k`` evenly spaced by ``df < delta_0``), each layer an
offset square lattice of spacing ``a = sqrt(2) w`` (``w`` the distance between adjacent
layers), make near-regular tetrahedra and half-octahedra between two adjacent layers, as in
the face-centred cubic lattice seen along a cube axis: every such tetrahedron has its
vertices on two adjacent levels, so delta(T) = df exactly, with about 0.35 x N_iso3
tetrahedra at ``df = delta_0`` (N_iso3 counts regular tetrahedra of edge delta_0/|grad f|).

Each layer is the section of the prism: points on its boundary curves (spacing ``a``, arcs
also within the chord tolerance) and an interior square lattice (offset by half a cell on
alternate layers) at least ``a / 2`` from the boundary, moved along the prism's axis onto the
level. A deterministic in-plane jitter (a few per cent of ``a``, from the seed) breaks the
cocircular ties of the lattice, so the Delaunay tetrahedra are unique; it keeps every point
on its level and boundary points on their curve.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass

import numpy as np

from ..tri.geometry.pslg import sample_parameters

__all__ = ["Layer", "level_values", "section_points", "column_roots", "JITTER"]

log = logging.getLogger(__name__)

#: in-plane jitter amplitude, x the layer's spacing
JITTER = 0.04
#: interior lattice points closer than this x spacing to the section boundary are dropped
BOUNDARY_GAP = 0.45
#: arcs whose boundary step is below this x the spacing get rings of graded points inside
RING_START = 0.7
#: growth of the point step from one ring to the next
RING_GROWTH = 1.35
#: lattice points closer than this x the spacing to a ring point are dropped
RING_CLEAR = 0.6


@dataclass
class Layer:
    """The points of one level: section coordinates ``q (n, 2)``, axis values ``s (n,)``
    (nan where the level does not cross the column), the level value and the spacing."""

    q: np.ndarray
    s: np.ndarray
    level: float
    spacing: float
    on_boundary: np.ndarray  # (n,) bool


def level_values(f_lo: float, f_hi: float, step: float) -> np.ndarray:
    """Levels from ``f_lo`` to ``f_hi`` inclusive, evenly spaced by at most ``step``."""
    n = max(1, int(math.ceil((f_hi - f_lo) / step * (1 - 1e-12))))
    lev = f_lo + (f_hi - f_lo) * np.arange(n + 1) / n
    lev[-1] = f_hi
    return lev


def section_points(section, spacing: float, phase: int, rng: np.random.Generator,
                   chord_tol: float) -> tuple[np.ndarray, np.ndarray]:
    """Points of one layer in the section: ``(q (n, 2), on_boundary (n,))``.

    Boundary curves are divided into ``ceil(length / spacing)`` equal parts (arcs into at
    least as many as the chord tolerance needs, see :func:`arc_count`); the interior is a
    square lattice of ``spacing``, shifted by half a cell when ``phase`` is odd.
    """
    curves = [c.curve for c in section.curves if c.kind in ("outer", "hole")]
    off, t = sample_parameters(curves, spacing, None)
    qs, offs, ts = [], [0], []
    for i, c in enumerate(curves):
        ti = t[off[i]:off[i + 1]][:-1]  # the end is the next curve's start
        n = len(ti)
        if hasattr(c, "radius"):
            # arcs: the same points in every layer where the chord tolerance sets the count
            # (a side triangle then spans one step), else at least 1.5 x that count (a side
            # triangle spans at most 1.5 steps); never jittered
            nc = arc_count(c, chord_tol)
            n = nc if n < 1.5 * nc else n
            ti = np.arange(n) / n
        elif n > 1:
            j = np.zeros(n)
            j[1:] = rng.uniform(-JITTER, JITTER, n - 1) / n
            ti = ti + j
        qs.append(c.point(ti))
        ts.append(np.r_[ti, 1.0])
        offs.append(offs[-1] + len(ti) + 1)
    off, t = np.array(offs), np.concatenate(ts) if ts else np.empty(0)
    qb = np.concatenate(qs) if qs else np.empty((0, 2))
    rings = _arc_rings(section, curves, off, t, spacing, rng)
    x0, y0, x1, y1 = section.bounds
    o = 0.5 * spacing * (phase % 2)
    gx = np.arange(x0 + o, x1, spacing)
    gy = np.arange(y0 + o, y1, spacing)
    g = np.stack(np.meshgrid(gx, gy, indexing="ij"), axis=-1).reshape(-1, 2)
    if len(g):
        keep = section.contains(g)
        g = g[keep]
        if len(g):
            d = section.distance_to_boundary(g)
            g = g[d >= BOUNDARY_GAP * spacing]
    if len(g) and len(rings):
        from scipy.spatial import cKDTree
        dr, _ = cKDTree(rings).query(g)
        g = g[dr >= RING_CLEAR * spacing]
    if len(g):
        g = g + rng.uniform(-JITTER, JITTER, g.shape) * spacing
        g = np.concatenate([rings, g])
    elif len(rings):
        g = rings
    else:
        # an interior point keeps the boundary points (on one circle per layer in a
        # cylinder: two layers' are cospherical) from forming flat Delaunay tetrahedra
        r = section.polygon().representative_point()
        g = np.array([[r.x, r.y]])
    q = np.concatenate([qb, g])
    return q, np.r_[np.ones(len(qb), bool), np.zeros(len(g), bool)]


def arc_count(arc, chord_tol: float) -> int:
    """The fewest equal chords of ``arc`` within ``chord_tol`` of it (at least one per 90
    degrees)."""
    sweep = abs(arc.theta1 - arc.theta0)
    c = min(max(1.0 - chord_tol / arc.radius, -1.0), 1.0)
    step = 2.0 * np.arccos(c)  # the angle of a chord with sagitta chord_tol
    return int(max(np.ceil(sweep / max(step, 1e-12) - 1e-9), np.ceil(sweep / (np.pi / 2))))


def _arc_rings(section, curves, off, t, spacing: float, rng) -> np.ndarray:
    """Points on curves parallel to the arcs whose chord-limited step ``b`` is much finer
    than ``spacing``: rings at growing distances with steps growing by :data:`RING_GROWTH`
    from ``b`` to ``spacing``, so that the tetrahedra grade from the curved face to the
    lattice instead of meeting it in slivers."""
    out = []
    for i, c in enumerate(curves):
        if not hasattr(c, "radius"):
            continue
        n = off[i + 1] - off[i] - 1
        b = c.length / max(n, 1)
        if b >= RING_START * spacing:
            continue
        mid = c.point(np.array([0.5]))[0]
        to_c = np.asarray(c.center) - mid
        eps = 1e-6 * c.radius
        inward = 1.0 if section.contains((mid + eps * to_c / np.linalg.norm(to_c))[None])[0] \
            else -1.0
        d, step, k = 0.0, b, 0
        while step < RING_START * spacing:
            d += 0.85 * step
            step = min(step * RING_GROWTH, spacing)
            r = c.radius - inward * d
            if r <= 0.5 * step:
                break
            sweep = abs(c.theta1 - c.theta0)
            m = max(1, int(np.ceil(sweep * r / step)))
            k += 1
            th = c.theta0 + (c.theta1 - c.theta0) * (np.arange(m) + 0.5 * (k % 2)) / m
            th = th + rng.uniform(-JITTER, JITTER, m) * (c.theta1 - c.theta0) / m
            q = np.column_stack([c.center[0] + r * np.cos(th), c.center[1] + r * np.sin(th)])
            ok = section.contains(q)
            q = q[ok]
            if len(q):
                q = q[section.distance_to_boundary(q) >= 0.6 * d]
            out.append(q)
    return np.concatenate(out) if out else np.empty((0, 2))


def column_roots(F, q: np.ndarray, s0: float, s1: float, level: float,
                 samples: int = 65, iters: int = 60) -> np.ndarray:
    """The first ``s`` in ``[s0, s1]`` with ``F(q, s) = level`` on each column ``q (n, 2)``
    (``F`` vectorised over points); nan where the column has no such point.

    A sign change of ``F - level`` on ``samples`` equal steps, then bisection.
    """
    n = len(q)
    if n == 0:
        return np.empty(0)
    ss = np.linspace(s0, s1, samples)
    vals = F(np.repeat(q, samples, axis=0), np.tile(ss, n)).reshape(n, samples) - level
    exact = vals == 0
    change = (vals[:, :-1] * vals[:, 1:] < 0)
    hit = exact[:, :-1] | change
    has = hit.any(axis=1) | exact[:, -1]
    first = np.argmax(hit, axis=1)
    out = np.full(n, np.nan)
    rows = np.flatnonzero(has)
    if not len(rows):
        return out
    first = first[rows]
    only_end = ~hit[rows].any(axis=1)
    lo = ss[first]
    hi = ss[np.minimum(first + 1, samples - 1)]
    flo = vals[rows, first]
    e0 = exact[rows, first]
    res = np.where(e0, lo, np.nan)
    todo = ~e0 & ~only_end
    res[only_end] = s1
    if todo.any():
        a, b, fa = lo[todo], hi[todo], flo[todo]
        qq = q[rows[todo]]
        for _ in range(iters):
            m = 0.5 * (a + b)
            fm = F(qq, m) - level
            left = np.sign(fm) == np.sign(fa)
            a = np.where(left, m, a)
            fa = np.where(left, fm, fa)
            b = np.where(left, b, m)
            if (b - a).max() <= 1e-15 * max(1.0, abs(s1), abs(s0)):
                break
        res[todo] = 0.5 * (a + b)
    out[rows] = res
    return out
