"""Abaqus / CalculiX input files of tetrahedral meshes, and their analysis decks.

The mesh (:func:`write_inp_mesh3d`): nodes (every real in at most 20 characters,
:func:`hetmesh.io.abaqus.format_reals`), ``C3D4`` elements (``C3D10`` with ``order=2``,
the mid-edge nodes at the midpoints of the straight edges, numbered after the mesh's nodes
in Abaqus' order 1-2, 2-3, 3-1, 1-4, 2-4, 3-4), ``*ELSET, ELSET=REGION_<r>`` per region
and, per face name (one set for all the markers of a name), an ``*NSET`` of its nodes and
an element-based ``*SURFACE`` on internal element sets ``_F<marker>_S<k>``. Faces follow
the Abaqus manual's numbering of the tetrahedron: S1 = nodes 1-2-3, S2 = 1-4-2,
S3 = 2-4-3, S4 = 3-4-1. Element ids are the tetrahedron indices + 1, node ids the node
indices + 1, as in every other format; an element whose corners 1-2-3 turn clockwise seen
from node 4 (negative volume in Abaqus' convention) is written with nodes 1 and 2
swapped.

The deck (:func:`write_deck3d`): the mesh in SI units, the graded material binned by
composition (:mod:`hetmesh.io.material`) and, for a model whose ``[fea]`` table has
conditions, the analysis of :func:`hetmesh.fea.solve` on the same mesh: the node sets of
the conditions found as ``hetmesh fea`` finds them (the vertices of the named faces, edges
or point, with the mid-edge nodes of the boundary edges between two of them),
``*INITIAL CONDITIONS`` at the reference temperature, a steady ``*HEAT TRANSFER`` step when
temperatures are fixed (CalculiX; Abaqus gets one ``*COUPLED TEMPERATURE-DISPLACEMENT``
step on ``C3D4T``/``C3D10MT``), then ``*STATIC`` with the displacements (dofs 1-3) and the
pressures (``*DLOAD``, ``P<k>`` on each element face of the pressed faces).
"""

from __future__ import annotations

import logging
from pathlib import Path
from typing import TYPE_CHECKING, TextIO

import numpy as np

from ..errors import OutputError
from ..topology import unique
from . import textio
from .abaqus import (
    DISTRIBUTION,
    abaqus_name,
    format_reals,
    write_distribution,
    write_id_list,
    write_materials,
)
from .atomic import atomic_write

if TYPE_CHECKING:
    from ..mesh import Mesh

__all__ = ["FACE_OF_VERTEX", "TET_EDGES", "tet_element_type", "oriented", "face_sides",
           "quadratic_nodes3d", "write_inp_mesh3d", "write_inp3d", "write_deck3d"]

log = logging.getLogger(__name__)

#: Abaqus face number (1-4) of the face opposite local vertex k (0-based)
FACE_OF_VERTEX = (3, 4, 2, 1)

#: the corners of each Abaqus face S1..S4 (local, 0-based)
FACE_NODES = ((0, 1, 2), (0, 3, 1), (1, 3, 2), (2, 3, 0))

#: local vertex pairs of the six mid-edge nodes of a C3D10, in Abaqus' order (nodes 5-10)
TET_EDGES = ((0, 1), (1, 2), (2, 0), (0, 3), (1, 3), (2, 3))


def tet_element_type(order: int = 1) -> str:
    """``C3D4`` or ``C3D10``."""
    if order not in (1, 2):
        raise OutputError(f"no Abaqus tetrahedron of order {order!r}")
    return "C3D4" if order == 1 else "C3D10"


def oriented(points: np.ndarray, tets: np.ndarray) -> np.ndarray:
    """``tets`` with nodes 1 and 2 swapped where ``(x2 - x1) x (x3 - x1) . (x4 - x1) < 0``
    (Abaqus wants it positive)."""
    tets = np.array(tets, dtype=np.int64)
    a, b, c, d = (points[tets[:, k]] for k in range(4))
    neg = np.einsum("ij,ij->i", np.cross(b - a, c - a), d - a) < 0
    tets[neg, 0], tets[neg, 1] = tets[neg, 1], tets[neg, 0].copy()
    return tets


def face_sides(tets: np.ndarray, faces: np.ndarray, n_points: int
               ) -> tuple[np.ndarray, np.ndarray]:
    """For every triangle of ``faces`` ``(F, 3)``: a tetrahedron holding it and its Abaqus
    face number (1-4); ``(-1, -1)`` for a triangle of no tetrahedron."""
    n = np.int64(max(n_points, 1))

    def keys(tri):
        s = np.sort(np.asarray(tri, np.int64), axis=1)
        return (s[:, 0] * n + s[:, 1]) * n + s[:, 2]

    tk = np.concatenate([keys(tets[:, [j for j in range(4) if j != k]]) for k in range(4)])
    owner = np.tile(np.arange(len(tets)), 4)
    side = np.repeat(np.array(FACE_OF_VERTEX), len(tets))
    order = np.argsort(tk, kind="stable")
    fk = keys(faces)
    if not len(tk):
        return np.full(len(fk), -1), np.full(len(fk), -1)
    pos = np.minimum(np.searchsorted(tk[order], fk), len(tk) - 1)
    hit = tk[order][pos] == fk
    return np.where(hit, owner[order][pos], -1), np.where(hit, side[order][pos], -1)


def quadratic_nodes3d(points: np.ndarray, tets: np.ndarray
                      ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Mid-edge nodes of ten-node tetrahedra: ``(points (E, 3), mid (M, 6), edges (E, 2))``,
    ``mid`` the index (from ``len(points)`` on) of the midpoint of each edge of
    :data:`TET_EDGES`, ``edges`` the sorted vertex pairs of the new nodes."""
    pairs = np.stack([np.sort(tets[:, list(e)], axis=1) for e in TET_EDGES], axis=1)
    n = np.int64(len(points))
    keys = pairs[..., 0].astype(np.int64) * n + pairs[..., 1]
    uniq, inv = unique(keys.ravel(), return_inverse=True)
    edges = np.column_stack([uniq // n, uniq % n])
    mid = inv.reshape(keys.shape) + len(points)
    return 0.5 * (points[edges[:, 0]] + points[edges[:, 1]]), mid, edges


def _write_nodes(f: TextIO, points: np.ndarray) -> None:
    f.write("*NODE\n")
    text = iter(format_reals(points))
    rows = [f"{i}, {x}, {y}, {z}\n" for i, x, y, z in zip(range(1, len(points) + 1), text,
                                                          text, text)]
    for s in range(0, len(rows), textio.ROWS_PER_CHUNK):
        f.write("".join(rows[s:s + textio.ROWS_PER_CHUNK]))


def face_set_names(mesh: Mesh) -> list[tuple[str, tuple[int, ...]]]:
    """``[(set name, markers)]``, one per face name (:func:`~hetmesh.io.groups.
    curve_groups`: the markers sharing a name form one set): valid Abaqus names in
    capitals, unique, never ``REGION_*``/``MAT_*``/``FIXED_*``/``NALL``/``EALL``
    (``FACE_<tag>`` then)."""
    from .groups import curve_groups

    used: set[str] = set()
    out = []
    for g in curve_groups(mesh):
        named = g.name != f"marker_{g.tag}"
        s = abaqus_name(g.name).upper() if named else f"FACE_{g.tag}"
        if (s in used or s in ("NALL", "EALL")
                or s.startswith(("REGION_", "MAT_", "FIXED_", "_"))):
            s = f"FACE_{g.tag}"
        used.add(s)
        out.append((s, g.markers))
    return out


def write_inp_mesh3d(f: TextIO, mesh: Mesh, path: Path, *, order: int = 1, heading: str = "",
                     scale: float = 1.0, kind: str | None = None
                     ) -> tuple[np.ndarray, np.ndarray | None, np.ndarray | None]:
    """The mesh part of a deck (see the module docstring). Returns ``(points written
    (unscaled; mesh nodes then mid-edge nodes), mid (M, 6) or None, mid-node edges (E, 2) or
    None)``."""
    kind = kind or tet_element_type(order)
    P = np.asarray(mesh.points, np.float64)
    tets = oriented(P, mesh.cells)
    points, cells, mid, medges = P, tets + 1, None, None
    if order == 2:
        mid_points, mid, medges = quadratic_nodes3d(P, tets)
        points = np.vstack([P, mid_points])
        cells = np.column_stack([cells, mid + 1])
    f.write("*HEADING\n" + (heading or f"hetmesh mesh: {len(P)} nodes and {len(tets)} "
                                       f"{kind} elements") + "\n")
    _write_nodes(f, points * scale)
    f.write(f"*ELEMENT, TYPE={kind}, ELSET=EALL\n")
    row = "%d" + ", %d" * cells.shape[1] + "\n"  # 5 or 11 entries: one line each
    textio.write_rows(f, row, np.column_stack([np.arange(1, len(cells) + 1), cells]))
    regions = np.asarray(mesh.regions)
    for r in unique(regions):
        f.write(f"*ELSET, ELSET=REGION_{r}\n")
        write_id_list(f, np.flatnonzero(regions == r) + 1)
    facets = np.asarray(mesh.facets, np.int64)
    markers = np.asarray(mesh.facet_markers)
    owner, side = face_sides(tets, facets, len(P))
    if np.any(owner < 0):
        log.warning("%s: %d named triangles are no tetrahedron's face; no surface for them",
                    path, int((owner < 0).sum()))
    for name, group in face_set_names(mesh):
        sel = np.isin(markers, group)
        parts = []
        for m in group:
            for k in range(1, 5):
                ids = unique(owner[(markers == m) & (side == k)])
                if ids.size:
                    parts.append(f"_F{m}_S{k}")
                    f.write(f"*ELSET, ELSET={parts[-1]}, INTERNAL\n")
                    write_id_list(f, ids + 1)
        if parts:
            f.write(f"*SURFACE, NAME={name}, TYPE=ELEMENT\n"
                    + "".join(f"{s}, S{s[-1]}\n" for s in parts))
        nodes = facets[sel].ravel()
        if mid is not None:
            ok = sel & (owner >= 0)
            local = np.array(FACE_NODES)[side[ok] - 1]  # (F, 3) corners of each face
            on = []
            for i in range(len(TET_EDGES)):  # the mid nodes of the face's three edges
                a, b = TET_EDGES[i]
                has = np.isin(local, a).any(axis=1) & np.isin(local, b).any(axis=1)
                on.append(mid[owner[ok][has], i])
            nodes = np.concatenate([nodes] + on)
        f.write(f"*NSET, NSET={name}\n")
        write_id_list(f, unique(nodes) + 1)
    return points, mid, medges


def write_inp3d(mesh: Mesh, path: Path, fmt=None) -> None:
    """Write a tetrahedral ``mesh`` as an Abaqus input file of ``C3D4`` elements (the
    ``.inp`` format of :func:`hetmesh.io.export.write_mesh` for 3D meshes)."""
    options = dict(getattr(fmt, "options", None) or {})
    with open(path, "w", encoding="utf-8") as f:
        write_inp_mesh3d(f, mesh, path, order=options.get("order", 1))


def _condition_nodes(mask: np.ndarray, boundary: np.ndarray, medges: np.ndarray | None,
                     n: int) -> np.ndarray:
    """Node ids (0-based) of a vertex selection: the vertices and, for ten-node elements,
    the mid-edge nodes of the boundary edges with both ends selected (as
    :func:`hetmesh.fea.solid.surface_dofs` takes the edge dofs)."""
    nodes = np.flatnonzero(mask)
    if medges is None:
        return nodes
    both = mask[medges[:, 0]] & mask[medges[:, 1]]
    tri = np.sort(boundary, axis=1)
    pairs = np.vstack([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [0, 2]]]).astype(np.int64)
    bkeys = unique(pairs[:, 0] * n + pairs[:, 1])
    ekeys = medges[:, 0] * n + medges[:, 1]
    return np.concatenate([nodes, n + np.flatnonzero(both & np.isin(ekeys, bkeys))])


def write_deck3d(path: Path, mesh: Mesh, model, bins, target: str,
                 distribution: bool = False) -> bool:
    """Write the ``target`` (``"calculix"`` or ``"abaqus"``) deck of a tetrahedral ``mesh``
    of a 3-D ``model`` to ``path`` (see the module docstring); ``True`` if it holds the
    analysis (the model's ``[fea]`` table has conditions). ``distribution``: the
    elasticity element by element (:func:`hetmesh.io.abaqus.write_distribution`)."""
    from ..fea.analysis3d import face_vertices, selection_mask
    from ..tet.faces import boundary_faces

    cfg = model.fea
    order = cfg.order
    kind = tet_element_type(order)
    coupled = target == "abaqus" and bool(cfg.temperature)
    if coupled:
        kind = "C3D4T" if order == 1 else "C3D10MT"
    f1 = lambda v: format_reals(np.array([v]))[0]  # noqa: E731
    P = np.asarray(mesh.points, np.float64)
    with atomic_write(path) as f:
        points, mid, medges = write_inp_mesh3d(
            f, mesh, path, order=order, scale=cfg.length_scale, kind=kind,
            heading=f"hetmesh {target} deck for model {model.name}: {mesh.n_elements} "
                    f"{kind} elements in SI units (m Pa K W)")
        f.write("*NSET, NSET=NALL\n")
        write_id_list(f, np.arange(1, len(points) + 1))
        name = None
        if distribution:
            name = DISTRIBUTION
            write_distribution(f, mesh.cell_data["youngs_modulus"],
                               mesh.cell_data["poisson_ratio"], name)
        write_materials(f, bins, thickness=None,
                        reference_temperature=cfg.reference_temperature, distribution=name)
        if not cfg.has_problem:
            return False
        faces = face_vertices(mesh, getattr(model, "solid", None))
        boundary = np.asarray(boundary_faces(np.asarray(mesh.cells))[0], np.int64)
        tets = oriented(P, mesh.cells)

        def nset(name, mask):
            f.write(f"*NSET, NSET={name}\n")
            write_id_list(f, _condition_nodes(mask, boundary, medges, len(P)) + 1)

        temp_bc, disp_bc, loads = "", "", ""
        for i, bc in enumerate(cfg.temperature):
            nset(f"FIXED_T{i + 1}", selection_mask(bc.where, faces, P, bc.key))
            temp_bc += f"FIXED_T{i + 1}, 11, 11, {f1(bc.value)}\n"
        for i, bc in enumerate(cfg.displacement):
            nset(f"FIXED_U{i + 1}", selection_mask(bc.where, faces, P, bc.key))
            for dof, v in enumerate(bc.components, start=1):
                if v is not None:
                    disp_bc += f"FIXED_U{i + 1}, {dof}, {dof}, {f1(v * cfg.length_scale)}\n"
        for bc in cfg.pressure:
            mask = selection_mask(bc.where, faces, P, bc.key)
            tri = boundary[np.all(mask[boundary], axis=1)]
            owner, side = face_sides(tets, tri, len(P))
            if not len(tri) or np.any(owner < 0):
                raise OutputError(f"{bc.key}: the pressed faces are not faces of the mesh's "
                                  f"boundary tetrahedra")
            v = f1(bc.value)
            loads += "".join(f"{e + 1}, P{s}, {v}\n" for e, s in zip(owner.tolist(),
                                                                   side.tolist()))
        f.write(f"*INITIAL CONDITIONS, TYPE=TEMPERATURE\nNALL, {f1(cfg.reference_temperature)}\n")
        dload = "*DLOAD\n" + loads if loads else ""
        out = "*NODE FILE\nU, NT\n*EL FILE\nS\n*NODE PRINT, NSET=NALL\nU\n*END STEP\n"
        if coupled:
            f.write("*STEP\n*COUPLED TEMPERATURE-DISPLACEMENT, STEADY STATE\n1., 1.\n*BOUNDARY\n"
                    + temp_bc + disp_bc + dload + "*OUTPUT, FIELD\n*NODE OUTPUT\nNT, U\n"
                    "*ELEMENT OUTPUT\nS\n*END STEP\n")
            return True
        if temp_bc:
            f.write("*STEP\n*HEAT TRANSFER, STEADY STATE\n1., 1.\n*BOUNDARY\n" + temp_bc
                    + "*NODE FILE\nNT\n*END STEP\n")
        if target == "abaqus":
            out = "*OUTPUT, FIELD\n*NODE OUTPUT\nU\n*ELEMENT OUTPUT\nS\n*END STEP\n"
        f.write("*STEP\n*STATIC\n*BOUNDARY\n" + disp_bc + dload + out)
    return True
