"""Abaqus / CalculiX input files (``.inp``): the mesh, its named sets, its graded material.

Numbers: CalculiX (and Abaqus' fixed-width readers) read at most 20 characters of a field,
so every real is written in at most 20 characters (:func:`format_reals`): Python's shortest
round-trip form where it fits, else the nearest number of 14 or 15 significant digits
that does (at most 1e-14 relative from the coordinate in memory). The reader then gets
exactly the number written.

Elements: ``CPE3`` (plane strain) or ``CPS3`` (plane stress); with ``order=2`` the
six-node ``CPE6``/``CPS6``, their mid-side nodes at the midpoints of the straight edges
(numbered after the mesh's nodes). Element ids are the triangle indices + 1, node ids the
node indices + 1, as in every other format.

Sets: ``*ELSET, ELSET=REGION_<r>`` per region; per curve *name*
(:func:`hetmesh.io.groups.curve_groups`) one ``*NSET`` and one element-based
``*SURFACE`` named after it, the surface built on internal element sets
``_M<marker>_S<side>`` (from which the edges and their markers read back exactly); per
named point an ``*NSET`` of its node. Names are made valid (letters, digits, ``_``,
starting with a letter, at most 80 characters).

Material (optional, :class:`MaterialBins`): element sets ``MAT_<i>`` binned by
composition, one ``*MATERIAL`` (``*ELASTIC``, ``*EXPANSION``, ``*CONDUCTIVITY``) and one
``*SOLID SECTION`` per bin (with the thickness), see :mod:`hetmesh.io.material`. For
Abaqus/Standard, the elasticity can instead be given element by element
(:func:`write_distribution`: ``*DISTRIBUTION TABLE`` / ``*DISTRIBUTION`` with the labels
``MODULUS, RATIO`` of the Abaqus keyword reference), each bin's ``*ELASTIC`` naming the
distribution; CalculiX has no ``*DISTRIBUTION``.
"""

from __future__ import annotations

import logging
import re
from pathlib import Path
from typing import TYPE_CHECKING, TextIO

import numpy as np

from ..errors import OutputError
from ..topology import unique
from . import textio
from .groups import curve_groups
from .textio import check_ids

if TYPE_CHECKING:  # the writers take any mesh with Mesh's attributes
    from ..mesh import Mesh

__all__ = ["format_reals", "abaqus_name", "element_type", "quadratic_nodes", "write_inp",
           "write_inp_mesh", "write_materials", "write_distribution", "write_id_list",
           "edge_sides", "set_names", "MAX_FIELD", "DISTRIBUTION"]

log = logging.getLogger(__name__)

#: characters of a field that CalculiX reads
MAX_FIELD = 20

#: the name of the element-wise elasticity of :func:`write_distribution`
DISTRIBUTION = "GRADED_ELASTIC"


def format_reals(values: np.ndarray) -> list[str]:
    """Each value as the shortest text of at most 20 characters that reads back as the
    value (``repr``), or else the nearest with 15, then 14 significant digits.

    >>> format_reals(np.array([0.5, -8.881784197001252e-16, 7.105427357601002e-15]))
    ['0.5', '-8.8817841970013e-16', '7.105427357601e-15']
    """
    out = []
    for v in np.asarray(values, np.float64).ravel().tolist():
        s = repr(v)
        if len(s) > MAX_FIELD:
            for digits in (15, 14, 13):
                s = f"{v:.{digits}g}"
                if len(s) <= MAX_FIELD:
                    break
        if not np.isfinite(v):
            raise OutputError(f"cannot write the non-finite number {v!r} in an .inp file")
        out.append(s)
    return out


def abaqus_name(name: str) -> str:
    """A valid Abaqus set name: letters, digits and underscores, starting with a letter.

    >>> abaqus_name("discontinuity[0]")
    'discontinuity_0_'
    """
    s = re.sub(r"[^A-Za-z0-9_]", "_", name.strip())
    if not s or not s[0].isalpha():
        s = "M_" + s
    return s[:80]


def set_names(mesh: Mesh) -> tuple[list[str], dict[str, str]]:
    """The ``*NSET``/``*SURFACE`` name of every curve group (in :func:`curve_groups`
    order) and of every named point (``{point name: set name}``), unique ignoring case and
    never ``REGION_*``/``MAT_*`` (``MARKER_<tag>``/``POINT_<i>`` where a name clashes)."""
    used: set[str] = set()

    def pick(name: str | None, fallback: str) -> str:
        s = abaqus_name(name) if name else fallback
        if s.upper() in used or s.upper().startswith(("REGION_", "MAT_", "_")):
            s = fallback
        used.add(s.upper())
        return s

    curves = [pick(None if g.name == f"marker_{g.tag}" else g.name, f"MARKER_{g.tag}")
              for g in curve_groups(mesh)]
    points = {k: pick(k, f"POINT_{i + 1}") for i, k in enumerate(mesh.named_points)}
    return curves, points


def element_type(plane: str = "strain", order: int = 1) -> str:
    """``CPE3``, ``CPS3``, ``CPE6`` or ``CPS6``."""
    if plane not in ("strain", "stress") or order not in (1, 2):
        raise OutputError(f"no Abaqus element for plane {plane!r}, order {order!r}")
    return ("CPE" if plane == "strain" else "CPS") + ("3" if order == 1 else "6")


def quadratic_nodes(mesh: Mesh) -> tuple[np.ndarray, np.ndarray]:
    """Mid-side nodes of the six-node triangles: ``(points (E, 2), mid (M, 3))``, ``mid``
    the index (from ``n_points`` on) of the midpoint of sides 1-2, 2-3 and 3-1."""
    u, _ = mesh.unique_edges
    t = mesh.triangles.astype(np.int64)
    lo = np.minimum(t, np.roll(t, -1, axis=1))
    hi = np.maximum(t, np.roll(t, -1, axis=1))
    keys = (u[:, 0].astype(np.int64) << 32) | u[:, 1]
    mid = np.searchsorted(keys, (lo << 32) | hi) + mesh.n_points
    return 0.5 * (mesh.points[u[:, 0]] + mesh.points[u[:, 1]]), mid


def write_id_list(f: TextIO, ids: np.ndarray) -> None:
    """Ids (1-based), 16 per line as Abaqus wants."""
    full = len(ids) // 16 * 16
    textio.write_rows(f, "%d," * 15 + "%d\n", ids[:full].reshape(-1, 16))
    if full < len(ids):
        f.write(", ".join(str(int(i)) for i in ids[full:]) + "\n")


def edge_sides(mesh: Mesh) -> tuple[np.ndarray, np.ndarray]:
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


def _write_nodes(f: TextIO, points: np.ndarray) -> None:
    f.write("*NODE\n")
    text = format_reals(points).__iter__()
    rows = [f"{i}, {x}, {y}\n" for i, x, y in zip(range(1, len(points) + 1), text, text)]
    for s in range(0, len(rows), textio.ROWS_PER_CHUNK):
        f.write("".join(rows[s:s + textio.ROWS_PER_CHUNK]))


def _write_edges(f: TextIO, mesh: Mesh, path: Path, names: list[str],
                 mid: np.ndarray | None = None) -> None:
    """Per curve name: internal element sets ``_M<marker>_S<side>`` of its markers, an
    element-based ``*SURFACE`` and an ``*NSET`` (with the mid-side nodes ``mid`` ``(M, 3)``
    of its edges for six-node elements)."""
    tri, side = edge_sides(mesh)
    if np.any(tri < 0):
        log.warning("%s: %d constrained edges are no triangle's side; no surface for them",
                    path, int((tri < 0).sum()))
    for group, name in zip(curve_groups(mesh), names):
        faces = []
        for mk in group.markers:
            sel = mesh.edge_markers == mk
            for s in range(3):
                ids = unique(tri[sel][side[sel] == s])
                if ids.size:
                    faces.append(f"_M{mk}_S{s + 1}")
                    f.write(f"*ELSET, ELSET={faces[-1]}, INTERNAL\n")
                    write_id_list(f, ids + 1)
        if faces:
            f.write(f"*SURFACE, TYPE=ELEMENT, NAME={name}\n"
                    + "".join(f"{s}, {s[-2:]}\n" for s in faces))
        sel = np.isin(mesh.edge_markers, group.markers)
        nodes = mesh.edges[sel].ravel()
        if mid is not None:
            ok = sel & (tri >= 0)
            nodes = np.concatenate([nodes, mid[tri[ok], side[ok]]])
        f.write(f"*NSET, NSET={name}\n")
        write_id_list(f, unique(nodes) + 1)


def write_inp_mesh(f: TextIO, mesh: Mesh, path: Path, *, plane: str = "strain", order: int = 1,
                   heading: str = "", scale: float = 1.0, kind: str | None = None) -> np.ndarray:
    """The mesh part of a deck: nodes (coordinates times ``scale``), elements (``kind``,
    default :func:`element_type`) in ``ELSET=EALL``, region sets, curve and point sets.
    Returns the node coordinates written (mesh nodes, then any mid-side nodes), unscaled."""
    check_ids(mesh, path, "Abaqus")
    kind = kind or element_type(plane, order)
    points, cells, mid = mesh.points, mesh.triangles + 1, None
    if order == 2:
        mid_points, mid = quadratic_nodes(mesh)
        points = np.vstack([points, mid_points])
        cells = np.column_stack([cells, mid + 1])
    f.write("*HEADING\n")
    f.write((heading or f"hetmesh mesh: {mesh.n_points} nodes and {mesh.n_elements} {kind} "
                        f"elements") + "\n")
    _write_nodes(f, points * scale)
    f.write(f"*ELEMENT, TYPE={kind}, ELSET=EALL\n")
    row = "%d" + ", %d" * cells.shape[1] + "\n"
    textio.write_rows(f, row, np.column_stack([np.arange(1, len(cells) + 1), cells]))
    regions = unique(mesh.regions)
    for r in regions:
        f.write(f"*ELSET, ELSET=REGION_{r}\n")
        write_id_list(f, np.flatnonzero(mesh.regions == r) + 1)
    curves, pts = set_names(mesh)
    _write_edges(f, mesh, path, curves, mid)
    for name, node in mesh.named_points.items():
        f.write(f"*NSET, NSET={pts[name]}\n{node + 1}\n")
    return points


def write_distribution(f: TextIO, modulus: np.ndarray, ratio: np.ndarray,
                       name: str = DISTRIBUTION) -> None:
    """An element-wise isotropic elasticity for Abaqus/Standard: ``*DISTRIBUTION TABLE``
    (columns ``MODULUS, RATIO``) and ``*DISTRIBUTION, LOCATION=ELEMENT`` with a first line
    of defaults (blank element label; the median element's values) and one line per
    element ``id, E, nu`` (ids 1..M). Materials refer to it by giving ``name`` on their
    ``*ELASTIC`` data line (:func:`write_materials` with ``distribution``)."""
    E = np.asarray(modulus, np.float64)
    nu = np.asarray(ratio, np.float64)
    if not len(E):
        raise OutputError("an element distribution needs at least one element")
    mid = int(np.argsort(E, kind="stable")[len(E) // 2])
    f.write(f"*DISTRIBUTION TABLE, NAME={name}_TABLE\nMODULUS, RATIO\n"
            f"*DISTRIBUTION, NAME={name}, LOCATION=ELEMENT, TABLE={name}_TABLE\n")
    d = format_reals(np.array([E[mid], nu[mid]]))
    f.write(f", {d[0]}, {d[1]}\n")
    text = iter(format_reals(np.column_stack([E, nu])))
    rows = [f"{i}, {a}, {b}\n" for i, a, b in zip(range(1, len(E) + 1), text, text)]
    for s in range(0, len(rows), textio.ROWS_PER_CHUNK):
        f.write("".join(rows[s:s + textio.ROWS_PER_CHUNK]))


def write_materials(f: TextIO, bins, *, thickness: float | None = 1.0,
                    reference_temperature: float | None = None, heat: bool = True,
                    distribution: str | None = None) -> None:
    """Element sets ``MAT_<i>`` (1-based), one ``*MATERIAL`` (``*ELASTIC``, ``*EXPANSION``,
    ``*CONDUCTIVITY`` with ``heat``) and one ``*SOLID SECTION`` (with the ``thickness``
    of plane elements; none for solids) per bin of a
    :class:`~hetmesh.io.material.MaterialBins`; with ``distribution`` (the name of a
    :func:`write_distribution`) every ``*ELASTIC`` names it instead of giving the bin's
    ``E, nu``."""
    p = bins.properties
    for b in range(bins.count):
        name = f"MAT_{b + 1}"
        f.write(f"*ELSET, ELSET={name}\n")
        write_id_list(f, np.flatnonzero(bins.index == b) + 1)
        E, nu, alpha, k = format_reals(np.array([p["youngs_modulus"][b], p["poisson_ratio"][b],
                                                 p["expansion"][b], p["conductivity"][b]]))
        comp = ", ".join(f"{c:.6f}" for c in bins.composition[b])
        f.write(f"** {name}: mean composition ({comp})\n")
        elastic = distribution if distribution else f"{E}, {nu}"
        f.write(f"*MATERIAL, NAME={name}\n*ELASTIC\n{elastic}\n")
        zero = "" if reference_temperature is None else \
            f", ZERO={format_reals(np.array([reference_temperature]))[0]}"
        f.write(f"*EXPANSION{zero}\n{alpha}\n")
        if heat:
            f.write(f"*CONDUCTIVITY\n{k}\n")
        f.write(f"*SOLID SECTION, ELSET={name}, MATERIAL={name}\n")
        if thickness is not None:  # plane elements: the thickness; solids: no data line
            f.write(f"{format_reals(np.array([thickness]))[0]}\n")


def write_inp(mesh: Mesh, path: Path, fmt=None) -> None:
    """Write ``mesh`` as an Abaqus input file of ``CPE3`` elements (the ``.inp`` format of
    :func:`hetmesh.io.export.write_mesh`)."""
    options = dict(getattr(fmt, "options", None) or {})
    with open(path, "w", encoding="utf-8") as f:
        write_inp_mesh(f, mesh, path, plane=options.get("plane", "strain"),
                       order=options.get("order", 1))
