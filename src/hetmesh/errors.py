"""The package's exceptions.

Every error a user can cause derives from :class:`HetmeshError`; the CLI turns it into one
line on stderr and exit code 2. Messages name the problem and where it is (file, key,
coordinate), e.g. ``power_plate.toml: material.composition.metal: unknown name 'z'``.
"""

from __future__ import annotations

__all__ = [
    "HetmeshError",
    "ModelFileError",
    "GeometryError",
    "MaterialError",
    "FormulaError",
    "OptionError",
    "MeshingError",
    "BudgetError",
    "OutputError",
    "FEAError",
]


class HetmeshError(Exception):
    """Base class of every error hetmesh raises on bad input or an impossible request."""


class ModelFileError(HetmeshError):
    """A model file is not TOML, or has unknown, missing or mistyped keys."""


class GeometryError(HetmeshError):
    """The domain is invalid: too few vertices, self-intersections, misplaced holes, ..."""


class MaterialError(HetmeshError):
    """The material field is invalid: values outside [0, 1], not finite, sums not 1, ..."""


class FormulaError(MaterialError):
    """A formula does not compile: syntax, unknown names, forbidden constructs, size."""


class OptionError(HetmeshError):
    """An option is out of range (threshold <= 0, min angle outside (0, 34], ...)."""


class MeshingError(HetmeshError):
    """Meshing could not finish what it guarantees."""


class BudgetError(MeshingError):
    """The element budget would be (or was) exceeded."""


class OutputError(HetmeshError):
    """An output path is unwritable or has an unknown extension."""


class FEAError(HetmeshError):
    """A finite element analysis cannot be set up or solved: singular system (no fixed
    temperature, too few displacement constraints), a boundary condition or probe that finds
    no mesh node or element, no ``[fea]`` settings."""
