"""Small helpers shared by the text writers of :mod:`hetmesh.io` (Gmsh, Abaqus)."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, TextIO

import numpy as np

from ..errors import OutputError

if TYPE_CHECKING:  # the writers take any mesh with Mesh's attributes
    from ..mesh import Mesh

__all__ = ["write_rows", "float_pad", "check_ids", "region_tag_offset", "ROWS_PER_CHUNK"]

ROWS_PER_CHUNK = 65536


def write_rows(f: TextIO, row: str, a: np.ndarray) -> None:
    """Write the rows of ``a`` with the %-format ``row`` (fast for millions of rows)."""
    a = np.asarray(a)
    for s in range(0, len(a), ROWS_PER_CHUNK):
        block = a[s:s + ROWS_PER_CHUNK]
        f.write((row * len(block)) % tuple(block.ravel().tolist()))


def float_pad(a: np.ndarray, n: int) -> np.ndarray:
    """The padding of a cell data array on a block of ``n`` cells (NaN or -1)."""
    shape = (n,) + a.shape[1:]
    if np.issubdtype(a.dtype, np.floating):
        return np.full(shape, np.nan, a.dtype)
    if np.issubdtype(a.dtype, np.integer):
        return np.full(shape, -1, a.dtype)
    return np.zeros(shape, a.dtype)


def check_ids(mesh: Mesh, path: Path, what: str, *, markers: bool = False) -> None:
    """Ids that name sets and physical groups: regions >= 0 (and edge markers >= 1)."""
    if mesh.n_elements and mesh.regions.min() < 0:
        raise OutputError(f"cannot write {path}: {what} needs regions >= 0, got "
                          f"{mesh.regions.min()}")
    if markers and len(mesh.edges) and mesh.edge_markers.min() < 1:
        raise OutputError(f"cannot write {path}: {what} needs edge markers >= 1, "
                          f"got {mesh.edge_markers.min()}")


def region_tag_offset(markers: np.ndarray) -> int:
    """The physical tag of region ``r`` in Gmsh files is ``offset + r``.

    ``offset`` is 1000, or the next power of ten above the largest edge marker, so the tags
    of physical surfaces and curves never collide, even for tools that ignore dimensions.
    """
    largest = int(np.max(markers, initial=0))
    return max(1000, 10 ** len(str(largest)))
