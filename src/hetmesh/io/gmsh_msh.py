"""Gmsh MSH files (ASCII 4.1 and 2.2), written the way Gmsh itself writes them.

Geometric entities (4.1 ``$Entities``):

- **points**: every end of a curve's chain of edges and every named point
  (``mesh.named_points``), tags 1, 2, ... in node order; a named point is also a physical
  point (dimension 0) of its name, holding one ``15`` (point) element;
- **curves**: one per edge marker, entity tag = the marker, bounded by its end points
  (``start -end``; closed chains have none);
- **surfaces**: one per region, tags 1, 2, ... in region order, bounded by the curves
  whose edges border it.

Physical groups: one physical curve per *name* (:func:`hetmesh.io.groups.curve_groups`,
tag = the smallest marker of the name) holding every curve of that name; physical surface
``offset + r`` named ``region_<r>`` (:func:`region_tag_offset`); physical points from
:func:`point_tag_offset` up, named after the points.

Every node is classified on its entity (a point, else the curve it lies on, else its
region's surface), so ``gmsh.model.mesh.getNodes(1, c)`` returns the nodes inside curve
``c``. Node tags are the mesh's node indices + 1 and element tags the triangle indices + 1
(the edges follow, then the point elements) -- the numbering of every other format. Nodes
and elements are listed in tag order, a block for each run of one entity (the format allows
several blocks per entity), so readers that number by position (meshio, scikit-fem) get
the same numbering as Gmsh, which reads the tags. :func:`msh41_order` recovers the tag
order of files listed otherwise (as Gmsh writes them) for
:func:`hetmesh.io.read.read_mesh`.

MSH 2.2 has no node entities: nodes in tag order, elements with their physical and
geometric tags (the curve's marker, the region's surface), named points as point elements.
"""

from __future__ import annotations

import logging
from contextlib import nullcontext
from itertools import islice
from pathlib import Path
from typing import TYPE_CHECKING, TextIO

import numpy as np

from ..topology import edge_keys, unique
from . import textio
from .groups import curve_ends, curve_groups, node_entities, point_entities
from .textio import check_ids, float_pad, region_tag_offset

if TYPE_CHECKING:  # the writers take any mesh with Mesh's attributes
    from ..mesh import Mesh

__all__ = ["write_data", "write_msh41", "write_msh22", "point_tag_offset", "msh41_order",
           "physical_names"]

log = logging.getLogger(__name__)


def point_tag_offset(mesh: Mesh) -> int:
    """Physical point ``i`` (in ``mesh.named_points`` order) has tag ``offset + i + 1``:
    the next power of ten above every physical surface tag."""
    top = region_tag_offset(mesh.edge_markers) + int(np.max(mesh.regions, initial=0))
    return 10 ** len(str(top))


def physical_names(mesh: Mesh, regions: np.ndarray) -> list[tuple[int, int, str]]:
    """``(dim, tag, name)`` of every physical group: points, curves, surfaces."""
    p0 = point_tag_offset(mesh)
    out = [(0, p0 + i + 1, name) for i, name in enumerate(mesh.named_points)]
    out += [(1, g.tag, g.name) for g in curve_groups(mesh)]
    offset = region_tag_offset(mesh.edge_markers)
    out += [(2, offset + int(r), f"region_{r}") for r in regions]
    return out


def _write_header(f: TextIO, version: str, names: list[tuple[int, int, str]]) -> None:
    f.write(f"$MeshFormat\n{version} 0 8\n$EndMeshFormat\n")
    if names:
        f.write(f"$PhysicalNames\n{len(names)}\n")
        for dim, tag, name in names:
            f.write(f'{dim} {tag} "{name.replace(chr(34), chr(39))}"\n')
        f.write("$EndPhysicalNames\n")


def write_data(f: TextIO, section: str, name: str, tags: np.ndarray, values: np.ndarray,
                path: Path) -> None:
    """A ``$NodeData`` / ``$ElementData`` section, rows in the given (file) order."""
    v = np.asarray(values, np.float64).reshape(len(values), -1)
    if v.shape[1] not in (1, 3, 9):
        log.warning("%s: skipping %r: Gmsh data needs 1, 3 or 9 components, not %d",
                    path, name, v.shape[1])
        return
    f.write(f'${section}\n1\n"{name}"\n1\n0.0\n3\n0\n{v.shape[1]}\n{len(v)}\n')
    rows = np.column_stack([tags, v])
    textio.write_rows(f, "%d" + " %r" * v.shape[1] + "\n", rows)
    f.write(f"$End{section}\n")


def _bbox(points: np.ndarray) -> str:
    (x0, y0), (x1, y1) = points.min(axis=0).tolist(), points.max(axis=0).tolist()
    return f"{x0!r} {y0!r} 0 {x1!r} {y1!r} 0"


def _surface_curves(mesh: Mesh, regions: np.ndarray) -> list[np.ndarray]:
    """Per region: the markers whose edges are sides of its triangles."""
    t = mesh.triangles
    side = edge_keys(np.concatenate([t[:, 0], t[:, 1], t[:, 2]]),
                     np.concatenate([t[:, 1], t[:, 2], t[:, 0]]))
    reg = np.tile(mesh.regions, 3)
    ek = edge_keys(mesh.edges[:, 0], mesh.edges[:, 1])
    return [unique(mesh.edge_markers[np.isin(ek, side[reg == r])]) for r in regions]


def _write_entities(f: TextIO, mesh: Mesh, points: np.ndarray, regions: np.ndarray) -> None:
    p = mesh.points
    groups = {m: g.tag for g in curve_groups(mesh) for m in g.markers}
    p0 = point_tag_offset(mesh)
    phys_points: dict[int, list[int]] = {}
    for i, node in enumerate(mesh.named_points.values()):
        phys_points.setdefault(int(node), []).append(p0 + i + 1)
    ends = curve_ends(mesh)
    markers = sorted(ends)
    f.write(f"$Entities\n{len(points)} {len(markers)} {len(regions)} 0\n")
    for i, node in enumerate(points.tolist()):
        phys = phys_points.get(node, [])
        f.write(f"{i + 1} {float(p[node, 0])!r} {float(p[node, 1])!r} 0 {len(phys)}"
                + "".join(f" {t}" for t in phys) + "\n")
    pos = {int(n): i + 1 for i, n in enumerate(points.tolist())}
    for m in markers:
        nodes = mesh.edges[mesh.edge_markers == m].ravel()
        e = ends[m]
        bound = f"2 {pos[e[0]]} -{pos[e[1]]}" if e else "0"
        f.write(f"{m} {_bbox(p[nodes])} 1 {groups[m]} {bound}\n")
    offset = region_tag_offset(mesh.edge_markers)
    for i, (r, curves) in enumerate(zip(regions, _surface_curves(mesh, regions))):
        nodes = mesh.triangles[mesh.regions == r].ravel()
        f.write(f"{i + 1} {_bbox(p[nodes])} 1 {offset + int(r)} {len(curves)}"
                + "".join(f" {int(c)}" for c in curves) + "\n")
    f.write("$EndEntities\n")


def _runs(keys: np.ndarray) -> list[tuple[int, int]]:
    """``[(start, stop)]`` of the runs of equal rows of ``keys`` ``(n, k)`` (sorted)."""
    if not len(keys):
        return []
    change = np.flatnonzero(np.any(keys[1:] != keys[:-1], axis=1)) + 1
    bounds = np.concatenate([[0], change, [len(keys)]])
    return list(zip(bounds[:-1].tolist(), bounds[1:].tolist()))


def write_msh41(mesh: Mesh, path: Path, fmt=None) -> None:
    """Write ``mesh`` as an ASCII Gmsh 4.1 file (see the module docstring)."""
    check_ids(mesh, path, "Gmsh", markers=True)
    regions = unique(mesh.regions)
    points = point_entities(mesh)
    m, k, n = mesh.n_elements, len(mesh.edges), mesh.n_points
    dim, tag = node_entities(mesh, points, regions)
    node_order = np.arange(n)  # tag order: runs of one entity each (meshio reads by position)
    node_runs = _runs(np.column_stack([dim, tag])[node_order])
    # elements in tag order too, a block per run of one entity
    edge_order = np.arange(k)
    edge_runs = _runs(mesh.edge_markers[:, None])
    tri_order = np.arange(m)
    tri_runs = _runs(mesh.regions[:, None])
    with open(path, "w", encoding="utf-8") as f:
        _write_header(f, "4.1", physical_names(mesh, regions))
        _write_entities(f, mesh, points, regions)
        f.write(f"$Nodes\n{len(node_runs)} {n} 1 {n}\n")
        for a, b in node_runs:
            ids = node_order[a:b]
            f.write(f"{dim[ids[0]]} {tag[ids[0]]} 0 {b - a}\n")
            textio.write_rows(f, "%d\n", ids + 1)
            textio.write_rows(f, "%r %r 0\n", mesh.points[ids])
        f.write("$EndNodes\n")
        # point elements only on the physical (named) points, as Gmsh saves them
        named = unique(np.fromiter(mesh.named_points.values(), np.int64,
                                      len(mesh.named_points)))
        npe = len(named)
        blocks = npe + len(edge_runs) + len(tri_runs)
        f.write(f"$Elements\n{blocks} {m + k + npe} 1 {m + k + npe}\n")
        for i, node in enumerate(named.tolist()):
            entity = int(np.searchsorted(points, node)) + 1
            f.write(f"0 {entity} 15 1\n{m + k + i + 1} {node + 1}\n")
        for a, b in edge_runs:
            ids = edge_order[a:b]
            f.write(f"1 {mesh.edge_markers[ids[0]]} 1 {b - a}\n")
            textio.write_rows(f, "%d %d %d\n", np.column_stack([m + ids + 1, mesh.edges[ids] + 1]))
        for a, b in tri_runs:
            ids = tri_order[a:b]
            surface = int(np.searchsorted(regions, mesh.regions[ids[0]])) + 1
            f.write(f"2 {surface} 2 {b - a}\n")
            textio.write_rows(f, "%d %d %d %d\n",
                              np.column_stack([ids + 1, mesh.triangles[ids] + 1]))
        f.write("$EndElements\n")
        for name, v in mesh.point_data.items():
            write_data(f, "NodeData", name, node_order + 1, np.asarray(v)[node_order], path)
        # meshio wants a value on every element, in file order: NaN on points and lines
        elem_tags = np.concatenate([m + k + 1 + np.arange(npe), m + 1 + edge_order, tri_order + 1])
        for name, v in mesh.cell_data.items():
            if name == "region":
                continue
            v = np.asarray(v, np.float64)
            write_data(f, "ElementData", name, elem_tags,
                        np.concatenate([float_pad(v, npe + k), v[tri_order]]), path)


def write_msh22(mesh: Mesh, path: Path, fmt=None) -> None:
    """Write ``mesh`` as an ASCII Gmsh 2.2 file (see the module docstring)."""
    check_ids(mesh, path, "Gmsh", markers=True)
    regions, r_entity = unique(mesh.regions, return_inverse=True)
    groups = {mk: g.tag for g in curve_groups(mesh) for mk in g.markers}
    points = point_entities(mesh)
    m, k, p = mesh.n_elements, len(mesh.edges), mesh.points
    offset = region_tag_offset(mesh.edge_markers)
    named = list(mesh.named_points.items())
    with open(path, "w", encoding="utf-8") as f:
        _write_header(f, "2.2", physical_names(mesh, regions))
        f.write(f"$Nodes\n{len(p)}\n")
        textio.write_rows(f, "%d %r %r 0\n", np.column_stack([np.arange(1, len(p) + 1), p]))
        f.write(f"$EndNodes\n$Elements\n{m + k + len(named)}\n")
        tri = np.column_stack([np.arange(1, m + 1), mesh.regions + offset,
                               r_entity.ravel() + 1, mesh.triangles + 1])
        textio.write_rows(f, "%d 2 2 %d %d %d %d %d\n", tri)
        phys = np.array([groups[int(mk)] for mk in mesh.edge_markers], np.int64).reshape(-1)
        lines = np.column_stack([np.arange(m + 1, m + k + 1), phys, mesh.edge_markers,
                                 mesh.edges + 1])
        textio.write_rows(f, "%d 1 2 %d %d %d %d\n", lines)
        p0 = point_tag_offset(mesh)
        for i, (_, node) in enumerate(named):
            entity = int(np.searchsorted(points, node)) + 1
            f.write(f"{m + k + i + 1} 15 2 {p0 + i + 1} {entity} {node + 1}\n")
        f.write("$EndElements\n")
        # no $ElementData: meshio 5.3.5 cannot read it in MSH 2.2 with lines (meshio#1257)
        for name, v in mesh.point_data.items():
            write_data(f, "NodeData", name, np.arange(1, len(p) + 1), v, path)


def msh41_order(path, kind: int = 2) -> tuple[np.ndarray, np.ndarray] | None:
    """``(node tags, element tags of Gmsh type kind)`` (2: triangles, 4: tetrahedra) of an
    ASCII MSH 4.1 file (a path or an open text stream), in file order (meshio lists nodes
    and cells in that order); None for other versions or binary."""
    with (open(path, encoding="utf-8", errors="replace") if isinstance(path, (str, Path))
          else nullcontext(path)) as f:
        head = [next(f, ""), next(f, "")]
        if not head[0].startswith("$MeshFormat") or not head[1].split()[:2] == ["4.1", "0"]:
            return None
        nodes: list[np.ndarray] = []
        tris: list[np.ndarray] = []
        for line in f:
            if line.startswith("$Nodes"):
                blocks = int(next(f).split()[0])
                for _ in range(blocks):
                    d, _, param, count = (int(x) for x in next(f).split())
                    nodes.append(np.array([int(s) for s in islice(f, count)], np.int64))
                    for _ in islice(f, count):
                        pass
                    if param:
                        return None
            elif line.startswith("$Elements"):
                blocks = int(next(f).split()[0])
                for _ in range(blocks):
                    d, _, elem_kind, count = (int(x) for x in next(f).split())
                    rows = list(islice(f, count))
                    if elem_kind == kind:
                        tris.append(np.array([int(r.split(None, 1)[0]) for r in rows], np.int64))
                break
    cat = lambda a: np.concatenate(a) if a else np.zeros(0, np.int64)  # noqa: E731
    return cat(nodes), cat(tris)
