"""One entry point for 3D models: :func:`mesh_model` picks the placement.

* an extruded 2D model (composition independent of the extrusion coordinate): the 2D mesh of
  the section swept along the axis (:func:`hetmesh.tet.extrude.generate_extruded`), which keeps
  the subregions of feature-tree and piecewise fields;
* a convex prism (box, cylinder) whose composition varies along its axis only (for a box,
  along any of the three axes): layers on the level planes
  (:func:`hetmesh.tet.mesher.generate_tets`);
* any other prism: the swept section mesh (the 2D mesher's placement follows the in-plane
  variation), in layers thin enough for the variation along the axis, repaired by edge
  bisection where needed;
* a solid of revolution: the profile's 2D mesh swept about the axis
  (:func:`hetmesh.tet.revolve.generate_revolved`);
* a solid of primitives (a sphere, a clipped primitive, subtractions that are not
  through-holes): level-set cuts of a background grid, MMG remeshing to the material's size
  (:func:`hetmesh.tet.general.generate_solid`);
* an extrusion or a revolution minus primitives that are not through-holes: level-set cuts
  of its swept mesh, MMG remeshing to the material's size
  (:func:`hetmesh.tet.carve.generate_carved`);
* a solid bounded by a triangulated surface (STL, OBJ, PLY): Gmsh fills it, MMG remeshes
  it to the material's size (:func:`hetmesh.tet.surface_mesh.generate_surface`);
* the non-zero voxels of a mask volume: the level-set cut of the voxel-centre grid, MMG
  remeshing (:func:`hetmesh.tet.masked.generate_masked`).

>>> import hetmesh
>>> r = mesh_model(hetmesh.load_model(hetmesh.example_path("unit_cube")), 0.2)
>>> r.info["placement"], bool(r.delta.max() < 0.2)
('planar', True)
"""

from __future__ import annotations

import time
from dataclasses import replace

import numpy as np

from ..errors import OptionError
from ..kernel import Result
from ..material import has_subregions
from ..mesh import Mesh
from ..metrics import delta_vertices, dihedral_angles, statistics, tet_quality
from ..options import DEFAULT_GRADATION, DEFAULT_ROW_SPACING
from .extrude import generate_extruded
from .mesher import TetResult, generate_tets

__all__ = ["mesh_model", "generate", "to_mesh", "result_statistics", "DEFAULT_MAX_ELEMENTS",
           "OPTIONS_2D"]

DEFAULT_MAX_ELEMENTS = 20_000_000


def mesh_model(model, threshold: float, *, seed: int = 0, chord_tol: float | None = None,
               max_elements: int | None = DEFAULT_MAX_ELEMENTS,
               max_size: float | None = None, check: bool = True,
               sampling: str = "vertices") -> TetResult:
    """Tetrahedral mesh of a 3D model (:class:`hetmesh.io.model3d.Model3D`) with every
    element's delta below ``threshold``, verified.

    ``chord_tol`` is relative to the solid's diameter (as in 2D), default 0.002 (an
    extrusion's, box's or cylinder's section without it: the 2D mesher's default, 0.001 of
    the section's diameter, never looser);
    ``max_size`` (model units) bounds the node spacing: in swept and revolved meshes it
    evens out the section's sizes, which shapes the tetrahedra better at a higher count.
    The result's ``info["composition"]`` holds the vertex compositions ``(N, m)``, its
    ``mesh`` the :class:`~hetmesh.mesh.Mesh` (:func:`to_mesh`), which ``write`` saves.
    ``sampling = "pixels"`` (a material from a 3D volume) also meets delta_0 over every
    voxel centre of every tetrahedron (:func:`hetmesh.tet.sampling.resample`).
    """
    if isinstance(threshold, bool) or not isinstance(threshold, (int, float)) \
            or not 0 < threshold < 1:
        raise OptionError(f"threshold must be in (0, 1), got {threshold!r}")
    if chord_tol is not None and not 1e-7 <= chord_tol <= 0.05:
        raise OptionError(f"chord_tol must be in [1e-7, 0.05], got {chord_tol!r}")
    if max_size is not None and not (np.isfinite(max_size) and max_size > 0):
        raise OptionError(f"max_size must be a positive number, got {max_size!r}")
    if max_elements is not None and max_elements < 1:
        raise OptionError(f"max_elements must be positive, got {max_elements!r}")
    from .sampling import TET_SAMPLINGS, resample
    if sampling not in TET_SAMPLINGS:
        raise OptionError(f"sampling {sampling!r} is not available for 3D models (one of "
                          f"{', '.join(TET_SAMPLINGS)})")
    solid = model.solid
    chord = None if chord_tol is None else chord_tol * solid.diameter
    from ..io.model import Model
    from .carve import CarvedSolid
    from .extrude import mid_section_field
    from .implicit import CSGSolid
    from .masked import VoxelSolid
    from .revolve import Revolution, generate_revolved, is_axisymmetric, profile_field
    from .surface import SurfaceSolid
    if isinstance(solid, SurfaceSolid):
        from .surface_mesh import generate_surface
        res = generate_surface(solid, model.material, threshold, seed=seed, chord_tol=chord,
                               max_elements=max_elements, max_size=max_size, check=check)
    elif isinstance(solid, VoxelSolid):  # the non-zero voxels of a mask volume
        from .masked import generate_masked
        res = generate_masked(solid, model.material, threshold, seed=seed, chord_tol=chord,
                              max_elements=max_elements, max_size=max_size, check=check)
    elif isinstance(solid, CarvedSolid):  # an extrusion or a revolution minus primitives
        from .carve import generate_carved, section_field
        f2 = section_field(solid, model.material)
        res = generate_carved(solid, model.material, threshold,
                              Model(name=model.name, domain=solid.domain, material=f2),
                              seed=seed, chord_tol=chord, max_elements=max_elements,
                              max_size=max_size, check=check)
    elif isinstance(solid, CSGSolid):
        from .general import generate_solid
        res = generate_solid(solid, model.material, threshold, seed=seed, chord_tol=chord,
                             max_elements=max_elements, max_size=max_size, check=check)
    elif isinstance(solid, Revolution):
        axisym = model.material2d is not None or is_axisymmetric(model.material, solid)
        f2 = model.material2d or profile_field(model.material, solid)
        res = generate_revolved(solid, model.material, threshold,
                                Model(name=model.name, domain=solid.profile, material=f2),
                                axisymmetric=axisym, seed=seed, chord_tol=chord,
                                max_elements=max_elements, max_size=max_size, check=check)
    elif model.material2d is not None:
        res = generate_extruded(solid, model.material, threshold,
                                Model(name=model.name, domain=solid.section,
                                      material=model.material2d),
                                swept=True, seed=seed, chord_tol=chord,
                                max_elements=max_elements, max_size=max_size, check=check)
    elif solid.convex and (layered := _planar_prism(solid, model.material)) is not None:
        res = generate_tets(layered, model.material, threshold, seed=seed, chord_tol=chord,
                            max_elements=max_elements, h_max=max_size, check=check)
    else:
        res = generate_extruded(solid, model.material, threshold,
                                Model(name=model.name, domain=solid.section,
                                      material=mid_section_field(solid, model.material)),
                                swept=False, seed=seed, chord_tol=chord,
                                max_elements=max_elements, max_size=max_size, check=check)
    if "composition" not in res.info:  # the swept meshes' delta came from the 2D field
        res.info["composition"] = np.asarray(model.material.composition(res.points),
                                             dtype=np.float64)
    res = resample(res, solid, model.material, sampling, max_elements=max_elements,
                   chord_tol=chord, check=check)
    res.mesh = to_mesh(res, model.constituents)
    return res


def _planar_prism(solid, field):
    """``solid`` (or, for a box, the same box along another axis) if the composition varies
    along its axis only, else None: the layered placement's best case. Compositions that
    vary across the axis go to the swept section mesh, which keeps its quality."""
    from .mesher import is_planar
    from .solid import box

    if has_subregions(field):  # its jumps are embedded by the sweep (the layers would
        return None  # refine across them without end)
    if is_planar(field, solid, solid.sample(16)):
        return solid
    names = solid.face_names
    if len(names) == 6 and set(names) == {"xmin", "xmax", "ymin", "ymax", "zmin", "zmax"}:
        lo, hi = solid.bounds
        for axis in (0, 1, 2):
            if axis != solid.axis:
                other = box(lo, hi, axis=axis, where=solid.where)
                if is_planar(field, other, other.sample(16)):
                    return other
    return None


def result_statistics(res: TetResult, delta_at_vertices: np.ndarray):
    """The :class:`~hetmesh.metrics.MeshStats` of a tetrahedral result (its mesh built by
    :func:`to_mesh`): ``q`` the radius ratio, ``angle`` the smallest dihedral angle, delta
    the result's own (its sampling's), ``delta_max_vertices`` from ``delta_at_vertices``."""
    q = res.mesh.cell_data["quality"]
    ang = dihedral_angles(res.points, res.tets).min(axis=1)
    stats = statistics(res.points, res.tets, res.delta, quality=q, angle=ang)
    return replace(stats, delta_max_vertices=float(delta_at_vertices.max()))


def to_mesh(res: TetResult, constituents) -> Mesh:
    """The :class:`~hetmesh.mesh.Mesh` of a tetrahedral result: the boundary triangles as
    facets with their face markers and names, the compositions as point data (one array per
    constituent), ``delta`` and ``quality`` (radius ratio) as cell data, and the subregions
    of an extruded feature-tree model as regions (and cell data ``subregion``)."""
    comp = res.info.get("composition")
    pd = {} if comp is None else {c: comp[:, j] for j, c in enumerate(constituents)}
    cd = {"delta": res.delta, "quality": tet_quality(res.points, res.tets)}
    regions = res.info.get("regions")
    if regions is not None:
        cd["subregion"] = regions
    return Mesh(res.points, res.tets, regions=regions, facets=res.faces,
                facet_markers=res.face_markers, point_data=pd, cell_data=cd,
                marker_names={m: n for m, n in enumerate(res.face_names, start=1)})


#: the options of :func:`hetmesh.generate` that only the 2D kernel has, and their defaults
OPTIONS_2D = {"min_angle": 30.0, "method": "auto", "row_spacing": DEFAULT_ROW_SPACING,
              "gradation": DEFAULT_GRADATION, "min_quality": 0.6, "optimize": True,
              "sampling": "vertices", "progress": None}


def generate(model, threshold: float, *, seed: int = 0, chord_tol: float | None = None,
             max_elements: int | None = DEFAULT_MAX_ELEMENTS, max_size: float | None = None,
             **options) -> Result:
    """The 3D kernel behind :func:`hetmesh.generate`: :func:`mesh_model` as a
    :class:`~hetmesh.kernel.Result` (its ``stats``: ``q_min``/``q_avg`` the radius ratio,
    ``angle_min`` the smallest dihedral angle; ``options["placement"]`` the placement used).

    Options of the 2D kernel other than their defaults raise :class:`OptionError`.
    """
    sampling = options.pop("sampling", None) or "vertices"
    for key, value in options.items():
        if key not in OPTIONS_2D:
            raise TypeError(f"generate() got an unexpected keyword argument {key!r}")
        if value != OPTIONS_2D[key] and value is not None:
            raise OptionError(f"{key}={value!r} is not available for 3D models")
    t0 = time.perf_counter()
    res = mesh_model(model, threshold, seed=seed, chord_tol=chord_tol,
                     max_elements=max_elements, max_size=max_size, sampling=sampling)
    seconds = time.perf_counter() - t0
    dv = delta_vertices(res.info["composition"], res.tets) if sampling != "vertices" \
        else res.delta
    stats = result_statistics(res, dv)
    opts = dict(threshold=threshold, seed=seed, chord_tol=chord_tol,
                max_elements=max_elements, max_size=max_size, sampling=sampling,
                placement=res.info.get("placement"))
    return Result(mesh=res.mesh, stats=stats, threshold=threshold,
                  history=[{"round": 0, "stage": "tet", "elements": int(len(res.tets)),
                            "points": int(len(res.points)),
                            "delta_max": float(res.delta.max())}],
                  timings={"total": seconds}, options=opts, model=model)
