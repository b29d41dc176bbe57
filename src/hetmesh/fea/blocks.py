"""Blocks of elements and sums into sparse-matrix slots: what the 3D assembly and the stress
recovery share."""

from __future__ import annotations

import numpy as np

__all__ = ["CHUNK", "sum_into"]

#: elements per assembly chunk (bounds the temporaries: chunk x (3 nb)^2 floats)
CHUNK = 50_000


def sum_into(slot: np.ndarray, values: np.ndarray, size: int) -> np.ndarray:
    """The sums of ``values`` by ``slot`` (the positions of a sparse pattern's entries),
    ``(size,)``: element contributions assembled into the pattern's data array."""
    return np.bincount(slot.ravel(), weights=values.ravel(), minlength=size)
