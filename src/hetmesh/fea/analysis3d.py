"""The 3-D analysis of a tetrahedral :class:`~hetmesh.mesh.Mesh` against its model.

:func:`hetmesh.fea.solve` comes here when the mesh is 3-D (``mesh.dim == 3``). The conditions
of the ``[fea]`` table (:mod:`~hetmesh.fea.config3d`) are turned into vertex selections, then
:func:`hetmesh.fea.solid.solve_tets` runs conduction and thermoelasticity.

**Faces are found geometrically** when the model's solid can classify boundary triangles
(``solid.classify_faces(corners (K, 3, 3))`` -> face index, ``solid.face_names``), so any mesh
file of the model works, as in 2-D; otherwise from the mesh's own named facets
(``mesh.facets``, ``facet_markers``, ``marker_names``, as the tetrahedral mesher writes them).
An edge is the vertices on both of its faces; a point condition takes the vertex within
``1e-6`` x the mesh diameter of the point, or fails.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..errors import FEAError
from .config import ON_BOUNDARY
from .config3d import FEAConfig3D, Selection
from .mixing import mix
from .solid import STRESS_NAMES_3D, Displacement, solve_tets

__all__ = ["FEAResult3D", "Part3D", "solve_mesh3d", "face_vertices", "selection_mask",
           "Conditions3D", "mesh_conditions"]

log = logging.getLogger(__name__)


@dataclass(frozen=True, eq=False)
class FEAResult3D:
    """The solution on a tetrahedral mesh (SI units); the attributes of
    :class:`~hetmesh.fea.analysis.FEAResult` with 3-D shapes: ``displacement (N, 3)``,
    ``stress (N, 6)`` and ``cell_stress (M, 6)`` in the order of :data:`STRESS_NAMES_3D`
    (``xx, yy, zz, xy, yz, xz``), and ``solver`` (per system: method, unknowns, CG
    iterations, residual), ``error_indicator (M,)`` the Zienkiewicz-Zhu indicator of every
    element and ``energy`` the energy-like norm of the stress
    (:func:`hetmesh.fea.estimate.zz_indicator`)."""

    mesh: Any
    temperature: np.ndarray
    displacement: np.ndarray
    stress: np.ndarray
    von_mises: np.ndarray
    cell_stress: np.ndarray
    cell_von_mises: np.ndarray
    probes: Mapping[str, Mapping[str, float]]
    config: FEAConfig3D
    model_name: str = ""
    timings: Mapping[str, float] = field(default_factory=dict)
    solver: Mapping[str, Mapping[str, Any]] = field(default_factory=dict)
    error_indicator: np.ndarray | None = None
    energy: float = float("nan")

    def report(self) -> dict[str, Any]:
        """A JSON-ready summary: settings, extremes, solver statistics, timings and one entry
        per probe with ``x, y, z, element, temperature, ux, uy, uz, stress_xx, stress_yy,
        stress_zz, stress_xy, stress_yz, stress_xz, von_mises`` (SI units)."""
        c = self.config
        return {
            "model": self.model_name, "dimension": 3,
            "points": int(self.mesh.n_points), "elements": int(self.mesh.n_elements),
            "order": c.order, "mixing": c.mixing, "matrix": c.matrix,
            "reference_temperature": c.reference_temperature,
            "length_scale": c.length_scale,
            "units": {"length": "m", "temperature": "K", "stress": "Pa",
                      "probe_coordinates": "model units"},
            "temperature_range": [float(self.temperature.min()), float(self.temperature.max())],
            "von_mises_max": float(self.von_mises.max()),
            "von_mises_max_cell": float(self.cell_von_mises.max()),
            "solver": {k: dict(v) for k, v in self.solver.items()},
            "probes": {k: dict(v) for k, v in self.probes.items()},
            "timings": dict(self.timings),
        }


@dataclass(frozen=True, eq=False)
class Part3D:
    """A 3-D part for :func:`hetmesh.fea.solve` without a model file: a material field on
    ``(N, 3)`` points, the ``[fea]`` settings and optionally a solid (for finding faces
    geometrically); a 3-D model loaded from a file has the same attributes."""

    name: str
    material: Any
    fea: FEAConfig3D | None = None
    solid: Any = None


def face_vertices(mesh, solid) -> dict[str, np.ndarray]:
    """Face name -> vertex mask ``(N,)`` of the mesh's boundary triangles on that face
    (geometrically through ``solid.classify_faces`` when available, else from the mesh's
    named facets)."""
    P = np.asarray(mesh.points)
    n = len(P)
    out: dict[str, np.ndarray] = {}
    if solid is not None and callable(getattr(solid, "classify_faces", None)):
        tri = np.asarray(mesh.boundary_facets)
        label = np.asarray(solid.classify_faces(P[tri]))
        for i, name in enumerate(solid.face_names):
            m = out.setdefault(name, np.zeros(n, dtype=bool))
            m[tri[label == i].ravel()] = True
        return out
    facets = np.asarray(mesh.facets)
    markers = np.asarray(mesh.facet_markers)
    for marker, name in mesh.marker_names.items():
        m = out.setdefault(name, np.zeros(n, dtype=bool))
        m[facets[markers == marker].ravel()] = True
    return out


def selection_mask(sel: Selection, faces: Mapping[str, np.ndarray], P: np.ndarray,
                   key: str) -> np.ndarray:
    """The vertex mask of a :class:`~hetmesh.fea.config3d.Selection`; :class:`FEAError`
    if it selects nothing."""
    def face(name):
        if name not in faces:
            raise FEAError(f"{key}: no face {name!r} on this mesh (faces: "
                           f"{', '.join(faces) or 'none: the mesh has no named facets'})")
        return faces[name]

    if sel.point is not None:
        d = np.linalg.norm(P - np.asarray(sel.point), axis=1)
        i = int(np.argmin(d))
        tol = ON_BOUNDARY * float(np.linalg.norm(P.max(axis=0) - P.min(axis=0)))
        if d[i] > tol:
            raise FEAError(f"{key}: no mesh vertex at {sel.label} (the nearest is {d[i]:.3g} "
                           f"away); a point condition needs a vertex there")
        m = np.zeros(len(P), dtype=bool)
        m[i] = True
        return m
    if sel.edge is not None:
        m = face(sel.edge[0]) & face(sel.edge[1])
    else:
        m = np.any([face(f) for f in sel.faces], axis=0)
    if not m.any():
        raise FEAError(f"{key}: {sel.label} has no mesh vertex: is the mesh for this model?")
    return m


@dataclass(frozen=True, eq=False)
class Conditions3D:
    """What :func:`hetmesh.fea.solid.solve_tets` needs besides the mesh: the mixed material
    (a callable on points), the temperature, displacement and pressure conditions as vertex
    selections, and the piece of every element."""

    material: Any
    temperature: list
    displacement: list
    pressure: list
    groups: np.ndarray


def mesh_conditions(mesh, model, cfg: FEAConfig3D) -> Conditions3D:
    """The ``[fea]`` table ``cfg`` on a tetrahedral mesh of ``model``: :class:`Conditions3D`
    (used by :func:`solve_mesh3d` and by the dual solves of :mod:`hetmesh.fea.goal`)."""
    field_ = model.material
    if len(cfg.properties) != len(field_.constituents):
        raise FEAError(f"the [fea] properties are for {len(cfg.properties)} constituents, the "
                       f"material has {len(field_.constituents)}")
    if not cfg.displacement:
        raise FEAError(f"model {getattr(model, 'name', '')!r}: the [fea] table has no "
                       f"displacement conditions: see docs/model-format.md")
    P, T = np.asarray(mesh.points), np.asarray(mesh.cells)
    faces = face_vertices(mesh, getattr(model, "solid", None))
    temps = [(selection_mask(bc.where, faces, P, bc.key), bc.value) for bc in cfg.temperature]
    disp = [Displacement(selection_mask(bc.where, faces, P, bc.key), *bc.components,
                         label=bc.where.label) for bc in cfg.displacement]
    press = [(selection_mask(bc.where, faces, P, bc.key), bc.value) for bc in cfg.pressure]
    cons = list(field_.constituents)
    matrix = cons.index(cfg.matrix) if cfg.matrix is not None else 0
    table = cfg.table()

    def material(x):
        comp = np.asarray(field_.composition(x), dtype=np.float64)
        if not np.isfinite(comp).all():
            raise FEAError("the material field gave a non-finite composition at a "
                           "quadrature point")
        return mix(comp, table, cfg.mixing, matrix)

    groups = np.asarray(mesh.regions, dtype=np.int64)
    from ..material.field import element_subregions, has_subregions

    if has_subregions(field_):
        sub = element_subregions(field_, P, T)
        groups = groups * (int(sub.max()) + 1) + sub
    return Conditions3D(material, temps, disp, press, groups)


def solve_mesh3d(mesh, model, cfg: FEAConfig3D) -> FEAResult3D:
    """Conduction and thermoelasticity on a tetrahedral mesh (see the module docstring);
    ``model`` gives ``material`` (a field on ``(N, 3)`` points), ``name`` and optionally
    ``solid``."""
    c = mesh_conditions(mesh, model, cfg)
    P, T = np.asarray(mesh.points), np.asarray(mesh.cells)
    r = solve_tets(P, T, c.material, order=cfg.order, temperature=c.temperature,
                   displacement=c.displacement, pressure=c.pressure, probes=cfg.probes,
                   reference_temperature=cfg.reference_temperature,
                   length_scale=cfg.length_scale, groups=c.groups, solver=cfg.solver)
    out = mesh.with_data(
        point_data={"temperature": r.temperature, "displacement": r.displacement,
                    **{k: r.stress[:, i] for i, k in enumerate(STRESS_NAMES_3D)},
                    "von_mises": r.von_mises},
        cell_data={**{k: r.cell_stress[:, i] for i, k in enumerate(STRESS_NAMES_3D)},
                   "von_mises": r.cell_von_mises})
    return FEAResult3D(mesh=out, temperature=r.temperature, displacement=r.displacement,
                       stress=r.stress, von_mises=r.von_mises, cell_stress=r.cell_stress,
                       cell_von_mises=r.cell_von_mises, probes=r.probes, config=cfg,
                       model_name=getattr(model, "name", ""), timings=r.timings,
                       solver=r.solver, error_indicator=r.error_indicator,
                       energy=r.energy)
