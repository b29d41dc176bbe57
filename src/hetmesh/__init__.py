"""hetmesh: material-aware adaptive meshing of heterogeneous objects.

Places mesh nodes where the material composition changes, so that every triangle stays nearly
homogeneous (its composition variation delta(T) below a threshold delta_0) with as few, as
well-shaped elements as possible; every mesh returned is verified.

>>> import hetmesh
>>> model = hetmesh.load_model(hetmesh.example_path("power_plate"))   # doctest: +SKIP
>>> result = hetmesh.generate(model, threshold=0.05)                    # doctest: +SKIP
>>> result.mesh.write("plate.vtu")                                       # doctest: +SKIP
"""

from __future__ import annotations

from .errors import (
                     BudgetError,
                     FormulaError,
                     GeometryError,
                     HetmeshError,
                     MaterialError,
                     MeshingError,
                     ModelFileError,
                     OptionError,
                     OutputError,
)
from .io.model import Model, example_path, load_model
from .kernel import Result, mesh_statistics
from .mesh import Mesh
from .meshing import generate, uniform
from .metrics import MeshStats
from .version import __version__

__all__ = [
    "generate", "uniform", "sweep", "mesh_statistics", "load_model", "example_path", "Model",
    "Mesh", "Result", "MeshStats", "HetmeshError", "ModelFileError", "GeometryError",
    "MaterialError", "FormulaError", "OptionError", "MeshingError", "BudgetError", "OutputError",
    "__version__",
]

