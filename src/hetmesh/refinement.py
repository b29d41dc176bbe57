"""The pieces of the refinement loop that every kernel shares (triangles and tetrahedra).

The loop of a kernel (:func:`hetmesh.tri.refine.repair` in 2D) evaluates delta(T) of every
element (Eqs. 14-15, :func:`cell_delta`), marks the violators (delta(T) >= delta_0, Eq. 1),
splits each violator's edge with the largest composition jump
(:func:`largest_jump_edges`, the paper's Eq. 13 made concrete), re-triangulates, and stops
at delta_max < delta_0; :func:`check_budget` and :func:`check_progress` keep it finite.
Local re-triangulations keep most elements, whose values :func:`carried` and :func:`carry`
take over instead of recomputing them.
"""

from __future__ import annotations

import numpy as np

from .delta import element_delta
from .errors import BudgetError, MeshingError
from .material.field import element_subregions, has_subregions, thread_safe
from .mesh import edge_keys
from .metrics import TET_EDGES
from .parallel import block_concat
from .topology import unique

__all__ = ["SIMPLEX_EDGES", "cell_delta", "composition_at", "carried", "carry",
           "largest_jump_edges", "edge_lengths", "check_budget", "check_progress",
           "round_record"]

#: the vertex pairs of a simplex's edges by its vertex count: a triangle's sides opposite
#: vertices 0, 1, 2 (the column order of :func:`hetmesh.metrics.side_lengths`), a
#: tetrahedron's :data:`hetmesh.metrics.TET_EDGES`
SIMPLEX_EDGES = {3: ((1, 2), (2, 0), (0, 1)), 4: TET_EDGES}


def composition_at(field, pts: np.ndarray) -> np.ndarray:
    """The field's compositions at ``pts``, by blocks of points (pointwise; in parallel
    threads when the field is :func:`~hetmesh.material.field.thread_safe`)."""
    return block_concat(lambda s: field.composition(pts[s]), len(pts),
                        serial=not thread_safe(field))



def cell_delta(field, points: np.ndarray, cells: np.ndarray, sampling: str,
               composition: np.ndarray, threshold: float) -> np.ndarray:
    """delta(T) of every element (:func:`hetmesh.delta.element_delta`), each element of
    a piecewise field evaluated in its own subregion (the paper's Sec. 3.3)."""
    regions = element_subregions(field, points, cells) if has_subregions(field) else None
    return element_delta(field, points, cells, sampling, composition, regions=regions,
                         threshold=threshold)


def carried(state, lin) -> np.ndarray | None:
    """For every triangle of the current triangulation (lineage ``lin``,
    :func:`hetmesh.tri.workset.lineage`), its position in the triangulation ``state`` was
    evaluated on (``(base, rows, ...)``), or -1 where it is new; None if the two do not
    descend from one full rebuild."""
    if state is None or lin is None or lin[0] is not state[0]:
        return None
    rows = state[1]
    pos = np.full(len(lin[0]), -1, np.int64)
    ok = rows >= 0
    pos[rows[ok]] = np.flatnonzero(ok)
    src = np.full(len(lin[1]), -1, np.int64)
    have = lin[1] >= 0
    src[have] = pos[lin[1][have]]
    return src


def carry(src: np.ndarray, previous: tuple, compute) -> tuple:
    """Per-triangle arrays: ``previous[k][src]`` where ``src >= 0`` (unchanged triangles),
    ``compute(rows)[k]`` for the other rows."""
    old = np.flatnonzero(src >= 0)
    new = np.flatnonzero(src < 0)
    fresh = compute(new)
    out = []
    for a, f in zip(previous, fresh):
        o = np.empty(len(src), a.dtype)
        o[old] = a[src[old]]
        o[new] = f
        out.append(o)
    return tuple(out)



def edge_lengths(points: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """Lengths ``(M, E)`` of every element's edges, in the order of :data:`SIMPLEX_EDGES`."""
    pairs = SIMPLEX_EDGES[cells.shape[1]]
    return np.stack([np.linalg.norm(points[cells[:, i]] - points[cells[:, j]], axis=1)
                     for i, j in pairs], axis=1)


def largest_jump_edges(cells: np.ndarray, composition: np.ndarray, lengths: np.ndarray,
                       longest: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The edge of every element in ``cells (k, d + 1)`` with the largest composition jump
    (max-norm over the constituents, Eq. 15), once per edge: endpoint ids ``(a, b)``.

    ``lengths (k, E)`` are the elements' edge lengths (:func:`edge_lengths`; in 2D
    :func:`hetmesh.metrics.side_lengths`, the same order): among equal jumps the longest
    edge wins. Where ``longest (k,)`` is set, the longest edge is taken whatever its jump
    (an element over the largest size). Splitting these edges at their midpoints is the
    refinement of violators: a continuous field's jump along an edge shrinks as it is
    halved, so the loop ends.

    >>> comp = np.array([0.0, 0.1, 0.9, 0.95])
    >>> a, b = largest_jump_edges(np.array([[0, 1, 2]]), comp, np.ones((1, 3)))
    >>> sorted([int(a[0]), int(b[0])])
    [0, 2]
    """
    pairs = SIMPLEX_EDGES[cells.shape[1]]
    cv = composition[cells] if composition.ndim == 2 else composition[cells][..., None]
    jumps = np.stack([np.abs(cv[:, i] - cv[:, j]).max(axis=1) for i, j in pairs], axis=1)
    kk = (jumps + 1e-9 * lengths / lengths.max()).argmax(axis=1)
    if longest is not None:
        kk = np.where(longest, lengths.argmax(axis=1), kk)
    first_v = np.array([i for i, _ in pairs])[kk]
    second_v = np.array([j for _, j in pairs])[kk]
    rows = np.arange(len(cells))
    a, b = cells[rows, first_v], cells[rows, second_v]
    _, first = unique(edge_keys(a, b), return_index=True)
    return a[first], b[first]


def check_budget(n_elements: int, max_elements: int) -> None:
    """:class:`~hetmesh.errors.BudgetError` once the mesh has more elements than the budget."""
    if n_elements > max_elements:
        raise BudgetError(f"refinement exceeded the element budget ({n_elements} > "
                          f"{max_elements} elements); raise --max-elements or the threshold")


def check_progress(n_before: int, n_after: int, rnd: int, n_violators: int, n_bad: int,
                   threshold: float) -> None:
    """:class:`~hetmesh.errors.MeshingError` when a round added no node: the loop stalled."""
    if n_after == n_before:
        raise MeshingError(f"refinement stalled in round {rnd} with {n_violators} "
                           f"elements at delta >= {threshold:g} and {n_bad} below the "
                           "quality floor")


def round_record(rnd: int, n_elements: int, n_points: int, delta: np.ndarray,
                 viol: np.ndarray, bad: np.ndarray) -> dict:
    """One round of the loop as ``Result.history`` holds it."""
    return {"round": rnd, "elements": int(n_elements), "points": int(n_points),
            "delta_max": float(delta.max()), "violators": int(viol.sum()),
            "bad_quality": int(bad.sum())}
