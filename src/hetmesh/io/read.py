"""Reading mesh files back into :class:`~hetmesh.mesh.Mesh` objects."""

from __future__ import annotations

from pathlib import Path

from ..mesh import Mesh
from .export import read_mesh_arrays

__all__ = ["read_mesh"]


def read_mesh(path: str | Path) -> Mesh:
    """Read a mesh written by :func:`write_mesh` (or any triangle mesh meshio reads).

    Parameters
    ----------
    path : str or Path
        The format follows the extension (``.msh`` of either Gmsh version).

    Returns
    -------
    Mesh
        Points (x, y), the triangles, their regions (``region`` cell data, Gmsh physical
        surfaces, Medit references, dolfinx cell tags or Abaqus ``REGION_<id>`` sets), the
        edges and their markers and names, and the named points, where the format keeps
        them; point data and the triangles' cell data. Files written by :func:`write_mesh`
        read back in the mesh's own node and triangle order (``.msh`` 4.1 by its tags).

    Raises
    ------
    OutputError
        Unknown extension, missing file, unreadable content or no triangles.

    Examples
    --------
    >>> mesh = read_mesh("plate.vtu")   # doctest: +SKIP
    """
    return Mesh(**read_mesh_arrays(path))
