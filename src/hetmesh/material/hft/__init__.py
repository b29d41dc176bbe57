"""Heterogeneous Feature Tree material fields (paper Section 3.3); see :mod:`.features`."""

from __future__ import annotations

from .features import (BlendFeature, CurveFeature, HFTField, NearestFeature, PointFeature,
                       SelectFeature, inside_predicate, parse_hft)

__all__ = ["HFTField", "PointFeature", "CurveFeature", "NearestFeature", "SelectFeature",
           "BlendFeature", "inside_predicate", "parse_hft"]
