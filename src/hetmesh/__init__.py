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

from importlib.resources import files
from pathlib import Path

from .tri.adapt import Result, generate, mesh_statistics
from .errors import (BudgetError, FormulaError, GeometryError, HetmeshError, MaterialError,
                     MeshingError, ModelFileError, OptionError, OutputError)
from .io.model import Model, load_model
from .mesh import Mesh
from .study import sweep
from .metrics import MeshStats
from .tri.uniform import uniform

__version__ = "0.1.0"

__all__ = [
    "generate", "uniform", "sweep", "mesh_statistics", "load_model", "example_path", "Model",
    "Mesh", "Result", "MeshStats", "HetmeshError", "ModelFileError", "GeometryError",
    "MaterialError", "FormulaError", "OptionError", "MeshingError", "BudgetError", "OutputError",
    "__version__",
]


def example_path(name: str) -> Path:
    """Path of a packaged example model, e.g. ``example_path("power_plate")``."""
    p = files("hetmesh") / "examples" / f"{name}.toml"
    return Path(str(p))
