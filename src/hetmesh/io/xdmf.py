"""XDMF in the layout dolfinx writes and reads: ``file.xdmf`` beside its ``file.h5``.

``dolfinx.io.XDMFFile.write_mesh`` and ``write_meshtags`` write one grid per object, the
tags' grids sharing the mesh's geometry through an XPointer; ``read_mesh(name="mesh")``
and ``read_meshtags(mesh, name="cell_tags")`` / ``name="facet_tags"`` read them back.
hetmesh writes exactly that, and nothing padded:

- ``Grid "mesh"``: ``Triangle`` topology (``/Mesh/mesh/topology``, ``(M, 3)`` int64 node
  indices) and ``XY`` geometry (``/Mesh/mesh/geometry``, ``(N, 2)`` float64); the point
  data as ``Center="Node"`` and the cell data (delta, quality, material properties, mean
  composition, ...) as ``Center="Cell"`` attributes (``/Mesh/mesh/<Node|Cell>/<name>``);
- ``Grid "cell_tags"``: the triangles again, attribute ``cell_tags`` = the region;
- ``Grid "facet_tags"``: the boundary and interface edges as a ``PolyLine`` topology
  (2 nodes each), attribute ``facet_tags`` = the group tag of the edge's curve name
  (:func:`hetmesh.io.groups.curve_groups`), one ``<Information Name=<name> Value=<tag>>``
  per name, and ``marker``, the edge's own marker;
- ``Grid "point_tags"`` (named points only): ``Polyvertex`` topology, attribute
  ``point_tags`` = 1, 2, ... in the order of ``mesh.named_points``, named likewise.

The tags' grids include the mesh's ``Geometry`` by
``xpointer(/Xdmf/Domain/Grid[@GridType='Uniform'][@Name='mesh']/Geometry)``, as dolfinx
does. :func:`read_xdmf` reads this layout (ElementTree + h5py).
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path
from typing import TYPE_CHECKING

import h5py
import numpy as np

from ..errors import OutputError
from .atomic import atomic_path
from .groups import curve_groups

if TYPE_CHECKING:  # the writers take any mesh with Mesh's attributes
    from ..mesh import Mesh

__all__ = ["write_xdmf", "read_xdmf", "GEOMETRY_XPOINTER"]

GEOMETRY_XPOINTER = "xpointer(/Xdmf/Domain/Grid[@GridType='Uniform'][@Name='mesh']/Geometry)"
_XI = "http://www.w3.org/2001/XInclude"


def _item(parent: ET.Element, h5name: str, h5: h5py.File, key: str, data: np.ndarray
          ) -> None:
    data = np.ascontiguousarray(data)
    h5.create_dataset(key, data=data)
    kind = "Int" if np.issubdtype(data.dtype, np.integer) else "Float"
    precision = str(data.dtype.itemsize)
    item = ET.SubElement(parent, "DataItem", Dimensions=" ".join(map(str, data.shape)),
                         NumberType=kind, Precision=precision, Format="HDF")
    item.text = f"{h5name}:{key}"


def _attribute(grid: ET.Element, h5name: str, h5: h5py.File, key: str, name: str,
               values: np.ndarray, center: str) -> None:
    v = np.asarray(values)
    if v.dtype == bool:
        v = v.astype(np.int8)
    kind = "Scalar" if v.ndim == 1 else "Vector" if v.shape[1] in (2, 3) else "Matrix"
    if kind == "Vector" and v.shape[1] == 2:
        v = np.column_stack([v, np.zeros(len(v), v.dtype)])
    attr = ET.SubElement(grid, "Attribute", Name=name, AttributeType=kind, Center=center)
    _item(attr, h5name, h5, key, v)


def _tag_grid(domain: ET.Element, h5name: str, h5: h5py.File, name: str, kind: str,
              cells: np.ndarray, values: np.ndarray, names: dict[str, int] | None = None
              ) -> ET.Element:
    grid = ET.SubElement(domain, "Grid", Name=name, GridType="Uniform")
    ET.SubElement(grid, f"{{{_XI}}}include", xpointer=GEOMETRY_XPOINTER)
    topo = ET.SubElement(grid, "Topology", TopologyType=kind,
                         NumberOfElements=str(len(cells)), NodesPerElement=str(cells.shape[1]))
    _item(topo, h5name, h5, f"/MeshTags/{name}/topology", cells.astype(np.int64))
    attr = ET.SubElement(grid, "Attribute", Name=name, AttributeType="Scalar", Center="Cell")
    _item(attr, h5name, h5, f"/MeshTags/{name}/Values", values.astype(np.int32))
    for k, v in (names or {}).items():
        ET.SubElement(grid, "Information", Name=k, Value=str(v))
    return grid


def write_xdmf(mesh: Mesh, path: Path) -> Path:
    """Write ``path`` (``.xdmf``) and ``path.with_suffix(".h5")``, each atomically (the
    ``.h5`` first, so a finished ``.xdmf`` never points at a missing file)."""
    path = Path(path)
    h5path = path.with_suffix(".h5")
    ET.register_namespace("xi", _XI)
    root = ET.Element("Xdmf", Version="3.0")
    domain = ET.SubElement(root, "Domain")
    with atomic_path(h5path) as tmp:
        with h5py.File(tmp, "w") as h5:
            name = h5path.name
            grid = ET.SubElement(domain, "Grid", Name="mesh", GridType="Uniform")
            cell = "Tetrahedron" if mesh.dim == 3 else "Triangle"
            facet = "Triangle" if mesh.dim == 3 else "PolyLine"
            topo = ET.SubElement(grid, "Topology", TopologyType=cell,
                                 NumberOfElements=str(mesh.n_elements),
                                 NodesPerElement=str(mesh.dim + 1))
            _item(topo, name, h5, "/Mesh/mesh/topology", mesh.cells.astype(np.int64))
            geo = ET.SubElement(grid, "Geometry", GeometryType="XYZ" if mesh.dim == 3 else "XY")
            _item(geo, name, h5, "/Mesh/mesh/geometry", np.asarray(mesh.points, np.float64))
            for k, v in mesh.point_data.items():
                _attribute(grid, name, h5, f"/Mesh/mesh/Node/{k}", k, v, "Node")
            for k, v in mesh.cell_data.items():
                _attribute(grid, name, h5, f"/Mesh/mesh/Cell/{k}", k, v, "Cell")
            _tag_grid(domain, name, h5, "cell_tags", cell, mesh.cells, mesh.regions)
            if len(mesh.edges):
                groups = curve_groups(mesh)
                tag_of = {m: g.tag for g in groups for m in g.markers}
                values = np.array([tag_of[int(m)] for m in mesh.edge_markers], np.int32)
                g = _tag_grid(domain, name, h5, "facet_tags", facet, mesh.edges, values,
                              {gr.name: gr.tag for gr in groups})
                _attribute(g, name, h5, "/MeshTags/facet_tags/marker", "marker",
                           mesh.edge_markers.astype(np.int32), "Cell")
            if mesh.named_points:
                nodes = np.array(list(mesh.named_points.values()), np.int64)[:, None]
                _tag_grid(domain, name, h5, "point_tags", "Polyvertex", nodes,
                          np.arange(1, len(nodes) + 1),
                          {k: i + 1 for i, k in enumerate(mesh.named_points)})
    ET.indent(root)
    text = '<?xml version="1.0"?>\n<!DOCTYPE Xdmf SYSTEM "Xdmf.dtd" []>\n' + \
        ET.tostring(root, encoding="unicode") + "\n"
    with atomic_path(path) as tmp:
        Path(tmp).write_text(text, encoding="utf-8")
    return path


def _data(item: ET.Element, base: Path) -> np.ndarray:
    fmt = item.get("Format", "XML")
    if fmt == "HDF":
        file, key = item.text.strip().split(":", 1)
        with h5py.File(base / file, "r") as h5:
            return np.asarray(h5[key])
    shape = tuple(int(s) for s in item.get("Dimensions", "").split())
    kind = np.int64 if item.get("NumberType", "Float") in ("Int", "UInt") else np.float64
    return np.array(item.text.split(), kind).reshape(shape)


def read_xdmf(path: Path) -> dict | None:
    """Read the layout of :func:`write_xdmf`; None if ``path`` has no grid named ``mesh``
    (then it is some other XDMF file)."""
    path = Path(path)
    try:
        root = ET.parse(path).getroot()
    except ET.ParseError as exc:
        raise OutputError(f"cannot read {path}: {exc}") from exc
    grids = {g.get("Name"): g for g in root.iter("Grid")}
    if "mesh" not in grids:
        return None
    base = path.parent
    g = grids["mesh"]
    t = _data(g.find("Topology/DataItem"), base)
    p = _data(g.find("Geometry/DataItem"), base)
    pd, cd = {}, {}
    for a in g.findall("Attribute"):
        v = _data(a.find("DataItem"), base)
        if a.get("AttributeType") == "Vector" and v.shape[1] == 3 and not v[:, 2].any():
            v = v[:, :2]
        (pd if a.get("Center") == "Node" else cd)[a.get("Name")] = v
    regions = None
    if "cell_tags" in grids:
        regions = _data(grids["cell_tags"].find("Attribute/DataItem"), base).ravel()
    edges, markers, names = None, None, {}
    if "facet_tags" in grids:
        f = grids["facet_tags"]
        edges = _data(f.find("Topology/DataItem"), base)
        attrs = {a.get("Name"): _data(a.find("DataItem"), base).ravel()
                 for a in f.findall("Attribute")}
        markers = attrs.get("marker", attrs["facet_tags"])
        tag = {int(i.get("Value")): i.get("Name") for i in f.findall("Information")}
        names = {int(m): tag[int(v)] for m, v in zip(markers, attrs["facet_tags"])
                 if int(v) in tag and tag[int(v)] != f"marker_{v}"}
    named = {}
    if "point_tags" in grids:
        f = grids["point_tags"]
        nodes = _data(f.find("Topology/DataItem"), base).ravel()
        label = {int(i.get("Value")): i.get("Name") for i in f.findall("Information")}
        vals = _data(f.find("Attribute/DataItem"), base).ravel()
        named = {label.get(int(v), f"point_{v}"): int(n) for n, v in zip(nodes, vals)}
    xyz = g.find("Geometry").get("GeometryType") == "XYZ" and t.shape[1] == 4
    return dict(points=p if xyz else p[:, :2], cells=t, regions=regions, facets=edges,
                facet_markers=markers,
                point_data=pd, cell_data=cd, marker_names=names, named_points=named)
