"""The tetrahedral mesher: solids, 3D material fields, layered placement, delta repair and
verification (docs/tet.md)."""

from __future__ import annotations

from .api import mesh_model
from .mesher import TetResult, estimate_tets, generate_tets, n_iso3
from .quality import quality_summary
from .solid import Prism, box, cylinder

__all__ = ["mesh_model", "TetResult", "generate_tets", "estimate_tets", "n_iso3", "Prism",
           "box", "cylinder", "quality_summary"]
