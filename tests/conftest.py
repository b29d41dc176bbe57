"""Shared helpers: the invariants every mesh hetmesh writes must satisfy (DESIGN.md)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import hetmesh
from hetmesh.metrics import delta_vertices, min_angle

EXAMPLES = sorted((Path(hetmesh.__file__).parent / "examples").glob("*.toml"))


def square_domain(x0=0.0, y0=0.0, w=1.0, h=1.0):
    from hetmesh.geometry import Loop, Segment, make_domain

    pts = [(x0, y0), (x0 + w, y0), (x0 + w, y0 + h), (x0, y0 + h)]
    outer = Loop(tuple(Segment(a, b) for a, b in zip(pts, pts[1:] + pts[:1])), "outer")
    return make_domain(outer)


def check_invariants(result, model, threshold, min_angle_deg=30.0):
    """Valid conforming triangulation, area, delta_max < threshold, angle floor, curves kept."""
    mesh = result.mesh
    assert mesh.problems() == []
    assert mesh.area == pytest.approx(model.domain.area, rel=2e-3)
    comp = model.material.composition(mesh.points)
    delta = delta_vertices(comp, mesh.triangles)
    assert delta.max() < threshold
    assert np.all(delta <= mesh.cell_data["delta"] + 1e-12)  # dense sampling only adds
    # every constraint edge is an edge of the triangulation (conforming)
    t = mesh.triangles
    tri_edges = {tuple(sorted(e)) for e in np.concatenate([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]]).tolist()}
    assert all(tuple(sorted(e)) in tri_edges for e in mesh.edges.tolist())
    # boundary edges of the mesh are all constraint edges on the outer loop or holes
    cons = {tuple(sorted(e)) for e in mesh.edges.tolist()}
    assert all(tuple(e) in cons for e in mesh.boundary_edges.tolist())
    # minimum angle everywhere except at sharp input corners
    ang = min_angle(mesh.points, mesh.triangles)
    low = np.flatnonzero(ang < min_angle_deg - 1e-9)
    if low.size:
        corners = model.domain.corners
        for i in low:
            tri = mesh.points[mesh.triangles[i]]
            d = np.min(np.linalg.norm(tri[:, None, :] - corners[None], axis=2))
            assert d < 1e-9 * model.domain.diameter, f"triangle {i} has angle {ang[i]:.2f}"
    assert result.stats.delta_max < threshold
