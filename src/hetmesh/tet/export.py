"""Writing tetrahedral meshes (through meshio, atomically).

Cells: the tetrahedra (``tetra``) and the boundary triangles (``triangle``, their face marker
as cell data ``face``). Point data: the composition, one array per constituent. Cell data of
the tetrahedra: ``delta`` and, for extruded feature-tree models, ``subregion``.

* ``.vtu`` / ``.vtk``: all of the above;
* ``.msh`` (Gmsh 4.1; ``file_format="gmsh22"`` for 2.2): physical volume 1 ``"solid"`` (or
  one per subregion) and one physical surface per named face (tag = marker), with names;
* ``.xdmf``: the tetrahedra with their point and cell data;
* ``.inp`` (Abaqus): ``C3D4`` elements, an element set per subregion and a node set per face.
"""

from __future__ import annotations

import numpy as np

from ..errors import OutputError
from ..io.atomic import atomic_path

__all__ = ["write_tets", "TET_FORMATS"]

#: extension -> meshio format name
TET_FORMATS = {".vtu": "vtu", ".vtk": "vtk", ".msh": "gmsh", ".xdmf": "xdmf", ".inp": "abaqus"}
_NAMED = {"vtu": "vtu", "vtk": "vtk", "gmsh": "gmsh", "gmsh41": "gmsh", "gmsh22": "gmsh22",
          "xdmf": "xdmf", "abaqus": "abaqus"}


def _meshio_mesh(res, constituents, fmt: str):
    import meshio

    pts = np.asarray(res.points, dtype=np.float64)
    tets = np.asarray(res.tets, dtype=np.int64)
    faces = np.asarray(res.faces, dtype=np.int64)
    comp = res.info.get("composition")
    point_data = {}
    if comp is not None:
        for j, c in enumerate(constituents):
            point_data[c] = np.ascontiguousarray(comp[:, j])
    regions = res.info.get("regions")
    reg = (np.zeros(len(tets), dtype=np.int64) if regions is None
           else np.asarray(regions, dtype=np.int64))
    fm = np.asarray(res.face_markers, np.int64)
    if fmt in ("gmsh", "gmsh22"):
        # one cell block per physical group: the volume's (or each subregion's), then
        # one per named face
        cells, phys, geom = [], [], []
        for r in np.unique(reg):
            cells.append(("tetra", tets[reg == r]))
            phys.append(np.full(int((reg == r).sum()), r + 1, dtype=np.int64))
            geom.append(phys[-1])
        for m in np.unique(fm):
            cells.append(("triangle", faces[fm == m]))
            phys.append(np.full(int((fm == m).sum()), m + 100, dtype=np.int64))
            geom.append(np.full(int((fm == m).sum()), m, dtype=np.int64))
        field_data = {}
        for r in np.unique(reg):
            field_data["solid" if regions is None else f"subregion_{r}"] = np.array([r + 1, 3])
        for m, name in enumerate(res.face_names, start=1):
            if (fm == m).any():
                field_data[name] = np.array([m + 100, 2])
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
    if fmt == "abaqus":
        cell_sets = {}
        for r in np.unique(reg):
            cell_sets[f"SUBREGION_{r}" if regions is not None else "SOLID"] = \
                [np.flatnonzero(reg == r)]
        m = meshio.Mesh(pts, [("tetra", tets)], cell_sets=cell_sets)
        m.point_sets = {name.upper(): np.unique(faces[fm == k])
                        for k, name in enumerate(res.face_names, start=1) if (fm == k).any()}
        return m
    cell_data = {"delta": [np.asarray(res.delta, dtype=np.float64)]}
    cells = [("tetra", tets)]
    if regions is not None:
        cell_data["subregion"] = [reg]
    if fmt in ("vtu", "vtk"):
        cells.append(("triangle", faces))
        cell_data = {k: v + [np.zeros(len(faces), dtype=v[0].dtype)]
                     for k, v in cell_data.items()}
        cell_data["face"] = [np.zeros(len(tets), dtype=np.int64),
                             np.asarray(res.face_markers, dtype=np.int64)]
    return meshio.Mesh(pts, cells, point_data=point_data, cell_data=cell_data)


def write_tets(res, path, constituents, *, file_format: str | None = None):
    """Write a :class:`~hetmesh.tet.mesher.TetResult` to ``path`` (format from the
    extension, or ``file_format``); returns the path."""
    from pathlib import Path

    import meshio

    p = Path(path)
    if file_format is not None:
        if file_format.lower() not in _NAMED:
            raise OutputError(f"{p}: unknown format {file_format!r} for a tetrahedral mesh "
                              f"(known: {', '.join(sorted(_NAMED))})")
        fmt = _NAMED[file_format.lower()]
    else:
        ext = p.suffix.lower()
        if ext not in TET_FORMATS:
            raise OutputError(f"{p}: unknown mesh format {ext or '(no extension)'!r} for a "
                              f"tetrahedral mesh (known: {', '.join(sorted(TET_FORMATS))})")
        fmt = TET_FORMATS[ext]
    m = _meshio_mesh(res, constituents, fmt)
    kw = {"binary": False} if fmt in ("gmsh", "gmsh22") else {}
    if fmt == "vtu":
        kw = {"binary": True, "compression": "zlib"}
    with atomic_path(p) as tmp:
        if fmt == "xdmf":
            meshio.write(tmp, m, file_format="xdmf", data_format="XML")  # no .h5 beside it
        else:
            meshio.write(tmp, m, file_format=fmt, **kw)
        if fmt == "abaqus":
            with open(tmp, "a", encoding="ascii") as fh:
                fh.write(_abaqus_surfaces(res))
    return p


#: Abaqus C3D4 face of the face opposite local vertex k (0-based): S3, S4, S2, S1
_ABAQUS_FACE = ("S3", "S4", "S2", "S1")


def _abaqus_surfaces(res) -> str:
    """``*SURFACE`` (element-based) per named face: element sets by local face number."""
    from .verify import boundary_faces

    faces, _, rows = boundary_faces(np.asarray(res.tets), owners=True)
    key = np.sort(faces, axis=1)
    mk = np.asarray(res.face_markers)
    # the markers follow res.faces; map them onto these rows by face key
    rk = np.sort(np.asarray(res.faces), axis=1)
    order = np.lexsort(rk.T[::-1])
    pos = np.lexsort(key.T[::-1])
    marker = np.empty(len(rows), dtype=np.int64)
    marker[pos] = mk[order]
    out = []
    for m, name in enumerate(res.face_names, start=1):
        sel = marker == m
        if not sel.any():
            continue
        parts = []
        for k in range(4):
            e = rows[sel][rows[sel] % 4 == k] // 4 + 1
            if not len(e):
                continue
            set_name = f"_S_{name.upper()}_{_ABAQUS_FACE[k]}"
            out.append(f"*ELSET, ELSET={set_name}\n")
            for i in range(0, len(e), 16):
                out.append(", ".join(str(int(v)) for v in e[i:i + 16]) + "\n")
            parts.append(f"{set_name}, {_ABAQUS_FACE[k]}\n")
        out.append(f"*SURFACE, NAME={name.upper()}, TYPE=ELEMENT\n")
        out.extend(parts)
    return "".join(out)
