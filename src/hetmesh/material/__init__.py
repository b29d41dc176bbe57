"""Material fields: the :class:`MaterialField` interface, its validation and the analytic
(formula) and callable implementations.

>>> from hetmesh.material import AnalyticField
>>> AnalyticField({"metal": "(1 - y)**2"}, ["ceramic", "metal"]).composition([[0, 0]]).tolist()
[[0.0, 1.0]]
"""

from __future__ import annotations

from .analytic import AnalyticField, CallableField, check_constituents
from .field import (
                    TOLERANCE,
                    MaterialField,
                    PiecewiseField,
                    as_points,
                    check_field,
                    element_subregions,
                    field_dim,
                    has_subregions,
                    sample_domain,
)

__all__ = [
    "PiecewiseField",
    "field_dim",
    "has_subregions",
    "element_subregions",
    "MaterialField",
    "AnalyticField",
    "CallableField",
    "check_field",
    "check_constituents",
    "sample_domain",
    "as_points",
    "TOLERANCE",
]
