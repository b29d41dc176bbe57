"""Mesh export and import: VTU, Gmsh MSH (4.1 and 2.2), XDMF, Abaqus INP, legacy VTK, Medit.

Every format numbers nodes and elements alike: node ``i`` of the mesh is node ``i + 1``
(or index ``i``), triangle ``j`` element ``j + 1``. Curves are exported as **one group per
name** (:mod:`hetmesh.io.groups`): the pieces of a curve split by a discontinuity, and the
curves of a hole or an interface, form one named group. What each format keeps of a
:class:`~hetmesh.mesh.Mesh`:

- ``.vtu``, ``.vtk`` (meshio): a ``triangle`` and a ``line`` block; point data; the
  triangles' cell data and ``region``, padded on the lines (NaN, or -1 for integers);
  ``marker`` (0 on triangles). Points are (x, y, 0). Marker names are lost.
- ``.xdmf`` (:mod:`hetmesh.io.xdmf`): the layout dolfinx reads, an ``.h5`` file beside it.
- ``.msh`` (:mod:`hetmesh.io.gmsh_msh`): Gmsh 4.1 by default, 2.2 with
  ``file_format="gmsh22"``: entities (points, curves = markers, surfaces = regions) with
  their boundaries, nodes classified on them, one physical curve per name, physical
  surface ``region_<r>`` (:func:`region_tag_offset`), physical points for the named
  points; point data as ``$NodeData``, cell data as ``$ElementData`` (4.1 only).
- ``.inp`` (:mod:`hetmesh.io.abaqus`): Abaqus/CalculiX ``CPE3`` elements, ``*ELSET``
  ``REGION_<r>``, per curve name an ``*NSET`` and an element-based ``*SURFACE``, per named
  point an ``*NSET``; numbers of at most 20 characters. No data (see
  :mod:`hetmesh.io.material` for the graded material).
- ``.mesh`` (Medit, meshio): ``medit:ref`` is the region on triangles, the marker on edges.

meshio 5.3.5 cannot read ``CPE3`` and its kin; importing this module registers them in
meshio's Abaqus reader so ``meshio.read`` reads the files we write.
"""

from __future__ import annotations

import logging
import re
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import meshio
import numpy as np

from ..errors import OutputError
from ..topology import unique
from . import abaqus, gmsh_msh, xdmf
from .atomic import atomic_path, atomic_write  # atomic_write re-exported (docs/internals.md)
from .textio import float_pad, region_tag_offset

if TYPE_CHECKING:  # the writers take any mesh with Mesh's attributes
    from ..mesh import Mesh

__all__ = ["FORMATS", "FILE_FORMATS", "MeshFormat", "write_mesh", "read_mesh_arrays",
           "region_tag_offset",
           "atomic_write"]

log = logging.getLogger(__name__)

_RESERVED_CELL = {"region", "marker", "gmsh:physical", "gmsh:geometrical", "medit:ref", "cell_tags",
                  "facet_tags"}
_RESERVED_POINT = {"gmsh:dim_tags", "medit:ref"}


@dataclass(frozen=True)
class MeshFormat:
    """How to write one mesh format.

    Attributes
    ----------
    name : str
        hetmesh's name for it (the ``file_format`` argument of :func:`write_mesh`).
    meshio_format : str
        meshio's name, used for reading (and for writing through meshio unless
        ``meshio_writer`` is given).
    options : mapping
        Keyword arguments of the writer (``meshio.write`` or ours).
    writer : callable ``(mesh, path, fmt) -> None``
    meshio_writer : str, optional
        meshio's name of the writer when it differs (``"vtk42"``).
    dims : tuple of int
        The mesh dimensions the writer handles (triangles: 2, tetrahedra: 3).
    """

    name: str
    meshio_format: str
    options: Mapping = field(default_factory=dict)
    writer: Callable[[Mesh, Path, MeshFormat], None] | None = None
    meshio_writer: str | None = None
    dims: tuple[int, ...] = (2,)


# -- writers -----------------------------------------------------------------------------

def _numeric(a) -> np.ndarray:
    a = np.asarray(a)
    return a.astype(np.int8) if a.dtype == bool else a


def _to_meshio(mesh: Mesh, *, points3d: bool) -> meshio.Mesh:
    """The mesh as a meshio.Mesh: a block of its cells (triangles or tetrahedra) and, if
    there are facets, a block of them (lines or triangles); ``points3d`` pads 2D points
    with z = 0."""
    p = np.asarray(mesh.points, np.float64)
    if points3d and mesh.dim == 2:
        p = np.column_stack([p, np.zeros(len(p))])
    cells = [(mesh.cell_type, np.asarray(mesh.cells))]
    tri_data = {k: _numeric(v) for k, v in mesh.cell_data.items()
                if k not in ("region", "marker")}
    tri_data["region"] = np.asarray(mesh.regions)
    k = len(mesh.facets)
    if k:
        cells.append((mesh.facet_type, np.asarray(mesh.facets)))
        cell_data = {n: [v, float_pad(v, k)] for n, v in tri_data.items()}
        cell_data["marker"] = [np.zeros(mesh.n_elements, np.int32), np.asarray(mesh.facet_markers)]
    else:
        cell_data = {n: [v] for n, v in tri_data.items()}
    point_data = {n: _numeric(v) for n, v in mesh.point_data.items()}
    return meshio.Mesh(p, cells, point_data=point_data, cell_data=cell_data)


def _write_meshio(mesh: Mesh, path: Path, fmt: MeshFormat) -> None:
    m = _to_meshio(mesh, points3d=fmt.name in ("vtu", "vtk"))
    meshio.write(path, m, file_format=fmt.meshio_writer or fmt.meshio_format, **fmt.options)


def _write_medit(mesh: Mesh, path: Path, fmt: MeshFormat) -> None:
    cells = [(mesh.cell_type, np.asarray(mesh.cells))]
    refs = [np.asarray(mesh.regions)]
    if len(mesh.facets):
        cells.append((mesh.facet_type, np.asarray(mesh.facets)))
        refs.append(np.asarray(mesh.facet_markers))
    m = meshio.Mesh(np.asarray(mesh.points), cells, cell_data={"medit:ref": refs})
    meshio.write(path, m, file_format="medit", **fmt.options)


# -- registry ----------------------------------------------------------------------------

def _register_abaqus_types() -> None:
    """Teach meshio's Abaqus reader the plane elements (missing in meshio 5.3.5)."""
    table = getattr(getattr(meshio.abaqus, "_abaqus", None), "abaqus_to_meshio_type", None)
    if isinstance(table, dict):
        for name in ("CPE3", "CPS3"):
            table.setdefault(name, "triangle")
        for name in ("CPE6", "CPS6"):
            table.setdefault(name, "triangle6")
    else:  # pragma: no cover - meshio reorganised
        log.debug("meshio's Abaqus type table not found; cannot register CPE3")


_register_abaqus_types()

def _or_tets(writer2d: Callable, name3d: str) -> Callable:
    """``writer2d`` for 2D meshes, :func:`hetmesh.tet.export.write_tet_file` for 3D ones."""
    def write(mesh: Mesh, path: Path, fmt: MeshFormat) -> None:
        if mesh.dim == 3:
            from ..tet.export import write_tet_file
            write_tet_file(mesh, path, name3d)
        else:
            writer2d(mesh, path, fmt)
    return write


_GMSH41 = MeshFormat("gmsh41", "gmsh", {}, _or_tets(gmsh_msh.write_msh41, "gmsh"), dims=(2, 3))
FILE_FORMATS: dict[str, MeshFormat] = {
    "vtu": MeshFormat("vtu", "vtu", {"binary": True, "compression": "zlib"}, _write_meshio,
                      dims=(2, 3)),
    "vtk": MeshFormat("vtk", "vtk", {"binary": True}, _write_meshio, "vtk42", dims=(2, 3)),
    "xdmf": MeshFormat("xdmf", "xdmf", {}, xdmf.write_xdmf, dims=(2, 3)),
    "gmsh": _GMSH41,
    "gmsh41": _GMSH41,
    "gmsh22": MeshFormat("gmsh22", "gmsh", {}, _or_tets(gmsh_msh.write_msh22, "gmsh22"),
                         dims=(2, 3)),
    "abaqus": MeshFormat("abaqus", "abaqus", {}, _or_tets(abaqus.write_inp, "abaqus"),
                         dims=(2, 3)),
    "medit": MeshFormat("medit", "medit", {}, _write_medit, dims=(2, 3)),
}
"""Every format by its ``file_format`` name."""

FORMATS: dict[str, MeshFormat] = {
    ext: FILE_FORMATS[name] for ext, name in [(".vtu", "vtu"), (".vtk", "vtk"), (".xdmf", "xdmf"),
                                              (".msh", "gmsh41"), (".inp", "abaqus"),
                                              (".mesh", "medit")]
}
"""The default format of every known extension."""


def _resolve(path: Path, file_format: str | None) -> MeshFormat:
    if file_format is not None:
        try:
            return FILE_FORMATS[file_format.lower()]
        except KeyError:
            known = ", ".join(sorted(FILE_FORMATS))
            raise OutputError(f"unknown mesh file_format {file_format!r} for {path} "
                              f"(known: {known})") from None
    ext = path.suffix.lower()
    if ext not in FORMATS:
        known = ", ".join(sorted(FORMATS))
        raise OutputError(f"unknown mesh format {ext!r} for {path} (known: {known})")
    return FORMATS[ext]


def _one_line(exc: BaseException) -> str:
    return " ".join(str(exc).split()) or type(exc).__name__


def write_mesh(mesh: Mesh, path: str | Path, *, file_format: str | None = None) -> Path:
    """Write ``mesh`` to ``path`` atomically; the format follows the extension.

    Parameters
    ----------
    mesh : Mesh
    path : str or Path
        ``.vtu``, ``.vtk``, ``.xdmf``, ``.msh``, ``.inp`` or ``.mesh``.
    file_format : str, optional
        Overrides the extension: one of :data:`FILE_FORMATS` (``"gmsh22"`` for Gmsh 2.2).

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    OutputError
        Unknown format, unwritable path, or data the format cannot hold.

    Examples
    --------
    >>> write_mesh(mesh, "plate.msh", file_format="gmsh22")   # doctest: +SKIP
    PosixPath('plate.msh')
    """
    path = Path(path)
    fmt = _resolve(path, file_format)
    if mesh.dim not in fmt.dims:
        able = ", ".join(sorted(n for n, f in FILE_FORMATS.items() if mesh.dim in f.dims))
        raise OutputError(f"cannot write {path} as {fmt.name}: it takes "
                          f"{' and '.join(f'{d}D' for d in fmt.dims)} meshes, this one is "
                          f"{mesh.dim}D (formats for {mesh.dim}D meshes: {able})")
    try:
        if fmt.name == "xdmf":  # two files, each written atomically
            xdmf.write_xdmf(mesh, path)
        else:
            with atomic_path(path) as tmp:
                fmt.writer(mesh, tmp, fmt)
    except (meshio.WriteError, ValueError, TypeError, OSError) as exc:
        raise OutputError(f"cannot write {path} as {fmt.name}: {_one_line(exc)}") from exc
    log.info("wrote %s (%s: %d points, %d %s cells)", path, fmt.name, mesh.n_points,
             mesh.n_elements, mesh.cell_type)
    return path


# -- reading -----------------------------------------------------------------------------

def _blocks(m: meshio.Mesh, kind: str) -> list[int]:
    return [i for i, c in enumerate(m.cells) if c.type == kind]


def _gather(m: meshio.Mesh, name: str, blocks: list[int]) -> np.ndarray | None:
    if name not in m.cell_data or not blocks:
        return None
    return np.concatenate([np.asarray(m.cell_data[name][i]) for i in blocks])


def _tet_arrays(m: meshio.Mesh) -> dict:
    """The :class:`~hetmesh.mesh.Mesh` arrays of a tetrahedral meshio mesh, as the writers
    of 3D meshes store them: the tetrahedra; regions from ``region`` (vtu, vtk) or the
    physical volume tags (msh: tag - 1) or ``medit:ref``; the triangles as facets, their
    markers from ``marker``, ``gmsh:geometrical`` or ``medit:ref``, their names from the
    physical surface holding each marker's triangles (msh: tag = 100 + the smallest marker
    of the name, :data:`hetmesh.tet.export.FACE_TAG`)."""
    tet, tri = _blocks(m, "tetra"), _blocks(m, "triangle")
    cells = np.concatenate([m.cells[i].data for i in tet]).astype(np.int64)
    regions = _gather(m, "region", tet)
    if regions is None and "gmsh:physical" in m.cell_data:
        regions = _gather(m, "gmsh:physical", tet) - 1
    if regions is None:
        regions = _gather(m, "medit:ref", tet)
    facets = markers = None
    names: dict[int, str] = {}
    if tri:
        facets = np.concatenate([m.cells[i].data for i in tri]).astype(np.int64)
        for key in ("marker", "gmsh:geometrical", "medit:ref"):
            markers = _gather(m, key, tri)
            if markers is not None:
                break
        by_tag = {int(tag): name for name, (tag, dim) in
                  ((k, tuple(v)[:2]) for k, v in (m.field_data or {}).items())
                  if int(dim) == 2 and int(tag) > 100}
        phys = _gather(m, "gmsh:physical", tri)
        if phys is not None and markers is not None:  # every marker named by its group
            for mk, ph in unique(np.column_stack([markers, phys]), axis=0).tolist():
                if int(ph) in by_tag:
                    names[int(mk)] = by_tag[int(ph)]
        else:
            names = {t - 100: n for t, n in by_tag.items()}
    cell_data = {k: _gather(m, k, tet) for k in m.cell_data
                 if k not in _RESERVED_CELL and not k.startswith(("gmsh:", "medit:"))}
    point_data = {k: np.asarray(v) for k, v in m.point_data.items() if k not in _RESERVED_POINT}
    return dict(points=np.asarray(m.points, np.float64), cells=cells, regions=regions,
                facets=facets, facet_markers=markers, point_data=point_data,
                cell_data={k: v for k, v in cell_data.items() if v is not None},
                marker_names=names)


def _physical_names(m: meshio.Mesh, dim: int) -> dict[int, str]:
    """Gmsh physical names of one dimension: ``{tag: name}``."""
    tags = {name: np.asarray(v).ravel() for name, v in m.field_data.items()}
    return {int(v[0]): str(name) for name, v in tags.items() if len(v) >= 2 and int(v[1]) == dim}


def _read_regions(m: meshio.Mesh, tri: list[int], n: int) -> np.ndarray:
    region = _gather(m, "region", tri)
    if region is not None:
        return region.astype(np.int32)
    phys = _gather(m, "gmsh:physical", tri)
    if phys is not None:
        names = _physical_names(m, 2)
        lut = {t: int(s[7:]) for t, s in names.items() if re.fullmatch(r"region_-?\d+", s)}
        tags, inverse = unique(phys.astype(np.int64), return_inverse=True)
        return np.array([lut.get(int(t), int(t)) for t in tags], np.int32)[inverse.ravel()]
    ref = _gather(m, "medit:ref", tri)
    if ref is not None:
        return ref.astype(np.int32)
    return _regions_from_sets(m, tri, n)


def _set_cells(m: meshio.Mesh, name: str, tri: list[int]) -> np.ndarray:
    """Indices (into the concatenated triangle blocks) of the cells of a cell set."""
    offsets = np.cumsum([0] + [len(m.cells[i]) for i in tri])
    per_block = m.cell_sets[name]
    parts = [offsets[j] + np.asarray(per_block[i], np.int64) for j, i in enumerate(tri)
             if i < len(per_block) and per_block[i] is not None and len(per_block[i])]
    return np.concatenate(parts) if parts else np.zeros(0, np.int64)


def _regions_from_sets(m: meshio.Mesh, tri: list[int], n: int) -> np.ndarray:
    """Regions from Abaqus element sets named ``REGION_<id>``."""
    regions = np.zeros(n, np.int32)
    for name in m.cell_sets:
        match = re.fullmatch(r"REGION_(-?\d+)", name, flags=re.IGNORECASE)
        if match:
            regions[_set_cells(m, name, tri)] = int(match.group(1))
    return regions


def _surface_names(path: Path) -> dict[int, str]:
    """``{marker: surface name}`` from the ``*SURFACE`` blocks of our Abaqus files (their
    lines name the ``_M<marker>_S<side>`` sets)."""
    text = path.read_text(encoding="utf-8", errors="replace")
    out = {}
    for block in re.finditer(r"^\*SURFACE, TYPE=ELEMENT, NAME=(\S+)\n((?:_M\d+_S\d, S\d\n)+)",
                             text, flags=re.MULTILINE):
        for mk in re.findall(r"_M(\d+)_S", block.group(2)):
            out[int(mk)] = block.group(1)
    return out


def _edges_from_surfaces(m: meshio.Mesh, tri: list[int], triangles: np.ndarray, path: Path):
    """Edges and markers from the ``_M<marker>_S<side>`` element sets (our Abaqus files);
    the marker names from the ``*SURFACE`` blocks."""
    edges, markers = [], []
    for name in m.cell_sets:
        match = re.fullmatch(r"_M(\d+)_S([123])", name, flags=re.IGNORECASE)
        if match:
            s = int(match.group(2)) - 1
            edges.append(triangles[_set_cells(m, name, tri)][:, [s, (s + 1) % 3]])
            markers.append(np.full(len(edges[-1]), int(match.group(1)), np.int32))
    if not edges:
        return np.zeros((0, 2), np.int32), np.zeros(0, np.int32), {}
    names = {k: v for k, v in _surface_names(path).items() if v != f"MARKER_{k}"}
    return np.concatenate(edges), np.concatenate(markers), names


def _read_edges(m: meshio.Mesh, tri: list[int], triangles: np.ndarray, path: Path):
    """``(edges, markers, marker names)`` from line cells or Abaqus surfaces."""
    lines = _blocks(m, "line")
    if not lines:
        return _edges_from_surfaces(m, tri, triangles, path)
    edges = np.concatenate([m.cells[i].data for i in lines])
    for key in ("marker", "gmsh:geometrical", "gmsh:physical", "medit:ref"):
        markers = _gather(m, key, lines)
        if markers is not None:
            break
    else:
        markers = np.ones(len(edges), np.int32)
    names = {}
    phys = _gather(m, "gmsh:physical", lines)
    if phys is not None:
        by_tag = _physical_names(m, 1)
        names = {int(mk): by_tag[int(t)] for mk, t in zip(*unique(
            np.column_stack([markers, phys]), axis=0).T) if int(t) in by_tag}
        names = {k: v for k, v in names.items() if not re.fullmatch(r"marker_\d+", v)}
    return edges, markers.astype(np.int32), names


def _named_points(m: meshio.Mesh, curve_names: set[str]) -> dict[str, int]:
    """Named nodes: Gmsh physical points, or Abaqus node sets of one node that name no
    curve."""
    out: dict[str, int] = {}
    verts = _blocks(m, "vertex")
    phys = _gather(m, "gmsh:physical", verts)
    if phys is not None:
        by_tag = _physical_names(m, 0)
        nodes = np.concatenate([m.cells[i].data.ravel() for i in verts])
        for node, t in zip(nodes.tolist(), phys.tolist()):
            if int(t) in by_tag:
                out[by_tag[int(t)]] = int(node)
        return out
    for name, ids in m.point_sets.items():
        if len(ids) == 1 and name not in curve_names:
            out[name] = int(np.asarray(ids).ravel()[0])
    return out


def _tag_order(m: meshio.Mesh, path: Path, tri: list[int]) -> meshio.Mesh:
    """Put the nodes, triangles and tetrahedra of a Gmsh 4.1 file read by meshio (in file
    order) back in the order of their tags, the mesh's own order (``tri``: the triangle
    blocks)."""
    order = gmsh_msh.msh41_order(path)
    if order is None:
        return m
    node_tags, tri_tags = order
    if len(node_tags) != len(m.points):
        return m
    perm = np.argsort(node_tags, kind="stable")  # new index -> file position
    new_of = np.empty(len(perm), np.int64)
    new_of[perm] = np.arange(len(perm))
    cells = [(c.type, new_of[c.data]) for c in m.cells]
    cell_data = {k: list(v) for k, v in m.cell_data.items()}
    tets = [i for i, c in enumerate(cells) if c[0] == "tetra"]
    for kind, blocks, tags in (("triangle", tri, tri_tags),
                               ("tetra", tets, gmsh_msh.msh41_order(path, 4)[1] if tets
                                else np.zeros(0, np.int64))):
        if not blocks or len(tags) != sum(len(cells[i][1]) for i in blocks):
            continue
        # gather the blocks of this kind into one block in element tag order
        t_perm = np.argsort(tags, kind="stable")
        first = blocks[0]
        merged = np.concatenate([cells[i][1] for i in blocks])[t_perm]
        keep = [i for i in range(len(cells)) if i not in blocks[1:]]
        cells[first] = (kind, merged)
        for k, v in cell_data.items():
            v[first] = np.concatenate([np.asarray(v[i]) for i in blocks])[t_perm]
            cell_data[k] = [v[i] for i in keep]
        cells = [cells[i] for i in keep]
        if kind == "triangle":  # the tetra block indices after the merge
            tets = [i for i, c in enumerate(cells) if c[0] == "tetra"]
    point_data = {k: np.asarray(v)[perm] for k, v in m.point_data.items()}
    return meshio.Mesh(m.points[perm], cells, point_data=point_data, cell_data=cell_data,
                       field_data=m.field_data)


def read_mesh_arrays(path: str | Path) -> dict:
    """The arrays of a mesh file as the keyword arguments of :class:`hetmesh.mesh.Mesh`
    (``points``, ``cells``, ``regions``, ``facets``, ``facet_markers``, ``point_data``,
    ``cell_data``, ``marker_names``, ``named_points``); :func:`hetmesh.io.read.read_mesh`
    builds the mesh. What is read, from which format, and the errors: see there."""
    path = Path(path)
    fmt = _resolve(path, None)
    if not path.is_file():
        raise OutputError(f"cannot read {path}: no such file")
    if fmt.name == "xdmf":
        try:
            arrays = xdmf.read_xdmf(path)
        except (OSError, KeyError, ValueError, AttributeError) as exc:
            raise OutputError(f"cannot read {path} as xdmf: {_one_line(exc)}") from exc
        if arrays is not None:
            return arrays
    # the format's own reader: meshio.read() prints and calls sys.exit(1) on a bad file
    reader = getattr(meshio, fmt.meshio_format).read
    try:
        m = reader(path)
        if fmt.meshio_format == "gmsh":
            m = _tag_order(m, path, _blocks(m, "triangle"))
    except Exception as exc:  # malformed input surfaces as anything from ValueError to EOFError
        raise OutputError(f"cannot read {path} as {fmt.name}: {_one_line(exc)}") from exc
    if _blocks(m, "tetra"):
        return _tet_arrays(m)
    tri = _blocks(m, "triangle")
    quadratic = _blocks(m, "triangle6")
    if not tri and quadratic:  # six-node triangles: their corners; mid-side nodes follow
        cells = [(c.type, c.data[:, :3] if c.type == "triangle6" else c.data) for c in m.cells]
        n = 1 + max(int(c.data[:, :3].max()) for c in m.cells if c.type == "triangle6")
        m = meshio.Mesh(m.points[:n], [(t, d) for t, d in cells],
                        point_sets={k: v[v < n] for k, v in m.point_sets.items()},
                        cell_sets=m.cell_sets, cell_data=m.cell_data)
        m.cells = [meshio.CellBlock("triangle", c.data) if c.type == "triangle6" else c
                   for c in m.cells]
        tri = _blocks(m, "triangle")
    if not tri:
        raise OutputError(f"cannot read {path}: it has no triangles")
    triangles = np.concatenate([m.cells[i].data for i in tri])
    regions = _read_regions(m, tri, len(triangles))
    edges, markers, names = _read_edges(m, tri, triangles, path)
    curve_sets = set(_surface_names(path).values()) if fmt.name == "abaqus" else set()
    named = _named_points(m, curve_sets | set(names.values()))
    cell_data = {k: _gather(m, k, tri) for k in m.cell_data
                 if k not in _RESERVED_CELL and not k.startswith(("gmsh:", "medit:"))}
    point_data = {k: np.asarray(v) for k, v in m.point_data.items() if k not in _RESERVED_POINT}
    return dict(points=np.asarray(m.points, np.float64)[:, :2], cells=triangles,
                regions=regions, facets=edges, facet_markers=markers, point_data=point_data,
                cell_data=cell_data, marker_names=names, named_points=named)
