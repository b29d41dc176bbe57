"""Complete analysis decks and solver bundles for a mesh of a model (``hetmesh export``).

``calculix`` / ``abaqus``: one input file ``<model>.inp`` in SI units (coordinates times
``[fea]``'s length scale, so metres; Pa, K, W/(m K)) holding the mesh
(:func:`hetmesh.io.abaqus.write_inp_mesh`), the graded material binned by composition
(:func:`hetmesh.io.material.bin_material`, one ``*MATERIAL``/``*SOLID SECTION`` per bin),
and, when the model's ``[fea]`` table has boundary conditions, the analysis of
:func:`hetmesh.fea.solve`:

- CalculiX: ``*INITIAL CONDITIONS`` at the reference temperature, step 1 ``*HEAT TRANSFER,
  STEADY STATE`` with the fixed temperatures (dof 11), step 2 ``*STATIC`` with the
  displacement conditions; CalculiX carries step 1's temperatures into step 2, so the
  thermal strain is ``alpha (T - T_ref)``. Elements ``CPE3``/``CPS3`` (``[fea] order = 1``)
  or ``CPE6``/``CPS6`` (order 2). Results: ``.frd`` (NT, U, S) and ``.dat`` (NT, U).
- Abaqus (not run here: no licence): one ``*COUPLED TEMPERATURE-DISPLACEMENT, STEADY
  STATE`` step, as Abaqus' plane stress/strain elements carry no temperature in a heat
  transfer step; elements ``CPE3T``/``CPS3T`` or ``CPE6MT``/``CPS6MT``.

The condition node sets are found as :func:`hetmesh.fea.solve` finds them (the nodes within
``1e-6`` x the domain diameter of the named curves, the node at a named point), with the
mid-side nodes of the edges along a curve for six-node elements.

``fenics``: ``<model>.xdmf`` + ``.h5`` in the dolfinx layout (:mod:`hetmesh.io.xdmf`)
with the element properties and mean composition as cell attributes (DG0 data).
``comsol``: ``<model>.nas`` (NASTRAN bulk data: ``GRID``, ``CTRIA3`` (``CTETRA`` in 3-D)
with the region as property id, which COMSOL imports as domains) and
``<model>_composition.txt``, an interpolation table ``x y [z] <constituent fractions...>``
at the nodes (COMSOL: Definitions > Functions > Interpolation, data from file, two or three
arguments).

Tetrahedral meshes of 3-D models: the same targets; the Abaqus/CalculiX deck is written by
:func:`hetmesh.io.abaqus3d.write_deck3d` (``C3D4``/``C3D10``, named faces as surfaces,
pressures as ``*DLOAD``).
"""

from __future__ import annotations

import json
import logging
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import FEAError, OptionError
from ..mesh import Mesh
from ..topology import unique
from . import abaqus
from .atomic import atomic_write
from .material import MaterialBins, bin_material, element_material, material_config, with_material

__all__ = ["TARGETS", "DeckReport", "write_deck", "condition_nodes", "read_frd", "frd_nodal",
           "name_from_model"]

log = logging.getLogger(__name__)

TARGETS = ("calculix", "abaqus", "fenics", "comsol")


@dataclass
class DeckReport:
    """What :func:`write_deck` wrote and the binning it did."""

    target: str
    files: list[Path] = field(default_factory=list)
    bins: int = 0
    bin_width: float | None = None
    max_property_error: float | None = None
    property_errors: dict = field(default_factory=dict)
    analysis: bool = False
    distribution: bool = False

    def to_dict(self) -> dict:
        return {"target": self.target, "files": [str(p) for p in self.files],
                "bins": self.bins, "bin_width": self.bin_width,
                "max_property_error": self.max_property_error,
                "property_errors": self.property_errors, "analysis": self.analysis,
                "distribution": self.distribution}


def condition_nodes(mesh: Mesh, model, points: np.ndarray, mid: np.ndarray | None):
    """``(temperature [(nodes, value)], displacement [(nodes, bc)])`` as node ids (0-based)
    into ``points`` (mesh nodes then mid-side nodes ``mid`` ``(M, 3)``)."""
    from ..fea.analysis import curve_facets, displacement_nodes, temperature_nodes
    from ..fea.config import ON_BOUNDARY

    cfg = model.fea
    tol = ON_BOUNDARY * model.domain.diameter
    if mid is not None:
        edges = np.stack([mesh.triangles, np.roll(mesh.triangles, -1, axis=1)], axis=-1)
        facets = edges.reshape(-1, 2).T  # (2, 3M), one per side, its mid node in mid.ravel()
        mids = mid.ravel()

    def with_mid(nodes, names):
        if mid is None or not names:
            return np.asarray(nodes)
        f = curve_facets(model.domain, mesh.points, facets, nodes, names, tol)
        return unique(np.concatenate([nodes, mids[f]]))

    temps = [(with_mid(n, bc.curves), v) for (n, v), bc in
             zip(temperature_nodes(mesh, model.domain, cfg), cfg.temperature)]
    disps = [(with_mid(n, bc.curves if bc.point is None else ()), bc)
             for n, bc in displacement_nodes(mesh, model.domain, cfg)]
    return temps, disps


def section_thickness(model) -> float:
    """The ``*SOLID SECTION`` thickness (m): 1 in plane strain (per unit thickness, as
    :func:`hetmesh.fea.solve`); in plane stress 1e-3 x the domain's diameter, as CalculiX
    models plane stress by a slab of that thickness, free on its faces, which is plane
    stress only when thin."""
    cfg = model.fea
    if cfg.plane == "strain":
        return 1.0
    return 1e-3 * model.domain.diameter * cfg.length_scale


def _write_id_set(f, name: str, ids: np.ndarray) -> None:
    f.write(f"*NSET, NSET={name}\n")
    abaqus.write_id_list(f, np.asarray(ids, np.int64) + 1)


def _write_inp_deck(path: Path, mesh: Mesh, model, bins: MaterialBins, target: str,
                    distribution: bool = False) -> bool:
    cfg = model.fea
    order, plane = cfg.order, cfg.plane
    kind = abaqus.element_type(plane, order)
    if target == "abaqus":
        kind = kind.replace("6", "6M") + "T" if order == 2 else kind + "T"
    f1 = lambda v: abaqus.format_reals(np.array([v]))[0]  # noqa: E731
    with atomic_write(path) as f:
        points = abaqus.write_inp_mesh(
            f, mesh, path, plane=plane, order=order, scale=cfg.length_scale, kind=kind,
            heading=f"hetmesh {target} deck for model {model.name}: {mesh.n_elements} "
                    f"{kind} elements in SI units (m Pa K W)")
        _write_id_set(f, "NALL", np.arange(len(points)))
        name = None
        if distribution:
            name = abaqus.DISTRIBUTION
            abaqus.write_distribution(f, mesh.cell_data["youngs_modulus"],
                                      mesh.cell_data["poisson_ratio"], name)
        abaqus.write_materials(f, bins, thickness=section_thickness(model),
                               reference_temperature=cfg.reference_temperature,
                               distribution=name)
        if not cfg.has_problem:
            return False
        mid = abaqus.quadratic_nodes(mesh)[1] if order == 2 else None
        temps, disps = condition_nodes(mesh, model, points, mid)
        for i, (nodes, _) in enumerate(temps):
            _write_id_set(f, f"FIXED_T{i + 1}", nodes)
        for i, (nodes, _) in enumerate(disps):
            _write_id_set(f, f"FIXED_U{i + 1}", nodes)
        f.write(f"*INITIAL CONDITIONS, TYPE=TEMPERATURE\nNALL, {f1(cfg.reference_temperature)}\n")
        temp_bc = "".join(f"FIXED_T{i + 1}, 11, 11, {f1(v)}\n" for i, (_, v) in enumerate(temps))
        disp_bc = ""
        for i, (_, bc) in enumerate(disps):
            for dof, v in ((1, bc.ux), (2, bc.uy)):
                if v is not None:
                    disp_bc += f"FIXED_U{i + 1}, {dof}, {dof}, {f1(v * cfg.length_scale)}\n"
        if target == "calculix":
            f.write("*STEP\n*HEAT TRANSFER, STEADY STATE\n1., 1.\n*BOUNDARY\n" + temp_bc
                    + "*NODE FILE\nNT\n*END STEP\n")
            f.write("*STEP\n*STATIC\n*BOUNDARY\n" + disp_bc
                    + "*NODE FILE\nU, NT\n*EL FILE\nS\n*NODE PRINT, NSET=NALL\nNT, U\n*END STEP\n")
        else:
            f.write("*STEP\n*COUPLED TEMPERATURE-DISPLACEMENT, STEADY STATE\n1., 1.\n*BOUNDARY\n"
                    + temp_bc + disp_bc + "*OUTPUT, FIELD\n*NODE OUTPUT\nNT, U\n"
                    "*ELEMENT OUTPUT\nS\n*END STEP\n")
    return True


def _write_comsol(directory: Path, stem: str, mesh: Mesh) -> list[Path]:
    import meshio

    from .atomic import atomic_path

    nas = directory / f"{stem}.nas"
    p = mesh.points if mesh.dim == 3 else np.column_stack([mesh.points,
                                                           np.zeros(mesh.n_points)])
    m = meshio.Mesh(p, [(mesh.cell_type, np.asarray(mesh.cells))],
                    cell_data={"nastran:ref": [mesh.regions.astype(np.int64) + 1]})
    with atomic_path(nas) as tmp:
        meshio.write(tmp, m, file_format="nastran")
    table = directory / f"{stem}_composition.txt"
    cons = [k for k in mesh.point_data if np.asarray(mesh.point_data[k]).ndim == 1]
    with atomic_write(table) as f:
        f.write("% " + " ".join("xyz"[:mesh.dim]) + " " + " ".join(cons) + "\n")
        rows = np.column_stack([mesh.points] + [mesh.point_data[k] for k in cons])
        np.savetxt(f, rows, fmt="%.17g")
    return [nas, table]


def name_from_model(mesh: Mesh, model) -> Mesh:
    """``mesh`` with its curve names and named points taken from ``model`` where the file
    it was read from lost them (``.vtu``, ``.vtk``, ``.mesh``): marker ``m`` is curve
    ``m - 1`` of the model as meshed (discontinuities embedded), checked node by node."""
    import dataclasses

    from ..fea.config import ON_BOUNDARY
    from ..tri.discontinuity import embed_discontinuities

    tol = ON_BOUNDARY * model.domain.diameter
    changes = {}
    if len(mesh.edges) and not mesh.marker_names:
        curves = embed_discontinuities(model).domain.curves
        markers = unique(mesh.edge_markers)
        if markers.min() >= 1 and markers.max() <= len(curves):
            for m in markers.tolist():
                nodes = unique(mesh.edges[mesh.edge_markers == m])
                c = curves[m - 1].curve
                p = mesh.points[nodes]
                if np.hypot(*(c.point(c.project(p)) - p).T).max() > tol:
                    break
            else:
                changes["marker_names"] = {m: curves[m - 1].curve.name or curves[m - 1].owner
                                           for m in markers.tolist()}
    if not mesh.named_points and model.domain.points:
        named = {}
        for name, xy in model.domain.points.items():
            d = np.hypot(*(mesh.points - np.asarray(xy, np.float64)).T)
            if d.min() <= tol:
                named[name] = int(np.argmin(d))
        changes["named_points"] = named
    return dataclasses.replace(mesh, **changes) if changes else mesh


def write_deck(mesh: Mesh, model, directory: str | Path, target: str, *,
               bin_width: float | None = None, distribution: bool = False) -> DeckReport:
    """Write the bundle of ``target`` (:data:`TARGETS`) for ``mesh`` of ``model`` into
    ``directory`` (created if missing); returns a :class:`DeckReport`.

    ``bin_width`` (composition) defaults to the mesh's largest element delta (below the
    delta_0 it was meshed for), so the bins add no more variation than the mesh's own.
    ``distribution`` (``abaqus`` only): every element's own ``E`` and ``nu`` through an
    Abaqus ``*DISTRIBUTION`` (:func:`hetmesh.io.abaqus.write_distribution`); the bins then
    carry the expansion and the conductivity, and the report's Young's modulus and Poisson
    ratio errors are zero.
    """
    from .export import write_mesh

    if target not in TARGETS:
        raise OptionError(f"unknown export target {target!r} (known: {', '.join(TARGETS)})")
    if distribution and target != "abaqus":
        raise OptionError(f"--distribution is for --to abaqus (Abaqus/Standard's *DISTRIBUTION); "
                          f"{target} has no element distributions: use the material bins")
    cfg = material_config(model)
    if len(cfg.properties) != len(model.material.constituents):
        raise FEAError(f"the [fea] properties are for {len(cfg.properties)} constituents, the "
                       f"material has {len(model.material.constituents)}")
    if mesh.dim == 2:
        mesh = name_from_model(mesh, model)
    directory = Path(directory)
    try:
        directory.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise OptionError(f"cannot create the output directory {directory}: "
                          f"{exc.strerror}") from None
    material = element_material(mesh, model, cfg)
    width = bin_width if bin_width is not None else float(max(material.delta.max(initial=0), 1e-3))
    bins = bin_material(material, min(width, 1.0), cfg, model.material.constituents)
    errors = dict(bins.errors)
    if distribution:
        errors.update(youngs_modulus=0.0, poisson_ratio=0.0)
    report = DeckReport(target, bins=bins.count, bin_width=bins.width,
                        max_property_error=max(errors.values(), default=0.0),
                        property_errors=errors, distribution=distribution)
    stem = model.name or "model"
    graded = with_material(mesh, material)
    if target in ("calculix", "abaqus"):
        path = directory / f"{stem}.inp"
        if mesh.dim == 3:
            from .abaqus3d import write_deck3d

            report.analysis = write_deck3d(path, graded, model, bins, target, distribution)
        else:
            report.analysis = _write_inp_deck(path, graded, model, bins, target, distribution)
        report.files.append(path)
    elif target == "fenics":
        report.files.append(write_mesh(graded, directory / f"{stem}.xdmf"))
        report.files.append(directory / f"{stem}.h5")
        report.bins, report.bin_width, report.max_property_error = 0, None, 0.0
        report.property_errors = {}
    else:
        report.files += _write_comsol(directory, stem, graded)
        report.files.append(write_mesh(graded, directory / f"{stem}.vtu"))
        report.bins, report.bin_width, report.max_property_error = 0, None, 0.0
        report.property_errors = {}
    summary = directory / f"{stem}_export.json"
    with atomic_write(summary) as f:
        json.dump(report.to_dict() | {"model": model.name, "elements": mesh.n_elements}, f,
                  indent=2)
    report.files.append(summary)
    log.info("export %s: %s (%d bins of width %s, largest property error %.3g)", target,
             ", ".join(map(str, report.files)), report.bins, report.bin_width,
             report.max_property_error or 0.0)
    return report


def read_frd(path: str | Path) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Nodal results of a CalculiX ``.frd`` file (ASCII): ``{block: (node ids (K,),
    values (K, C))}`` for every result block (``NDTEMP``, ``DISP``, ``STRESS``, ...), the
    last of each name (the last step's)."""
    out: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    name, ids, rows = None, [], []
    with open(path, encoding="utf-8", errors="replace") as f:
        for line in f:
            if line.startswith(" -4"):
                name, ids, rows = line.split()[1], [], []
            elif name and line.startswith(" -1"):
                ids.append(int(line[3:13]))
                body = line[13:].rstrip("\n")
                rows.append([float(body[i:i + 12]) for i in range(0, len(body), 12)])
            elif name and line.startswith(" -3"):
                out[name] = (np.array(ids, np.int64), np.array(rows, np.float64))
                name = None
    return out


def frd_nodal(frd: dict, block: str, n: int) -> np.ndarray:
    """The values ``(n, C)`` of result ``block`` of :func:`read_frd`'s output at nodes 1..n
    (the mesh's nodes in order; nan where the file has none)."""
    ids, v = frd[block]
    out = np.full((ids.max() + 1, v.shape[1]), np.nan)
    out[ids] = v
    return out[1:n + 1]
