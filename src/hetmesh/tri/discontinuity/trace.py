"""Stage 1, trace: the subregion id on a grid, its switch points bisected, linked cell by
cell and chained into polylines."""

from __future__ import annotations

import math

import numpy as np

from ...errors import MeshingError
from ...topology import unique
from .regions import BISECT, GRID_CELLS, Discontinuity

__all__ = ["trace_discontinuities", "Untraceable"]


def _bisect(field, a: np.ndarray, b: np.ndarray, la: np.ndarray, steps: int = BISECT):
    """Switch points on segments ``a -> b`` (arrays ``(K, 2)``) where the region leaves
    ``la``; returns the points (the last point still in ``la`` and its neighbour agree to
    2^-steps of the segment)."""
    lo, hi = a.copy(), b.copy()
    for _ in range(steps):
        mid = 0.5 * (lo + hi)
        same = field.region(mid) == la
        lo = np.where(same[:, None], mid, lo)
        hi = np.where(same[:, None], hi, mid)
    return 0.5 * (lo + hi)


def _crossings(field, xs: np.ndarray, ys: np.ndarray, lab: np.ndarray):
    """Switch points on the edges of the grid ``xs`` x ``ys`` with labels ``lab``
    ``(len(ys), len(xs))``: ``(points (K, 2), sorted label pairs (K, 2), horizontal ids,
    vertical ids)``, the ids ``-1`` on edges without a switch."""
    ny, nx = len(ys) - 1, len(xs) - 1
    hid = np.full((ny + 1, nx), -1, np.int64)
    vid = np.full((ny, nx + 1), -1, np.int64)
    pts, pair, count = [], [], 0
    for ids, la, lb, (aj, ai), (bj, bi) in (
            (hid, lab[:, :-1], lab[:, 1:], (0, 0), (0, 1)),
            (vid, lab[:-1, :], lab[1:, :], (0, 0), (1, 0))):
        jj, ii = np.nonzero(la != lb)
        if len(jj) == 0:
            continue
        pa = np.column_stack([xs[ii + ai], ys[jj + aj]])
        pb = np.column_stack([xs[ii + bi], ys[jj + bj]])
        ids[jj, ii] = count + np.arange(len(jj))
        count += len(jj)
        pts.append(_bisect(field, pa, pb, la[jj, ii]))
        pair.append(np.sort(np.column_stack([la[jj, ii], lb[jj, ii]]), axis=1))
    if not pts:
        return np.zeros((0, 2)), np.zeros((0, 2), np.int64), hid, vid
    return np.concatenate(pts), np.concatenate(pair), hid, vid


class Untraceable(MeshingError):
    """The subregions cannot be traced: ``point`` (a coordinate of the trouble), ``pair``
    (the two subregions meeting there) and ``reason`` (the rest of a message)."""

    def __init__(self, point, pair, reason: str):
        super().__init__(reason)
        self.point, self.pair, self.reason = np.asarray(point, float), pair, reason


def _check_resolved(field, xs: np.ndarray, ys: np.ndarray, lab: np.ndarray, inside,
                    max_crossings: int | None) -> None:
    """Raise :class:`Untraceable` if, on the part of the grid inside the domain
    (``inside(points) -> bool``), the subregion boundaries cross more than
    ``max_crossings`` grid edges, or a cell's centre lies in another subregion than its
    four corners (a piece narrower than the grid, which the tracing would miss)."""
    gx, gy = np.meshgrid(xs, ys)
    ins = np.asarray(inside(np.column_stack([gx.ravel(), gy.ravel()])),
                     dtype=bool).reshape(lab.shape)
    h = float(xs[1] - xs[0])
    if max_crossings is not None:
        hor = (lab[:, :-1] != lab[:, 1:]) & (ins[:, :-1] | ins[:, 1:])
        ver = (lab[:-1] != lab[1:]) & (ins[:-1] | ins[1:])
        n = int(hor.sum() + ver.sum())
        if n > max_crossings:  # name the first crossed edge (a horizontal one if any)
            dj, di = (0, 1) if hor.any() else (1, 0)
            j, i = np.argwhere(hor if hor.any() else ver)[0]
            pair = (int(lab[j, i]), int(lab[j + dj, i + di]))
            at = (xs[i] + 0.5 * h * di, ys[j] + 0.5 * h * dj)
            raise Untraceable(at, pair, f"its curves cross {n:,} edges of the "
                               f"{len(xs) - 1} x {len(ys) - 1} tracing grid inside the domain "
                               f"(at most {max_crossings:,}): too many pieces to mesh")
    c00 = lab[:-1, :-1]
    same = ((c00 == lab[:-1, 1:]) & (c00 == lab[1:, :-1]) & (c00 == lab[1:, 1:])
            & ins[:-1, :-1] & ins[:-1, 1:] & ins[1:, :-1] & ins[1:, 1:])
    jj, ii = np.nonzero(same)
    if not len(jj):
        return
    centre = np.column_stack([xs[ii] + 0.5 * h, ys[jj] + 0.5 * h])
    cen = np.asarray(field.region(centre), dtype=np.int64)
    odd = np.flatnonzero(cen != c00[jj, ii])
    if len(odd):
        k = odd[0]
        raise Untraceable(centre[k], (int(c00[jj[k], ii[k]]), int(cen[k])),
                           f"a piece narrower than the tracing grid's spacing {h:.3g} lies "
                           f"there, which the grid cannot follow")


def _labels(field, xs: np.ndarray, ys: np.ndarray) -> np.ndarray:
    gx, gy = np.meshgrid(xs, ys, indexing="xy")
    return np.asarray(field.region(np.column_stack([gx.ravel(), gy.ravel()])),
                      dtype=np.int64).reshape(len(ys), len(xs))


def _junction(field, center: np.ndarray, size: float, tol: float) -> np.ndarray:
    """The point where three or more subregions meet, near ``center``.

    In a shrinking window: the switch points of a 16 x 16 grid, a straight line fitted to
    those of every pair of subregions, and their least-squares intersection. Near the
    junction the curves are straight to second order, so each window (a quarter of the
    last) gains about two digits.
    """
    c = np.asarray(center, dtype=float)
    w = float(size)
    while w > tol:
        s = np.linspace(-0.5 * w, 0.5 * w, 17)
        xs, ys = c[0] + s, c[1] + s
        pts, pairs, _, _ = _crossings(field, xs, ys, _labels(field, xs, ys))
        A, rhs = np.zeros((2, 2)), np.zeros(2)
        for pr in unique(pairs, axis=0):
            q = pts[(pairs == pr).all(axis=1)]
            if len(q) < 2:
                continue
            m = q.mean(axis=0)
            _, _, vt = np.linalg.svd(q - m)
            n = vt[1]  # the line's normal
            A += np.outer(n, n)
            rhs += np.outer(n, n) @ m
        if np.linalg.cond(A) < 1e8:
            x = np.linalg.solve(A, rhs)
            c = np.clip(x, c - 0.5 * w, c + 0.5 * w)
        w /= 4.0
    return c


def trace_discontinuities(field, bounds, *, cells: int = GRID_CELLS,
                          tol: float | None = None, inside=None,
                          max_crossings: int | None = None) -> list[Discontinuity]:
    """Every curve in the box ``bounds = (x0, y0, x1, y1)`` where ``field.region`` changes,
    as ordered polylines (see the module docstring, step 1).

    The grid resolves features larger than the box's longer side / ``cells``; a subregion
    thinner than a grid cell everywhere can be missed. With ``inside`` (a callable
    ``points -> bool``, the domain), that is checked first on the grid cells inside: a
    cell whose centre lies in another subregion than its corners, or more than
    ``max_crossings`` grid edges crossed, raise an exception (a
    :class:`~hetmesh.errors.MeshingError` with the attributes ``point``, ``pair`` and
    ``reason``; :func:`embed_discontinuities` turns it into a
    :class:`~hetmesh.errors.MaterialError` naming the jump).
    """
    x0, y0, x1, y1 = (float(v) for v in bounds)
    span = max(x1 - x0, y1 - y0)
    pad = 0.02 * span
    h = (span + 2 * pad) / cells
    nx = int(math.ceil((x1 - x0 + 2 * pad) / h))
    ny = int(math.ceil((y1 - y0 + 2 * pad) / h))
    xs = x0 - pad + h * np.arange(nx + 1)
    ys = y0 - pad + h * np.arange(ny + 1)
    lab = _labels(field, xs, ys)
    if inside is not None:
        _check_resolved(field, xs, ys, lab, inside, max_crossings)
    tol = 1e-9 * span if tol is None else tol

    P, pairs, hid, vid = _crossings(field, xs, ys, lab)
    if len(P) == 0:
        return []

    # link crossings cell by cell
    c00, c10, c01, c11 = lab[:-1, :-1], lab[:-1, 1:], lab[1:, :-1], lab[1:, 1:]
    nlab = (1 + (c10 != c00) + ((c01 != c00) & (c01 != c10))
            + ((c11 != c00) & (c11 != c10) & (c11 != c01)))
    links: list[tuple[int, int]] = []
    junction_cells = np.argwhere(nlab >= 3)
    jnodes: dict[tuple[int, int], int] = {}
    extra: list[np.ndarray] = []
    groups = _group_cells(junction_cells)
    for group in groups:
        gj, gi = group[:, 0], group[:, 1]
        # one junction per group of touching junction cells, refined in its bounding square
        size = h * (max(gj.max() - gj.min(), gi.max() - gi.min()) + 1)
        corner = np.array([xs[gi.min()], ys[gj.min()]])
        J = _junction(field, corner + 0.5 * size, 2.0 * size, tol)
        k = len(P) + len(extra)
        extra.append(J)
        for j, i in group:
            jnodes[(int(j), int(i))] = k
    for j, i in np.argwhere(nlab >= 2):
        edges = [hid[j, i], vid[j, i + 1], hid[j + 1, i], vid[j, i]]  # bottom right top left
        cr = [e for e in edges if e >= 0]
        key = (int(j), int(i))
        if key in jnodes:
            J = jnodes[key]
            for e, (dj, di) in zip(edges, ((-1, 0), (0, 1), (1, 0), (0, -1))):
                if e >= 0 and jnodes.get((int(j) + dj, int(i) + di)) != J:
                    links.append((int(e), J))
            continue
        if len(cr) == 2:
            links.append((int(cr[0]), int(cr[1])))
        elif len(cr) == 4:  # saddle: the centre decides which corners are connected
            cen = field.region(np.array([[xs[i] + 0.5 * h, ys[j] + 0.5 * h]]))[0]
            b, r, t, lf = (int(e) for e in edges)
            links += [(b, r), (t, lf)] if cen == c00[j, i] else [(b, lf), (t, r)]
    if extra:
        P = np.vstack([P, np.array(extra)])
        pairs = np.vstack([pairs, np.full((len(extra), 2), -1)])
    return [Discontinuity(P[c], _pair_of(pairs[c]), closed) for c, closed in
            _chains(len(P), links)]


def _group_cells(cells: np.ndarray) -> list[np.ndarray]:
    """Groups of junction cells touching by an edge or a corner."""
    left = {tuple(c) for c in cells.tolist()}
    out = []
    while left:
        stack = [left.pop()]
        group = []
        while stack:
            j, i = stack.pop()
            group.append((j, i))
            for dj in (-1, 0, 1):
                for di in (-1, 0, 1):
                    n = (j + dj, i + di)
                    if n in left:
                        left.remove(n)
                        stack.append(n)
        out.append(np.array(sorted(group)))
    return sorted(out, key=lambda g: tuple(g[0]))


def _pair_of(pairs: np.ndarray) -> tuple[int, int]:
    ok = pairs[pairs[:, 0] >= 0]
    if len(ok) == 0:
        return (-1, -1)
    vals, counts = unique(ok, axis=0, return_counts=True)
    a, b = vals[np.argmax(counts)]
    return int(a), int(b)


def _chains(n: int, links: list[tuple[int, int]]) -> list[tuple[list[int], bool]]:
    """Maximal paths of the link graph between nodes of degree != 2, then the cycles."""
    adj: list[list[int]] = [[] for _ in range(n)]
    for a, b in links:
        if a != b:
            adj[a].append(b)
            adj[b].append(a)
    used: set[tuple[int, int]] = set()
    out = []

    def walk(start, nxt):
        path = [start, nxt]
        used.add((min(start, nxt), max(start, nxt)))
        prev, cur = start, nxt
        while len(adj[cur]) == 2:
            a, b = adj[cur]
            step = b if a == prev else a
            key = (min(cur, step), max(cur, step))
            if key in used:
                break
            used.add(key)
            path.append(step)
            prev, cur = cur, step
        return path

    for v in range(n):
        if len(adj[v]) != 2:
            for w in adj[v]:
                if (min(v, w), max(v, w)) not in used:
                    out.append((walk(v, w), False))
    for v in range(n):
        for w in adj[v]:
            if (min(v, w), max(v, w)) not in used:
                path = walk(v, w)
                out.append((path, path[0] == path[-1]))
    return out
