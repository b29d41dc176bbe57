"""The Gmsh and Abaqus writers of tetrahedral meshes (through meshio), called by
:func:`hetmesh.io.export.write_mesh` for 3D meshes (which writes atomically):

* ``.msh`` (Gmsh 4.1; ``file_format="gmsh22"`` for 2.2): a physical volume ``"solid"`` (or
  ``region_<r>`` per region) and one physical surface per named face (tag
  :data:`FACE_TAG` + its marker), with names;
* ``.inp`` (Abaqus): ``C3D4`` elements, an element set per region, a node set and an
  element-based ``*SURFACE`` per named face.

``.vtu``, ``.vtk``, ``.mesh`` and ``.xdmf`` are written by the shared writers of
:mod:`hetmesh.io.export` and :mod:`hetmesh.io.xdmf`.
"""

from __future__ import annotations

import numpy as np

__all__ = ["write_tet_file", "FACE_TAG"]

#: physical tag of a face in .msh files: FACE_TAG + its marker
FACE_TAG = 100

#: Abaqus C3D4 face of the face opposite local vertex k (0-based): S3, S4, S2, S1
_ABAQUS_FACE = ("S3", "S4", "S2", "S1")


def _meshio_3d(mesh, fmt: str):
    """A 3D :class:`~hetmesh.mesh.Mesh` as a meshio mesh for Gmsh (``"gmsh"`` 4.1,
    ``"gmsh22"``) or Abaqus (``"abaqus"``)."""
    import meshio

    pts = np.asarray(mesh.points, dtype=np.float64)
    tets = np.asarray(mesh.cells, dtype=np.int64)
    faces = np.asarray(mesh.facets, dtype=np.int64)
    fm = np.asarray(mesh.facet_markers, np.int64)
    reg = np.asarray(mesh.regions, dtype=np.int64)
    names = dict(mesh.marker_names)
    many = len(np.unique(reg)) > 1
    if fmt in ("gmsh", "gmsh22"):
        # one cell block per physical group: the volume's (or each region's), then one per
        # named face
        cells, phys, geom = [], [], []
        for r in np.unique(reg):
            cells.append(("tetra", tets[reg == r]))
            phys.append(np.full(int((reg == r).sum()), r + 1, dtype=np.int64))
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
                           field_data=field_data)
    cell_sets = {(f"REGION_{r}" if many else "SOLID"): [np.flatnonzero(reg == r)]
                 for r in np.unique(reg)}
    m = meshio.Mesh(pts, [("tetra", tets)], cell_sets=cell_sets)
    m.point_sets = {names.get(int(k), f"face_{k}").upper(): np.unique(faces[fm == k])
                    for k in np.unique(fm)}
    return m


def write_tet_file(mesh, path, fmt: str) -> None:
    """Write a 3D :class:`~hetmesh.mesh.Mesh` to ``path`` as ``fmt`` (``"gmsh"``,
    ``"gmsh22"`` or ``"abaqus"``); not atomic by itself (:func:`hetmesh.io.export.write_mesh`
    calls it on a temporary file)."""
    import meshio

    m = _meshio_3d(mesh, fmt)
    if fmt == "abaqus":
        meshio.write(path, m, file_format="abaqus")
        with open(path, "a", encoding="ascii") as fh:
            fh.write(_abaqus_surfaces(mesh))
    else:
        meshio.write(path, m, file_format=fmt, binary=False)


def _abaqus_surfaces(mesh) -> str:
    """``*SURFACE`` (element-based) per named face: element sets by local face number."""
    from .faces import boundary_faces

    tets = np.asarray(mesh.cells)
    faces, _, rows = boundary_faces(tets, owners=True)
    if not len(mesh.facets) or not len(faces):
        return ""
    n = len(mesh.points) + 1

    def keys(f):
        f = np.sort(np.asarray(f, np.int64), axis=1)
        return (f[:, 0] * n + f[:, 1]) * n + f[:, 2]

    fk = keys(mesh.facets)
    order = np.argsort(fk)
    bk = keys(faces)
    pos = np.minimum(np.searchsorted(fk[order], bk), len(fk) - 1)
    hit = fk[order][pos] == bk
    marker = np.where(hit, np.asarray(mesh.facet_markers)[order][pos], -1)
    names = dict(mesh.marker_names)
    out = []
    for m in np.unique(marker[marker > 0]):
        name = names.get(int(m), f"face_{m}").upper()
        sel = marker == m
        parts = []
        for k in range(4):
            e = rows[sel][rows[sel] % 4 == k] // 4 + 1
            if not len(e):
                continue
            set_name = f"_S_{name}_{_ABAQUS_FACE[k]}"
            out.append(f"*ELSET, ELSET={set_name}\n")
            for i in range(0, len(e), 16):
                out.append(", ".join(str(int(v)) for v in e[i:i + 16]) + "\n")
            parts.append(f"{set_name}, {_ABAQUS_FACE[k]}\n")
        out.append(f"*SURFACE, NAME={name}, TYPE=ELEMENT\n")
        out.extend(parts)
    return "".join(out)
