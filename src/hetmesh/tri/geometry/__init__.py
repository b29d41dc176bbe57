"""Geometry: curves (segments, arcs), loops, interfaces, the domain and its PSLG.

Examples
--------
>>> from hetmesh.tri.geometry import Arc, Loop, Segment, make_domain, build_pslg
>>> plate = make_domain(Loop((Segment((0, 0), (42, 0)), Segment((42, 0), (42, 24)),
...                           Arc.through((42, 24), (21, 30), (0, 24)),
...                           Segment((0, 24), (0, 0))), "outer"))
>>> g = build_pslg(plate, 2.0, 0.01)
"""

from __future__ import annotations

from .curves import Arc, Curve, CurveBatch, Segment, SizeLike, sample_parameters, segments_through
from .domain import CurveInfo, Domain, Loop, Path, make_domain
from .pslg import PSLG, build_pslg, pslg_from_parameters

__all__ = [
    "Arc",
    "Curve",
    "CurveBatch",
    "CurveInfo",
    "Domain",
    "Loop",
    "PSLG",
    "Path",
    "Segment",
    "SizeLike",
    "build_pslg",
    "pslg_from_parameters",
    "make_domain",
    "sample_parameters",
    "segments_through",
]
