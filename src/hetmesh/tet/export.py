"""The Gmsh and Abaqus writers of tetrahedral meshes, called by
:func:`hetmesh.io.export.write_mesh` for 3D meshes (which writes atomically):

* ``.msh`` (Gmsh 4.1; ``file_format="gmsh22"`` for 2.2, through meshio): a physical volume
  ``"solid"`` (or ``region_<r>`` per region) and one physical surface per named face (tag
  :data:`FACE_TAG` + its marker), each name once; the tetrahedra first, element ``j + 1``
  being tetrahedron ``j`` (one region) or numbered region by region; the mesh's float cell
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

__all__ = ["write_tet_file", "FACE_TAG"]

#: physical tag of a face in .msh files: FACE_TAG + its marker
FACE_TAG = 100


def _meshio_3d(mesh, fmt: str):
    """A 3D :class:`~hetmesh.mesh.Mesh` as a meshio mesh for Gmsh (``"gmsh"`` 4.1,
    ``"gmsh22"``), and the element tag of every tetrahedron ``(M,)``."""
    import meshio

    pts = np.asarray(mesh.points, dtype=np.float64)
    tets = np.asarray(mesh.cells, dtype=np.int64)
    faces = np.asarray(mesh.facets, dtype=np.int64)
    fm = np.asarray(mesh.facet_markers, np.int64)
    reg = np.asarray(mesh.regions, dtype=np.int64)
    names = dict(mesh.marker_names)
    many = len(np.unique(reg)) > 1
    # one cell block per physical group: the volume's (or each region's), then one per
    # named face
    cells, phys, geom = [], [], []
    tags = np.empty(len(tets), np.int64)
    start = 1
    for r in np.unique(reg):
        sel = np.flatnonzero(reg == r)
        tags[sel] = np.arange(start, start + len(sel))
        start += len(sel)
        cells.append(("tetra", tets[sel]))
        phys.append(np.full(len(sel), r + 1, dtype=np.int64))
        geom.append(phys[-1])
    for m in np.unique(fm):
        cells.append(("triangle", faces[fm == m]))
        phys.append(np.full(int((fm == m).sum()), m + FACE_TAG, dtype=np.int64))
        geom.append(np.full(int((fm == m).sum()), m, dtype=np.int64))
    field_data = {}
    for r in np.unique(reg):
        field_data[f"region_{r}" if many else "solid"] = np.array([r + 1, 3])
    for m in np.unique(fm):
        field_data[names.get(int(m), f"face_{m}")] = np.array([m + FACE_TAG, 2])
    point_data = {}
    if fmt == "gmsh":  # 4.1: every node on one entity (a face, else the volume)
        dim_tags = np.zeros((len(pts), 2), dtype=np.int64)
        dim_tags[:, 0] = 3
        dim_tags[tets.ravel(), 1] = np.repeat(reg + 1, 4)
        order = np.argsort(-fm, kind="stable")  # the smallest marker written last wins
        dim_tags[faces[order].ravel(), 0] = 2
        dim_tags[faces[order].ravel(), 1] = np.repeat(fm[order], 3)
        point_data["gmsh:dim_tags"] = dim_tags
    return meshio.Mesh(pts, cells, point_data=point_data,
                       cell_data={"gmsh:physical": phys, "gmsh:geometrical": geom},
                       field_data=field_data), tags


def _write_data(f, mesh, tags: np.ndarray, path) -> None:
    """``$NodeData`` of the point data and ``$ElementData`` of the cell data: the
    tetrahedra's values, then the face triangles' padding (:func:`~hetmesh.io.textio.
    float_pad`, as the 2D writer pads its lines) so that every element has a value, as
    meshio's reader requires."""
    from ..io.gmsh_msh import write_data
    from ..io.textio import float_pad

    k = len(mesh.facets)
    tri_tags = np.arange(len(tags) + 1, len(tags) + k + 1)

    from ..io.gmsh_msh import msh41_order

    nodes = msh41_order(path)[0]  # rows in the file's node order, as meshio reads them
    for name, v in mesh.point_data.items():
        if np.asarray(v).dtype.kind in "fiub":
            write_data(f, "NodeData", name, nodes, np.asarray(v)[nodes - 1], path)
    order = np.argsort(tags)
    for name, v in mesh.cell_data.items():
        if np.asarray(v).dtype.kind in "fiub":
            v = np.asarray(v)
            write_data(f, "ElementData", name, np.concatenate([tags[order], tri_tags]),
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
    m, tags = _meshio_3d(mesh, fmt)
    meshio.write(path, m, file_format=fmt, binary=False)
    if fmt == "gmsh":
        extra = io.StringIO()
        _write_data(extra, mesh, tags, path)
        with open(path, "a", encoding="ascii") as fh:
            fh.write(extra.getvalue())
