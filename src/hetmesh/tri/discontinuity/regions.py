"""What the stages share: the discontinuity record, the subregions of a field and the
stages' settings."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...errors import MaterialError

__all__ = ["Discontinuity", "DomainRegions", "DISCONTINUITY", "GRID_CELLS", "FIT_TOL", "BISECT",
           "MAX_CROSSINGS_PER_CELL"]

#: name prefix of the interface paths holding discontinuities
DISCONTINUITY = "discontinuity"
GRID_CELLS = 400          # grid cells along the longer side of the bounding box
FIT_TOL = 1e-5            # default fitting tolerance, relative to the domain diameter
BISECT = 48               # bisection steps for a crossing (2^-48 of a grid edge)
#: most grid edges inside the domain that discontinuities may cross, per grid cell along
#: the longer side (about as many curves spanning the domain): more pieces than this are
#: not embedded (:func:`embed_discontinuities` raises MaterialError)
MAX_CROSSINGS_PER_CELL = 100


@dataclass(frozen=True)
class Discontinuity:
    """One discontinuity curve: sampled points (``(K, 2)``, ordered), the two subregion ids
    it separates, and whether it is closed."""

    points: np.ndarray
    regions: tuple[int, int]
    closed: bool = False


class DomainRegions:
    """``region(points)`` of a field, -1 outside ``domain`` where the field owns no
    subregion (a ``select`` without a default may leave the outside unowned; that is not an
    error there, and the -1 boundary lies on the domain's boundary, which is clipped away)."""

    def __init__(self, field, domain):
        self.field, self.domain = field, domain

    def region(self, points):
        try:
            return np.asarray(self.field.region(points), dtype=np.int64)
        except MaterialError:
            out = np.full(len(points), -1, dtype=np.int64)
            inside = self.domain.contains(points)
            out[inside] = self.field.region(points[inside])
            return out
