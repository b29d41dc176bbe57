"""Mesh export and import: VTU, Gmsh MSH (4.1 and 2.2), XDMF, Abaqus INP, legacy VTK, Medit.

What each format keeps of a :class:`~hetmesh.mesh.Mesh`:

- ``.vtu``, ``.vtk``, ``.xdmf`` (meshio): a ``triangle`` and a ``line`` block; point data;
  the triangles' cell data and ``region``, padded on the lines (NaN, or -1 for integers);
  ``marker`` (0 on triangles). VTK points are (x, y, 0); XDMF keeps (x, y) and inlines its
  arrays as XML: one file, no ``.h5`` side file. Marker names are lost.
- ``.msh`` (ASCII, written here): Gmsh 4.1 by default, 2.2 with ``file_format="gmsh22"``.
  Edges of marker ``m`` form physical curve ``m`` named ``mesh.marker_names[m]`` (or
  ``marker_<m>``); triangles of region ``r`` form physical surface ``1000 + r`` named
  ``region_<r>`` (see :func:`region_tag_offset`) -- disjoint ranges, as some readers ignore
  the dimension of a physical tag. Each region and marker is one geometric entity (tags
  1, 2, ... in sorted order). Point data as ``$NodeData``; cell data as ``$ElementData`` in
  4.1 only (NaN on lines: meshio wants every element; meshio 5.3.5 cannot read 2.2 element
  data with lines, meshio#1257). 4.1 groups the triangles by region, so they read back in
  that order.
- ``.inp`` (written here): Abaqus ``CPE3`` (plane strain) elements, an ``*ELSET``
  ``REGION_<r>`` per region; per marker, an element-based ``*SURFACE`` and an ``*NSET``
  named after it (sanitised; ``MARKER_<m>`` without a name), built on internal element
  sets ``_M<m>_S<side>`` from which the edges read back exactly. No data.
- ``.mesh`` (Medit, meshio): ``medit:ref`` is the region on triangles, the marker on edges.

meshio 5.3.5 cannot read ``CPE3``; importing this module registers it as a triangle in
meshio's Abaqus reader so ``meshio.read`` reads the files we write.
"""

from __future__ import annotations

import logging
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Mapping, TextIO

import meshio
import numpy as np

from ..errors import OutputError
from ..mesh import Mesh
from .atomic import atomic_path, atomic_write  # atomic_write re-exported (docs/internals.md)

__all__ = ["FORMATS", "FILE_FORMATS", "MeshFormat", "write_mesh", "read_mesh", "region_tag_offset",
           "atomic_write"]

log = logging.getLogger(__name__)

_RESERVED_CELL = {"region", "marker", "gmsh:physical", "gmsh:geometrical", "medit:ref", "cell_tags"}
_RESERVED_POINT = {"gmsh:dim_tags", "medit:ref"}
_ROWS_PER_CHUNK = 65536


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
    """

    name: str
    meshio_format: str
    options: Mapping = field(default_factory=dict)
    writer: Callable[[Mesh, Path, "MeshFormat"], None] | None = None
    meshio_writer: str | None = None


# -- writers -----------------------------------------------------------------------------

def _write_rows(f: TextIO, row: str, a: np.ndarray) -> None:
    """Write the rows of ``a`` with the %-format ``row`` (fast for millions of rows)."""
    a = np.asarray(a)
    for s in range(0, len(a), _ROWS_PER_CHUNK):
        block = a[s:s + _ROWS_PER_CHUNK]
        f.write((row * len(block)) % tuple(block.ravel().tolist()))


def _numeric(a) -> np.ndarray:
    a = np.asarray(a)
    return a.astype(np.int8) if a.dtype == bool else a


def _float_pad(a: np.ndarray, n: int) -> np.ndarray:
    """The padding of a cell data array on a block of ``n`` cells (NaN or -1)."""
    shape = (n,) + a.shape[1:]
    if np.issubdtype(a.dtype, np.floating):
        return np.full(shape, np.nan, a.dtype)
    if np.issubdtype(a.dtype, np.integer):
        return np.full(shape, -1, a.dtype)
    return np.zeros(shape, a.dtype)


def _to_meshio(mesh: Mesh, *, points3d: bool) -> meshio.Mesh:
    """The mesh as a meshio.Mesh: a triangle block and (if there are edges) a line block."""
    p = np.asarray(mesh.points, np.float64)
    if points3d:
        p = np.column_stack([p, np.zeros(len(p))])
    cells = [("triangle", np.asarray(mesh.triangles))]
    tri_data = {k: _numeric(v) for k, v in mesh.cell_data.items()
                if k not in ("region", "marker")}
    tri_data["region"] = np.asarray(mesh.regions)
    k = len(mesh.edges)
    if k:
        cells.append(("line", np.asarray(mesh.edges)))
        cell_data = {n: [v, _float_pad(v, k)] for n, v in tri_data.items()}
        cell_data["marker"] = [np.zeros(mesh.n_elements, np.int32), np.asarray(mesh.edge_markers)]
    else:
        cell_data = {n: [v] for n, v in tri_data.items()}
    point_data = {n: _numeric(v) for n, v in mesh.point_data.items()}
    return meshio.Mesh(p, cells, point_data=point_data, cell_data=cell_data)


def _write_meshio(mesh: Mesh, path: Path, fmt: MeshFormat) -> None:
    m = _to_meshio(mesh, points3d=fmt.name in ("vtu", "vtk"))
    meshio.write(path, m, file_format=fmt.meshio_writer or fmt.meshio_format, **fmt.options)


def _write_medit(mesh: Mesh, path: Path, fmt: MeshFormat) -> None:
    cells = [("triangle", np.asarray(mesh.triangles))]
    refs = [np.asarray(mesh.regions)]
    if len(mesh.edges):
        cells.append(("line", np.asarray(mesh.edges)))
        refs.append(np.asarray(mesh.edge_markers))
    m = meshio.Mesh(np.asarray(mesh.points), cells, cell_data={"medit:ref": refs})
    meshio.write(path, m, file_format="medit", **fmt.options)


# -- Gmsh --------------------------------------------------------------------------------

def region_tag_offset(markers: np.ndarray) -> int:
    """The physical tag of region ``r`` in Gmsh files is ``offset + r``.

    ``offset`` is 1000, or the next power of ten above the largest edge marker, so the tags
    of physical surfaces and curves never collide, even for tools that ignore dimensions.
    """
    largest = int(np.max(markers, initial=0))
    return max(1000, 10 ** len(str(largest)))


def _check_ids(mesh: Mesh, path: Path, what: str, *, markers: bool = False) -> None:
    """Ids that name sets and physical groups: regions >= 0 (and edge markers >= 1)."""
    if mesh.n_elements and mesh.regions.min() < 0:
        raise OutputError(f"cannot write {path}: {what} needs regions >= 0, got {mesh.regions.min()}")
    if markers and len(mesh.edges) and mesh.edge_markers.min() < 1:
        raise OutputError(f"cannot write {path}: {what} needs edge markers >= 1, "
                          f"got {mesh.edge_markers.min()}")


def _gmsh_names(mesh: Mesh, regions: np.ndarray, markers: np.ndarray) -> list[tuple[int, int, str]]:
    offset = region_tag_offset(markers)
    names = [(1, int(m), mesh.marker_names.get(int(m), f"marker_{m}")) for m in markers]
    names += [(2, offset + int(r), f"region_{r}") for r in regions]
    return names


def _write_gmsh_header(f: TextIO, version: str, names: list[tuple[int, int, str]]) -> None:
    f.write(f"$MeshFormat\n{version} 0 8\n$EndMeshFormat\n")
    if names:
        f.write(f"$PhysicalNames\n{len(names)}\n")
        for dim, tag, name in names:
            f.write(f'{dim} {tag} "{name.replace(chr(34), chr(39))}"\n')
        f.write("$EndPhysicalNames\n")


def _write_gmsh_data(f: TextIO, section: str, name: str, values: np.ndarray, path: Path) -> None:
    """A ``$NodeData`` / ``$ElementData`` section; entity tags are 1..len(values)."""
    v = np.asarray(values, np.float64).reshape(len(values), -1)
    if v.shape[1] not in (1, 3, 9):
        log.warning("%s: skipping %r: Gmsh data needs 1, 3 or 9 components, not %d",
                    path, name, v.shape[1])
        return
    f.write(f'${section}\n1\n"{name}"\n1\n0.0\n3\n0\n{v.shape[1]}\n{len(v)}\n')
    rows = np.column_stack([np.arange(1, len(v) + 1), v])
    _write_rows(f, "%d" + " %r" * v.shape[1] + "\n", rows)
    f.write(f"$End{section}\n")


def _write_gmsh_fields(f: TextIO, mesh: Mesh, order: np.ndarray | None, path: Path) -> None:
    """Point data; cell data too unless ``order`` (of the triangles in the file) is None."""
    for name, v in mesh.point_data.items():
        _write_gmsh_data(f, "NodeData", name, v, path)
    if order is None:
        return
    k = len(mesh.edges)
    for name, v in mesh.cell_data.items():
        if name != "region":  # meshio wants a value on every element: NaN on the lines
            v = np.asarray(v, np.float64)[order]
            _write_gmsh_data(f, "ElementData", name, np.concatenate([v, _float_pad(v, k)]), path)


def _write_gmsh22(mesh: Mesh, path: Path, fmt: MeshFormat) -> None:
    _check_ids(mesh, path, "Gmsh", markers=True)
    regions, r_entity = np.unique(mesh.regions, return_inverse=True)
    markers, m_entity = np.unique(mesh.edge_markers, return_inverse=True)
    m, k, p = mesh.n_elements, len(mesh.edges), mesh.points
    with open(path, "w", encoding="utf-8") as f:
        _write_gmsh_header(f, "2.2", _gmsh_names(mesh, regions, markers))
        f.write(f"$Nodes\n{len(p)}\n")
        _write_rows(f, "%d %r %r 0\n", np.column_stack([np.arange(1, len(p) + 1), p]))
        f.write(f"$EndNodes\n$Elements\n{m + k}\n")
        tri = np.column_stack([np.arange(1, m + 1), mesh.regions + region_tag_offset(markers),
                               r_entity.ravel() + 1, mesh.triangles + 1])
        _write_rows(f, "%d 2 2 %d %d %d %d %d\n", tri)
        lines = np.column_stack([np.arange(m + 1, m + k + 1), mesh.edge_markers,
                                 m_entity.ravel() + 1, mesh.edges + 1])
        _write_rows(f, "%d 1 2 %d %d %d %d\n", lines)
        f.write("$EndElements\n")
        # no $ElementData: meshio 5.3.5 cannot read it in MSH 2.2 with lines (meshio#1257)
        _write_gmsh_fields(f, mesh, None, path)


def _grouped(values: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(groups, order, bounds)``: ``order[bounds[i]:bounds[i + 1]]`` are the indices of
    ``values`` equal to ``groups[i]`` (sorted unique), in their original order."""
    order = np.argsort(values, kind="stable")
    groups, starts = np.unique(values[order], return_index=True)
    return groups, order, np.append(starts, len(values))


def _bbox(points: np.ndarray) -> str:
    (x0, y0), (x1, y1) = points.min(axis=0).tolist(), points.max(axis=0).tolist()
    return f"{x0!r} {y0!r} 0 {x1!r} {y1!r} 0"


def _write_gmsh41_entities(f: TextIO, mesh: Mesh, tri_groups, edge_groups) -> None:
    """Curve ``i`` = the i-th marker, surface ``i`` = the i-th region, with bounding boxes."""
    regions, t_order, t_bounds = tri_groups
    markers, e_order, e_bounds = edge_groups
    p, offset = mesh.points, region_tag_offset(markers)
    f.write(f"$Entities\n0 {len(markers)} {len(regions)} 0\n")
    for i, mk in enumerate(markers):
        nodes = mesh.edges[e_order[e_bounds[i]:e_bounds[i + 1]]].ravel()
        f.write(f"{i + 1} {_bbox(p[nodes])} 1 {int(mk)} 0\n")
    for i, r in enumerate(regions):
        nodes = mesh.triangles[t_order[t_bounds[i]:t_bounds[i + 1]]].ravel()
        f.write(f"{i + 1} {_bbox(p[nodes])} 1 {offset + int(r)} 0\n")
    f.write("$EndEntities\n")


def _write_gmsh41_nodes(f: TextIO, mesh: Mesh) -> None:
    """All nodes in one block (on surface 1): meshio returns 4.1 nodes in file order and
    reads $NodeData by position, so the file order must be the tag order."""
    n = mesh.n_points
    f.write(f"$Nodes\n1 {n} 1 {n}\n2 1 0 {n}\n")
    _write_rows(f, "%d\n", np.arange(1, n + 1))
    _write_rows(f, "%r %r 0\n", mesh.points)
    f.write("$EndNodes\n")


def _write_gmsh41_elements(f: TextIO, dim: int, cells: np.ndarray, groups, tag0: int) -> int:
    """One element block per group (entity); returns the next free element tag."""
    _, order, bounds = groups
    kind = {2: 2, 1: 1}[dim]  # Gmsh element types: 2 = 3-node triangle, 1 = 2-node line
    row = "%d" + " %d" * cells.shape[1] + "\n"
    for i in range(len(bounds) - 1):
        block = cells[order[bounds[i]:bounds[i + 1]]] + 1
        f.write(f"{dim} {i + 1} {kind} {len(block)}\n")
        _write_rows(f, row, np.column_stack([np.arange(tag0, tag0 + len(block)), block]))
        tag0 += len(block)
    return tag0


def _write_gmsh41(mesh: Mesh, path: Path, fmt: MeshFormat) -> None:
    _check_ids(mesh, path, "Gmsh", markers=True)
    tri_groups, edge_groups = _grouped(mesh.regions), _grouped(mesh.edge_markers)
    regions, markers = tri_groups[0], edge_groups[0]
    m, k = mesh.n_elements, len(mesh.edges)
    with open(path, "w", encoding="utf-8") as f:
        _write_gmsh_header(f, "4.1", _gmsh_names(mesh, regions, markers))
        _write_gmsh41_entities(f, mesh, tri_groups, edge_groups)
        _write_gmsh41_nodes(f, mesh)
        f.write(f"$Elements\n{len(regions) + len(markers)} {m + k} 1 {m + k}\n")
        tag0 = _write_gmsh41_elements(f, 2, mesh.triangles, tri_groups, 1)
        _write_gmsh41_elements(f, 1, mesh.edges, edge_groups, tag0)
        f.write("$EndElements\n")
        _write_gmsh_fields(f, mesh, tri_groups[1], path)


# -- Abaqus ------------------------------------------------------------------------------

def _abaqus_name(name: str) -> str:
    """A valid Abaqus set name: letters, digits and underscores, starting with a letter."""
    s = re.sub(r"[^A-Za-z0-9_]", "_", name.strip())
    if not s or not s[0].isalpha():
        s = "M_" + s
    return s[:80]


def _abaqus_set_names(mesh: Mesh, markers: np.ndarray) -> list[str]:
    names: list[str] = []
    for mk in markers:
        given = mesh.marker_names.get(int(mk))
        name = _abaqus_name(given) if given else f"MARKER_{mk}"
        if name.upper() in {n.upper() for n in names} or name.upper().startswith("REGION_"):
            name = f"MARKER_{mk}"
        names.append(name)
    return names


def _write_id_list(f: TextIO, ids: np.ndarray) -> None:
    """Ids (1-based), 16 per line as Abaqus wants."""
    full = len(ids) // 16 * 16
    _write_rows(f, "%d," * 15 + "%d\n", ids[:full].reshape(-1, 16))
    if full < len(ids):
        f.write(", ".join(str(int(i)) for i in ids[full:]) + "\n")


def _edge_sides(mesh: Mesh) -> tuple[np.ndarray, np.ndarray]:
    """A triangle holding every constrained edge and the edge's side in it (0: nodes 1-2,
    1: nodes 2-3, 2: nodes 3-1, Abaqus' faces S1-S3); -1 for an edge of no triangle."""
    n = max(mesh.n_points, 1)
    t = mesh.triangles.astype(np.int64)
    half = np.sort(np.stack([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]], axis=1), axis=2)
    keys = (half[..., 0] * n + half[..., 1]).ravel()  # position = 3 * triangle + side
    order = np.argsort(keys, kind="stable")
    e = np.sort(mesh.edges.astype(np.int64), axis=1)
    wanted = e[:, 0] * n + e[:, 1]
    pos = np.minimum(np.searchsorted(keys[order], wanted), max(len(keys) - 1, 0))
    hit = keys[order][pos] == wanted if len(keys) else np.zeros(len(e), bool)
    flat = np.where(hit, order[pos] if len(keys) else -1, -1)
    return np.where(hit, flat // 3, -1), np.where(hit, flat % 3, -1)


def _write_abaqus_edges(f: TextIO, mesh: Mesh, path: Path) -> None:
    """Per marker: internal element sets ``_M<marker>_S<side>``, an element-based
    ``*SURFACE`` and an ``*NSET``, both named after the marker."""
    tri, side = _edge_sides(mesh)
    if np.any(tri < 0):
        log.warning("%s: %d constrained edges are no triangle's side; no surface for them",
                    path, int((tri < 0).sum()))
    markers, order, bounds = _grouped(mesh.edge_markers)
    for i, name in enumerate(_abaqus_set_names(mesh, markers)):
        sel = order[bounds[i]:bounds[i + 1]]
        faces = []
        for s in range(3):
            ids = np.unique(tri[sel][side[sel] == s])
            if ids.size:
                faces.append(f"_M{markers[i]}_S{s + 1}")
                f.write(f"*ELSET, ELSET={faces[-1]}, INTERNAL\n")
                _write_id_list(f, ids + 1)
        if faces:
            f.write(f"*SURFACE, TYPE=ELEMENT, NAME={name}\n" + "".join(f"{s}, {s[-2:]}\n" for s in faces))
        f.write(f"*NSET, NSET={name}\n")
        _write_id_list(f, np.unique(mesh.edges[sel]) + 1)


def _write_abaqus(mesh: Mesh, path: Path, fmt: MeshFormat) -> None:
    p, t = mesh.points, mesh.triangles
    _check_ids(mesh, path, "Abaqus")
    with open(path, "w", encoding="utf-8") as f:
        f.write("*HEADING\n")
        f.write(f"hetmesh mesh: {len(p)} nodes, {len(t)} CPE3 elements\n")
        f.write("*NODE\n")
        _write_rows(f, "%d, %r, %r\n", np.column_stack([np.arange(1, len(p) + 1), p]))
        f.write("*ELEMENT, TYPE=CPE3\n")
        _write_rows(f, "%d, %d, %d, %d\n", np.column_stack([np.arange(1, len(t) + 1), t + 1]))
        regions, order, bounds = _grouped(mesh.regions)
        for i, r in enumerate(regions):
            f.write(f"*ELSET, ELSET=REGION_{r}\n")
            _write_id_list(f, order[bounds[i]:bounds[i + 1]] + 1)
        _write_abaqus_edges(f, mesh, path)


def _register_cpe3() -> None:
    """Teach meshio's Abaqus reader the CPE3 element (missing in meshio 5.3.5)."""
    table = getattr(getattr(meshio.abaqus, "_abaqus", None), "abaqus_to_meshio_type", None)
    if isinstance(table, dict):
        table.setdefault("CPE3", "triangle")
    else:  # pragma: no cover - meshio reorganised
        log.debug("meshio's Abaqus type table not found; cannot register CPE3")


_register_cpe3()


# -- registry ----------------------------------------------------------------------------

_GMSH41 = MeshFormat("gmsh41", "gmsh", {}, _write_gmsh41)
FILE_FORMATS: dict[str, MeshFormat] = {
    "vtu": MeshFormat("vtu", "vtu", {"binary": True, "compression": "zlib"}, _write_meshio),
    "vtk": MeshFormat("vtk", "vtk", {"binary": True}, _write_meshio, "vtk42"),
    "xdmf": MeshFormat("xdmf", "xdmf", {"data_format": "XML"}, _write_meshio),
    "gmsh": _GMSH41,
    "gmsh41": _GMSH41,
    "gmsh22": MeshFormat("gmsh22", "gmsh", {}, _write_gmsh22),
    "abaqus": MeshFormat("abaqus", "abaqus", {}, _write_abaqus),
    "medit": MeshFormat("medit", "medit", {}, _write_medit),
}
"""Every format by its ``file_format`` name."""

FORMATS: dict[str, MeshFormat] = {
    ext: FILE_FORMATS[name] for ext, name in [(".vtu", "vtu"), (".vtk", "vtk"), (".xdmf", "xdmf"),
                                              (".msh", "gmsh41"), (".inp", "abaqus"), (".mesh", "medit")]
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
    try:
        with atomic_path(path) as tmp:
            fmt.writer(mesh, tmp, fmt)
    except (meshio.WriteError, ValueError, TypeError) as exc:
        raise OutputError(f"cannot write {path} as {fmt.name}: {_one_line(exc)}") from exc
    log.info("wrote %s (%s: %d points, %d triangles)", path, fmt.name, mesh.n_points, mesh.n_elements)
    return path


# -- reading -----------------------------------------------------------------------------

def _blocks(m: meshio.Mesh, kind: str) -> list[int]:
    return [i for i, c in enumerate(m.cells) if c.type == kind]


def _gather(m: meshio.Mesh, name: str, blocks: list[int]) -> np.ndarray | None:
    if name not in m.cell_data or not blocks:
        return None
    return np.concatenate([np.asarray(m.cell_data[name][i]) for i in blocks])


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
        tags, inverse = np.unique(phys.astype(np.int64), return_inverse=True)
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


def _edges_from_surfaces(m: meshio.Mesh, tri: list[int], triangles: np.ndarray):
    """Edges and markers from the ``_M<marker>_S<side>`` element sets (our Abaqus files);
    the marker names from the node sets, written in the same (sorted) order."""
    edges, markers = [], []
    for name in m.cell_sets:
        match = re.fullmatch(r"_M(\d+)_S([123])", name, flags=re.IGNORECASE)
        if match:
            s = int(match.group(2)) - 1
            edges.append(triangles[_set_cells(m, name, tri)][:, [s, (s + 1) % 3]])
            markers.append(np.full(len(edges[-1]), int(match.group(1)), np.int32))
    if not edges:
        return np.zeros((0, 2), np.int32), np.zeros(0, np.int32), {}
    markers = np.concatenate(markers)
    ids = np.unique(markers).tolist()
    names = dict(zip(ids, m.point_sets)) if len(ids) == len(m.point_sets) else {}
    return np.concatenate(edges), markers, {k: v for k, v in names.items() if v != f"MARKER_{k}"}


def _read_edges(m: meshio.Mesh, tri: list[int], triangles: np.ndarray):
    """``(edges, markers, marker names)`` from line cells or Abaqus surfaces."""
    lines = _blocks(m, "line")
    if not lines:
        return _edges_from_surfaces(m, tri, triangles)
    edges = np.concatenate([m.cells[i].data for i in lines])
    for key in ("marker", "gmsh:physical", "medit:ref"):
        markers = _gather(m, key, lines)
        if markers is not None:
            break
    else:
        markers = np.ones(len(edges), np.int32)
    names = {t: s for t, s in _physical_names(m, 1).items() if s != f"marker_{t}"}
    return edges, markers.astype(np.int32), names


def read_mesh(path: str | Path) -> Mesh:
    """Read a mesh written by :func:`write_mesh` (or any triangle mesh meshio reads).

    Parameters
    ----------
    path : str or Path
        The format follows the extension (``.msh`` of either Gmsh version).

    Returns
    -------
    Mesh
        Points (x, y), the triangles, their regions (``region`` cell data, Gmsh physical
        surfaces, Medit references or Abaqus ``REGION_<id>`` sets), the edges and their
        markers and names where the format keeps them, point data and the triangles'
        cell data.

    Raises
    ------
    OutputError
        Unknown extension, missing file, unreadable content or no triangles.

    Examples
    --------
    >>> mesh = read_mesh("plate.vtu")   # doctest: +SKIP
    """
    path = Path(path)
    fmt = _resolve(path, None)
    if not path.is_file():
        raise OutputError(f"cannot read {path}: no such file")
    # the format's own reader: meshio.read() prints and calls sys.exit(1) on a bad file
    reader = getattr(meshio, fmt.meshio_format).read
    try:
        m = reader(path)
    except Exception as exc:  # malformed input surfaces as anything from ValueError to EOFError
        raise OutputError(f"cannot read {path} as {fmt.name}: {_one_line(exc)}") from exc
    tri = _blocks(m, "triangle")
    if not tri:
        raise OutputError(f"cannot read {path}: it has no triangles")
    triangles = np.concatenate([m.cells[i].data for i in tri])
    regions = _read_regions(m, tri, len(triangles))
    edges, markers, names = _read_edges(m, tri, triangles)
    cell_data = {k: _gather(m, k, tri) for k in m.cell_data
                 if k not in _RESERVED_CELL and not k.startswith(("gmsh:", "medit:"))}
    point_data = {k: np.asarray(v) for k, v in m.point_data.items() if k not in _RESERVED_POINT}
    return Mesh(np.asarray(m.points, np.float64)[:, :2], triangles, regions=regions, edges=edges,
                edge_markers=markers, point_data=point_data, cell_data=cell_data,
                marker_names=names)
