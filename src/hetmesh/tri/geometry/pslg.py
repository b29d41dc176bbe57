"""The planar straight-line graph (PSLG) of a domain: its curves sampled into edges.

Fixed vertices (curve end points, shared by consecutive curves, and named points) come first,
then the sampled interior points of every curve in :attr:`Domain.curves` order. The edges of a
curve are contiguous and ordered from its start to its end.

Examples
--------
>>> from hetmesh.tri.geometry import Loop, make_domain
>>> d = make_domain(Loop.polygon([(0, 0), (1, 0), (1, 1), (0, 1)]))
>>> g = build_pslg(d, 0.5, 1e-3)
>>> len(g.vertices), len(g.edges), g.vertex_curve[:4].tolist()
(8, 8, [-1, -1, -1, -1])
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Callable, Sequence

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from hetmesh.errors import GeometryError

from .curves import Curve, CurveBatch, SizeLike, fmt_num, fmt_point

if TYPE_CHECKING:  # domain.py imports this module
    from .domain import Domain

__all__ = ["pslg_from_parameters", "PSLG", "build_pslg", "fixed_vertices", "sample_parameters"]

MAX_SAMPLES = 50_000_000


def _frozen(a, dtype) -> np.ndarray:
    a = np.ascontiguousarray(a, dtype=dtype)
    a.flags.writeable = False
    return a


@dataclass(frozen=True, eq=False)
class PSLG:
    """Vertices and constrained edges of a sampled domain.

    Attributes
    ----------
    vertices : (N, 2) float64
    edges : (E, 2) int32
        Consecutive vertices along a curve, oriented like the curve.
    edge_curve : (E,) int32
        Index into ``domain.curves`` of every edge (its marker minus one).
    vertex_curve : (N,) int32
        The curve a sliding vertex lies on; -1 for fixed vertices (curve ends, named points).
    vertex_t : (N,) float64
        The vertex's parameter on ``vertex_curve``; nan for fixed vertices.
    """

    vertices: np.ndarray
    edges: np.ndarray
    edge_curve: np.ndarray
    vertex_curve: np.ndarray
    vertex_t: np.ndarray

    def __post_init__(self) -> None:
        for name, dtype in (("vertices", np.float64), ("edges", np.int32),
                            ("edge_curve", np.int32), ("vertex_curve", np.int32),
                            ("vertex_t", np.float64)):
            object.__setattr__(self, name, _frozen(getattr(self, name), dtype))
        object.__setattr__(self, "edges", self.edges.reshape(-1, 2))
        if self.vertices.ndim != 2 or self.vertices.shape[1] != 2:
            raise GeometryError(f"PSLG vertices must have shape (N, 2), got "
                                f"{self.vertices.shape}")

    @property
    def fixed(self) -> np.ndarray:
        """Boolean mask ``(N,)`` of fixed vertices."""
        return self.vertex_curve < 0

    def curve_vertices(self, i: int) -> np.ndarray:
        """Vertex indices along curve ``i``, from its start to its end (both included)."""
        e = self.edges[self.edge_curve == i]
        return np.r_[e[:, 0], e[-1:, 1]]


def fixed_vertices(domain: Domain) -> tuple[np.ndarray, np.ndarray, np.ndarray, dict[str, int]]:
    """The fixed vertices of a domain's PSLG, merged within the domain's tolerance.

    Returns ``coords (K, 2)``, ``start_id (C,)``, ``end_id (C,)`` (fixed vertex of every
    curve's ends) and ``point_id`` (named point -> fixed vertex). Between two curves the
    vertex is a segment's exact end point where there is one.
    """
    b = domain.curve_batch
    coords, start_id, end_id = [], np.empty(len(b), np.int64), np.empty(len(b), np.int64)
    k = 0
    for j in range(len(domain._owners)):
        i0, i1 = domain._slices[j], domain._slices[j + 1]
        n = i1 - i0
        seg, p0, p1 = ~b.is_arc[i0:i1], b.p0[i0:i1], b.p1[i0:i1]
        prev = np.arange(n) - 1
        J = np.where(seg[prev, None], p1[prev], p0)
        if not domain._closed[j]:
            J[0] = p0[0]
            J = np.vstack([J, p1[-1:]])
        ids = k + np.arange(len(J))
        start_id[i0:i1] = ids[:n]
        end_id[i0:i1] = np.roll(ids, -1) if domain._closed[j] else ids[1:]
        coords.append(J)
        k += len(J)
    names = list(domain.points)
    coords.append(np.array([domain.points[q] for q in names]).reshape(-1, 2))
    coords = np.vstack(coords)
    pairs = cKDTree(coords).query_pairs(domain._tol, output_type="ndarray")
    m = len(coords)
    graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(m, m))
    _, labels = connected_components(graph, directed=False)
    _, first = np.unique(labels, return_index=True)  # first vertex of every label
    order = np.argsort(first)
    rank = np.empty_like(order)
    rank[order] = np.arange(len(order))
    new = rank[labels]
    point_id = {q: int(new[k + i]) for i, q in enumerate(names)}
    return coords[first[order]], new[start_id], new[end_id], point_id


def build_pslg(domain: Domain, size: SizeLike, chord_tol: float | None = None) -> PSLG:
    """Sample every curve of ``domain`` into a PSLG.

    Parameters
    ----------
    domain : Domain
        A validated domain.
    size : float or callable ``(N, 2) -> (N,)``
        Target edge length along the curves (see :func:`sample_parameters`).
    chord_tol : float, optional
        Largest distance between an arc and its chords; ``1e-3 * diameter`` by default.

    Returns
    -------
    PSLG
    """
    if chord_tol is None:
        chord_tol = 1e-3 * domain.diameter
    offsets, t = sample_parameters(domain.curve_batch, size, chord_tol)
    return pslg_from_parameters(domain, offsets, t)


def pslg_from_parameters(domain: Domain, offsets: np.ndarray, t: np.ndarray) -> PSLG:
    """The PSLG whose curve ``i`` is sampled at ``t[offsets[i]:offsets[i + 1]]``.

    Every curve's parameters must increase from 0 to 1 (both included); curve end points and
    named points become the shared fixed vertices. Lets a caller choose the samples itself
    (e.g. where iso-composition rows cross the boundary) and still get the same PSLG layout
    as :func:`build_pslg`.
    """
    offsets = np.asarray(offsets, dtype=np.int64)
    t = np.asarray(t, dtype=np.float64)
    coords, start_id, end_id, _ = domain._junctions  # fixed_vertices(domain), cached
    K = len(coords)
    b = domain.curve_batch
    counts = np.diff(offsets)
    idx = np.repeat(np.arange(len(b), dtype=np.int64), counts)
    inner = np.ones(len(t), dtype=bool)
    inner[offsets[:-1]] = False
    inner[offsets[1:] - 1] = False
    # vertex id of every sample along its curve: fixed ends, then new interior vertices
    vid = np.empty(len(t), dtype=np.int64)
    vid[inner] = K + np.arange(int(inner.sum()))
    vid[offsets[:-1]] = start_id
    vid[offsets[1:] - 1] = end_id
    last = np.zeros(len(t), dtype=bool)
    last[offsets[1:] - 1] = True
    e_from = np.flatnonzero(~last)
    return PSLG(
        vertices=np.vstack([coords, b.points(idx[inner], t[inner])]),
        edges=np.c_[vid[e_from], vid[e_from + 1]],
        edge_curve=idx[e_from],
        vertex_curve=np.r_[np.full(K, -1), idx[inner]],
        vertex_t=np.r_[np.full(K, np.nan), t[inner]],
    )


# ----------------------------------------------------------------------------- sampling
def _eval_size(size: Callable, pts: np.ndarray) -> np.ndarray:
    h = np.broadcast_to(np.asarray(size(pts), dtype=np.float64), (len(pts),))
    bad = ~(h > 0)  # also catches nan
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise GeometryError(f"size function returned {fmt_num(h[i])} at {fmt_point(pts[i])}; "
                            f"sizes must be positive")
    return h


def _check_count(n: np.ndarray) -> None:
    if n.sum() > MAX_SAMPLES:
        raise GeometryError(f"sampling the curves would need {int(n.sum())} points "
                            f"(more than {MAX_SAMPLES}); increase the size")


def sample_parameters(curves: Sequence[Curve] | CurveBatch, size: SizeLike,
                      chord_tol: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Parameters of points spaced by the local target edge length along many curves.

    The count of intervals on a curve is ``ceil(∫ 1/h ds)`` (at least one; for arcs at least
    one per 90 degrees and three for a full circle), with ``h = min(size, max_step)`` where
    ``max_step`` keeps the sagitta of an arc's chords below ``chord_tol``. Points sit at equal
    increments of that integral, computed on a fine sub-sampling (at least 4 per interval).

    Parameters
    ----------
    curves : sequence of Segment / Arc, or a CurveBatch
    size : float or callable ``(N, 2) -> (N,)``
        Target edge length (``inf`` means no limit).
    chord_tol : float, optional
        Largest distance between an arc and its chords.

    Returns
    -------
    offsets : (C + 1,) int64
        Curve ``i`` owns ``t[offsets[i]:offsets[i + 1]]``.
    t : (sum,) float64
        Increasing from exactly 0 to exactly 1 on every curve.

    Examples
    --------
    >>> from hetmesh.tri.geometry import Segment
    >>> off, t = sample_parameters([Segment((0, 0), (1, 0))], 0.25)
    >>> off.tolist(), t.tolist()
    ([0, 5], [0.0, 0.25, 0.5, 0.75, 1.0])
    """
    batch = curves if isinstance(curves, CurveBatch) else CurveBatch.from_curves(curves)
    if chord_tol is not None and not chord_tol > 0:
        raise GeometryError(f"chord tolerance must be positive, got {chord_tol!r}")
    C = len(batch)
    L = batch.length
    cap = batch.max_step(chord_tol)
    nmin = batch.min_intervals()
    if C == 0:
        return np.zeros(1, dtype=np.int64), np.zeros(0)
    if not callable(size):
        h = float(size)
        if not h > 0:
            raise GeometryError(f"size must be positive, got {size!r}")
        x = L / np.minimum(h, cap)
        n = np.maximum(nmin, np.ceil(x * (1 - 1e-12))).astype(np.int64)
        _check_count(n)
        offsets = np.r_[0, np.cumsum(n + 1)]
        idx = np.repeat(np.arange(C), n + 1)
        k = np.arange(offsets[-1]) - offsets[idx]
        return offsets, k / n[idx]
    m = np.full(C, 16, dtype=np.int64)
    for _ in range(5):
        idx, t, first = _ragged(m)
        inv = 1.0 / np.minimum(_eval_size(size, batch.points(idx, t)), cap[idx])
        same = idx[1:] == idx[:-1]
        w = np.where(same, 0.5 * (inv[1:] + inv[:-1]) * (L / m)[idx[:-1]], 0.0)
        F = np.r_[0.0, np.cumsum(w)]
        total = F[first + m] - F[first]
        n = np.maximum(nmin, np.ceil(total * (1 - 1e-12))).astype(np.int64)
        _check_count(n)
        if np.all(m >= 4 * n):
            break
        m = np.maximum(m, 4 * n)
    # normalised cumulative integral G in [0, 1] per curve (tiny linear term: strictly increasing)
    Fl = F - F[first][idx]
    eps = np.where(total > 0, 1e-9 * total, 1.0)
    G = (Fl + eps[idx] * t) / (total + eps)[idx]
    G[first + m] = 1.0
    key = idx + G
    u = idx + t
    offsets = np.r_[0, np.cumsum(n + 1)]
    jdx = np.repeat(np.arange(C), n + 1)
    k = np.arange(offsets[-1]) - offsets[jdx]
    out = np.interp(jdx + k / n[jdx], key, u) - jdx
    out[offsets[:-1]] = 0.0
    out[offsets[1:] - 1] = 1.0
    return offsets, np.clip(out, 0.0, 1.0)


def _ragged(m: np.ndarray):
    """Curve index, uniform parameter and first position of ``m + 1`` samples per curve."""
    first = np.r_[0, np.cumsum(m + 1)[:-1]]
    idx = np.repeat(np.arange(len(m)), m + 1)
    k = np.arange(int((m + 1).sum())) - first[idx]
    return idx, k / m[idx], first
