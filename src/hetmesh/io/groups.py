"""Named groups of a mesh as every export format writes them: one group per name.

A model curve split by a material discontinuity or an interface keeps its name on every
piece, and the curves of a hole or an interface without names of their own carry the hole's
or the interface's name, so several edge markers may share a name. Solvers address
boundaries by name: every format writes **one** group per name (a Gmsh physical curve
holding several curves, one Abaqus ``*NSET``/``*SURFACE``, one dolfinx facet tag) whose
members are all the edges of all the markers of that name.

Pure numpy; shared by the Gmsh, Abaqus and XDMF writers.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from ..topology import unique

if TYPE_CHECKING:  # the writers take any mesh with Mesh's attributes
    from ..mesh import Mesh

__all__ = ["CurveGroup", "curve_groups", "curve_ends", "point_entities", "node_entities"]


@dataclass(frozen=True)
class CurveGroup:
    """The edge markers sharing one name.

    Attributes
    ----------
    name : str
        ``mesh.marker_names[m]``, or ``marker_<m>`` for an unnamed marker.
    tag : int
        The group's number in the files: its smallest marker (markers are distinct, so are
        tags).
    markers : tuple of int
        The markers of the group, ascending.
    """

    name: str
    tag: int
    markers: tuple[int, ...]


def curve_groups(mesh: Mesh) -> list[CurveGroup]:
    """One :class:`CurveGroup` per name among the markers of ``mesh.edges``, by tag.

    >>> from hetmesh.mesh import Mesh
    >>> m = Mesh([[0, 0], [1, 0], [0, 1]], [[0, 1, 2]], facets=[[0, 1], [1, 2], [2, 0]],
    ...          facet_markers=[3, 5, 4], marker_names={3: "a", 4: "b", 5: "a"})
    >>> [(g.name, g.tag, g.markers) for g in curve_groups(m)]
    [('a', 3, (3, 5)), ('b', 4, (4,))]
    """
    groups: dict[str, list[int]] = {}
    for m in unique(mesh.edge_markers).tolist():
        groups.setdefault(mesh.marker_names.get(int(m), f"marker_{m}"), []).append(int(m))
    out = [CurveGroup(name, min(ms), tuple(sorted(ms))) for name, ms in groups.items()]
    return sorted(out, key=lambda g: g.tag)


def curve_ends(mesh: Mesh) -> dict[int, tuple[int, int] | None]:
    """The end nodes of each marker's chain of edges: ``{marker: (first, last)}``, None for
    a closed chain. The first end is the lower node id when the chain's direction cannot
    be told (it never can from the edges alone)."""
    out: dict[int, tuple[int, int] | None] = {}
    for m in unique(mesh.edge_markers).tolist():
        e = mesh.edges[mesh.edge_markers == m]
        nodes, count = unique(e.ravel(), return_counts=True)
        ends = nodes[count == 1]
        out[int(m)] = (int(ends[0]), int(ends[-1])) if len(ends) else None
    return out


def point_entities(mesh: Mesh) -> np.ndarray:
    """The nodes that are geometric points: every end of a marker's chain and every named
    point, sorted (a Gmsh point entity each, tag = position + 1)."""
    ends = [n for pair in curve_ends(mesh).values() if pair for n in pair]
    named = list(mesh.named_points.values())
    return unique(np.array(ends + named, np.int64))


def node_entities(mesh: Mesh, points: np.ndarray, regions: np.ndarray
                  ) -> tuple[np.ndarray, np.ndarray]:
    """The geometric entity of every node: ``(dim (N,), tag (N,))``.

    A node at a point entity (``points``) is on that point (dim 0, tag = position + 1);
    else a node of a marker's edges is on that curve (dim 1, tag = the marker); else it is
    inside the surface of the smallest region (sorted ``regions``; tag = position + 1) of
    the triangles around it. A node of no triangle and no edge goes to surface 1.
    """
    n = mesh.n_points
    dim = np.full(n, 2, np.int32)
    tag = np.full(n, np.iinfo(np.int32).max, np.int64)
    t = mesh.triangles
    if len(t):
        surf = np.searchsorted(regions, mesh.regions).astype(np.int64) + 1
        for j in range(3):
            np.minimum.at(tag, t[:, j], surf)
    tag[tag == np.iinfo(np.int32).max] = 1
    if len(mesh.edges):
        for j in range(2):
            tag[mesh.edges[:, j]] = mesh.edge_markers
            dim[mesh.edges[:, j]] = 1
    dim[points] = 0
    tag[points] = np.arange(1, len(points) + 1)
    return dim, tag.astype(np.int32)
