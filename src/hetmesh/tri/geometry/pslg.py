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

import numpy as np

from hetmesh.errors import GeometryError

from .curves import SizeLike, sample_parameters
from .domain import Domain

__all__ = ["pslg_from_parameters", "PSLG", "build_pslg"]


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


def build_pslg(domain: Domain, size: SizeLike, chord_tol: float | None = None, *,
               nearest: bool = False) -> PSLG:
    """Sample every curve of ``domain`` into a PSLG.

    Parameters
    ----------
    domain : Domain
        A validated domain.
    size : float or callable ``(N, 2) -> (N,)``
        Target edge length along the curves (see :func:`.curves.sample_parameters`).
    chord_tol : float, optional
        Largest distance between an arc and its chords; ``1e-3 * diameter`` by default.
    nearest : bool
        Round each curve's interval count to the nearest, not up
        (:func:`.curves.sample_parameters`).

    Returns
    -------
    PSLG
    """
    if chord_tol is None:
        chord_tol = 1e-3 * domain.diameter
    offsets, t = sample_parameters(domain.curve_batch, size, chord_tol, nearest=nearest)
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
    coords, start_id, end_id, _ = domain.junctions
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
