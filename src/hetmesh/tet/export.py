"""The Gmsh and Abaqus writers of tetrahedral meshes, called by
:func:`hetmesh.io.export.write_mesh` for 3D meshes (which writes atomically):

* ``.msh`` (Gmsh 4.1; ``file_format="gmsh22"`` for 2.2, through meshio): a physical volume
  ``"solid"`` (or ``region_<r>`` per region) and one physical surface per named face (tag
  :data:`FACE_TAG` + the smallest marker of its name), each name once; the tetrahedra
  first, element ``j + 1`` being tetrahedron ``j`` as in every other format; the cell
  data (the graded material of :mod:`hetmesh.io.material`, delta, quality) as
  ``$ElementData`` (4.1 only; the face triangles padded as in 2D), point data as
  ``$NodeData``;
* ``.inp`` (Abaqus, :mod:`hetmesh.io.abaqus3d`): ``C3D4`` elements, an element set per
  region, a node set and an element-based ``*SURFACE`` per named face.

``.vtu``, ``.vtk``, ``.mesh`` and ``.xdmf`` are written by the shared writers of
:mod:`hetmesh.io.export` and :mod:`hetmesh.io.xdmf`.
"""

from __future__ import annotations

import io

import numpy as np

from ..topology import unique

__all__ = ["write_tet_file", "FACE_TAG"]

#: physical tag of a face in .msh files: FACE_TAG + its marker
FACE_TAG = 100


def _meshio_3d(mesh, fmt: str):
    """A 3D :class:`~hetmesh.mesh.Mesh` as a meshio mesh for Gmsh (``"gmsh"`` 4.1,
    ``"gmsh22"``): one tetrahedron block per region (physical volume ``region + 1``), one
    triangle block per face marker (geometrical tag the marker, physical tag
    :data:`FACE_TAG` + the smallest marker of its name, :func:`~hetmesh.io.groups.
    curve_groups`). Also returns ``order`` ``(M,)``: the tetrahedra in the file's order."""
    import meshio

    from ..io.groups import curve_groups

    pts = np.asarray(mesh.points, dtype=np.float64)
    tets = np.asarray(mesh.cells, dtype=np.int64)
    faces = np.asarray(mesh.facets, dtype=np.int64)
    fm = np.asarray(mesh.facet_markers, np.int64)
    reg = np.asarray(mesh.regions, dtype=np.int64)
    groups = curve_groups(mesh)
    group_of = {m: g for g in groups for m in g.markers}
    many = len(unique(reg)) > 1
    cells, phys, geom, order = [], [], [], []
    for r in unique(reg):
        sel = np.flatnonzero(reg == r)
        order.append(sel)
        cells.append(("tetra", tets[sel]))
        phys.append(np.full(len(sel), r + 1, dtype=np.int64))
        geom.append(phys[-1])
    for m in unique(fm):
        k = int((fm == m).sum())
        cells.append(("triangle", faces[fm == m]))
        phys.append(np.full(k, group_of[int(m)].tag + FACE_TAG, dtype=np.int64))
        geom.append(np.full(k, m, dtype=np.int64))
    field_data = {}
    for r in unique(reg):
        field_data[f"region_{r}" if many else "solid"] = np.array([r + 1, 3])
    for g in groups:
        field_data[g.name] = np.array([g.tag + FACE_TAG, 2])
    point_data = {}
    if fmt == "gmsh":  # 4.1: every node on one entity (a face, else the volume)
        dim_tags = np.zeros((len(pts), 2), dtype=np.int64)
        dim_tags[:, 0] = 3
        dim_tags[tets.ravel(), 1] = np.repeat(reg + 1, 4)
        rank = np.argsort(-fm, kind="stable")  # the smallest marker written last wins
        dim_tags[faces[rank].ravel(), 0] = 2
        dim_tags[faces[rank].ravel(), 1] = np.repeat(fm[rank], 3)
        point_data["gmsh:dim_tags"] = dim_tags
    return meshio.Mesh(pts, cells, point_data=point_data,
                       cell_data={"gmsh:physical": phys, "gmsh:geometrical": geom},
                       field_data=field_data), np.concatenate(order)


def _renumber_tets(text: str, order: np.ndarray) -> str:
    """Give the tetrahedra of a meshio-written MSH 4.1 text the tags ``order + 1`` (file
    order), so element ``j + 1`` is tetrahedron ``j`` as in every other format (meshio
    numbers elements by block, and blocks go region by region)."""
    head, sep, rest = text.partition("$Elements\n")
    body, end, tail = rest.partition("$EndElements\n")
    lines = body.split("\n")
    out = [lines[0]]
    i, k = 1, 0
    new = (order + 1).tolist()
    while i < len(lines) and lines[i]:
        dim, tag, kind, count = (int(x) for x in lines[i].split())
        out.append(lines[i])
        rows = lines[i + 1:i + 1 + count]
        if kind == 4:  # tetrahedra
            rows = [f"{new[k + j]} {r.split(None, 1)[1]}" for j, r in enumerate(rows)]
            k += count
        out.extend(rows)
        i += 1 + count
    out.extend(lines[i:])
    return head + sep + "\n".join(out) + end + tail


def _write_data(f, mesh, order: np.ndarray, path, text: str) -> None:
    """``$NodeData`` of the point data and ``$ElementData`` of the cell data, rows in the
    file's order (as meshio reads them): the tetrahedra (``order``, tags ``order + 1``),
    then the face triangles' padding (:func:`~hetmesh.io.textio.float_pad`, as the 2D
    writer pads its lines) so that every element has a value, as meshio requires."""
    from ..io.gmsh_msh import msh41_order, write_data
    from ..io.textio import float_pad

    nodes = msh41_order(io.StringIO(text))[0]
    for name, v in mesh.point_data.items():
        if np.asarray(v).dtype.kind in "fiub":
            write_data(f, "NodeData", name, nodes, np.asarray(v)[nodes - 1], path)
    k = len(mesh.facets)
    tags = np.concatenate([order + 1, np.arange(len(order) + 1, len(order) + k + 1)])
    for name, v in mesh.cell_data.items():
        if np.asarray(v).dtype.kind in "fiub":
            v = np.asarray(v)
            write_data(f, "ElementData", name, tags,
                       np.concatenate([v[order].astype(np.float64), float_pad(v, k)]), path)


def write_tet_file(mesh, path, fmt: str) -> None:
    """Write a 3D :class:`~hetmesh.mesh.Mesh` to ``path`` as ``fmt`` (``"gmsh"``,
    ``"gmsh22"`` or ``"abaqus"``); not atomic by itself (:func:`hetmesh.io.export.write_mesh`
    calls it on a temporary file)."""
    import meshio

    if fmt == "abaqus":
        from ..io.abaqus3d import write_inp3d

        write_inp3d(mesh, path)
        return
    m, order = _meshio_3d(mesh, fmt)
    meshio.write(path, m, file_format=fmt, binary=False)
    if fmt == "gmsh":
        with open(path, encoding="ascii") as fh:
            text = _renumber_tets(fh.read(), order)
        extra = io.StringIO()
        _write_data(extra, mesh, order, path, text)
        with open(path, "w", encoding="ascii") as fh:
            fh.write(text + extra.getvalue())
