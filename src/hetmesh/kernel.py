"""What a meshing kernel provides, and what every kernel returns.

A kernel meshes the models of one dimension: :mod:`hetmesh.tri` (triangles, planar
domains). Each provides, in its package:

``generate(model, threshold, **options) -> Result``
    the adaptive mesh: every element with delta(T) < threshold (Eq. 1), verified;
``uniform(model, threshold, **options) -> Result``
    the coarsest uniform quality mesh meeting the threshold (the baseline);

and builds its meshes on the dimension-generic core: :class:`hetmesh.mesh.Mesh` (points
``(N, d)``, cells ``(M, d + 1)``), :mod:`hetmesh.metrics` (delta on simplices, quality per
dimension), the material fields (:mod:`hetmesh.material`, points ``(N, d)``),
:mod:`hetmesh.density` (rho = |grad f|^(d+2), Eq. 9) and the loop's shared pieces
(:mod:`hetmesh.refinement`). :func:`mesh_statistics` re-measures any mesh of any dimension
against its model.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

from .delta import element_delta
from .errors import OptionError
from .material.field import element_subregions, has_subregions
from .mesh import Mesh
from .metrics import MeshStats, statistics
from .options import SAMPLINGS

if TYPE_CHECKING:
    from .io.model import Model

__all__ = ["Result", "mesh_statistics"]


@dataclass
class Result:
    """What :func:`generate` and :func:`hetmesh.uniform` return."""

    mesh: Mesh
    stats: MeshStats
    threshold: float
    history: list = field(default_factory=list)
    timings: dict = field(default_factory=dict)
    options: dict = field(default_factory=dict)
    #: the model as meshed: with its material discontinuities embedded as interfaces
    model: Model | None = None



def mesh_statistics(mesh: Mesh, model, sampling: str = "vertices") -> MeshStats:
    """Recompute q and delta of any mesh from the model (Eqs. 1, 16-18); with a feature-tree
    field each element is evaluated in the subregion of its centroid."""
    if sampling not in SAMPLINGS:
        raise OptionError(f"sampling {sampling!r} is not one of {', '.join(SAMPLINGS)}")
    fld = model.material
    regions = (element_subregions(fld, mesh.points, mesh.cells) if has_subregions(fld)
               else None)
    delta = element_delta(fld, mesh.points, mesh.cells, sampling, regions=regions)
    return statistics(mesh.points, mesh.cells, delta)

