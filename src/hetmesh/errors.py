"""The package's exceptions.

Every error hetmesh raises on purpose derives from :class:`HetmeshError`. Messages name the
problem and where it is (file, key, coordinate), e.g.
``power_plate.toml: material.composition.metal: unknown name 'z'``.

Each class says whose fault it is, in ``exit_code`` (the exit status of the ``hetmesh``
command) and ``internal``:

* exit 2, bad input: :class:`ModelFileError`, :class:`GeometryError`, :class:`MaterialError`
  (:class:`FormulaError`), :class:`OptionError`, :class:`OutputError`, :class:`FEAError`,
  :class:`MeshDataError`; and :class:`BudgetError`, since the user chose the threshold and
  the element budget that cannot both be met;
* exit 1, internal (hetmesh failed on valid input, a bug to report): :class:`MeshingError`
  (the refinement stalled or did not converge, the triangulation kernel failed, a material
  discontinuity could not be embedded) and :class:`VerificationError` (the finished mesh
  failed a check of the final verification).
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
    "VerificationError",
    "MeshDataError",
    "OutputError",
    "FEAError",
]


class HetmeshError(Exception):
    """Base class of every error hetmesh raises on purpose: bad input, an impossible request,
    or (:class:`MeshingError`) a failure of hetmesh itself."""

    #: exit status of the ``hetmesh`` command for this error: 2 bad input, 1 internal
    exit_code: int = 2
    #: a failure of hetmesh on valid input (a bug to report), not of the input
    internal: bool = False


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
    """Meshing could not finish what it guarantees on valid input: the refinement stalled or
    did not converge, the triangulation kernel failed, ... An internal error (exit code 1),
    except for the subclasses that say otherwise."""

    exit_code = 1
    internal = True


class BudgetError(MeshingError):
    """The element budget would be (or was) exceeded: the user's threshold and budget cannot
    both be met (exit code 2)."""

    exit_code = 2
    internal = False


class VerificationError(MeshingError):
    """The finished mesh failed a check of the final verification
    (:func:`hetmesh.tri.finish.finish`):
    a claim hetmesh makes about every mesh it returns does not hold. Internal (exit code 1)."""


class MeshDataError(MeshingError):
    """Arrays given to :class:`hetmesh.mesh.Mesh` (or read from a mesh file) are inconsistent:
    shapes, indices out of range, data of the wrong length (exit code 2). On the mesher's own
    arrays it is a bug: :func:`hetmesh.tri.finish.finish` raises :class:`VerificationError`."""

    exit_code = 2
    internal = False


class OutputError(HetmeshError):
    """An output path is unwritable or has an unknown extension."""


class FEAError(HetmeshError):
    """A finite element analysis cannot be set up or solved: singular system (no fixed
    temperature, too few displacement constraints), a boundary condition or probe that finds
    no mesh node or element, no ``[fea]`` settings."""
