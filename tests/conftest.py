"""Shared helpers: the invariants every mesh hetmesh writes must satisfy."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import hetmesh
from hetmesh.material import has_subregions
from hetmesh.metrics import delta_vertices, min_angle
from hetmesh.tri.discontinuity import crossing_elements

_ALL_EXAMPLES = sorted((Path(hetmesh.__file__).parent / "examples").glob("*.toml"))
#: the 3D example models (a [solid] table; hetmesh.tet), and the 2D ones
EXAMPLES_3D = [p for p in _ALL_EXAMPLES if "\n[solid]" in p.read_text(encoding="utf-8")]
EXAMPLES = [p for p in _ALL_EXAMPLES if p not in EXAMPLES_3D]


def square_domain(x0=0.0, y0=0.0, w=1.0, h=1.0):
    from hetmesh.tri.geometry import Loop, Segment, make_domain

    pts = [(x0, y0), (x0 + w, y0), (x0 + w, y0 + h), (x0, y0 + h)]
    outer = Loop(tuple(Segment(a, b) for a, b in zip(pts, pts[1:] + pts[:1])), "outer")
    return make_domain(outer)


def check_invariants(result, model, threshold, min_angle_deg=30.0):
    """Valid conforming triangulation, area, delta_max < threshold, angle floor, curves kept."""
    mesh = result.mesh
    assert mesh.problems() == []
    assert mesh.area == pytest.approx(model.domain.area, rel=2e-3)
    field = model.material
    meshed = result.model if getattr(result, "model", None) is not None else model
    if has_subregions(field):
        # each element in its own subregion, at all three vertices (Sec. 3.3)
        own = field.region(mesh.points[mesh.triangles].mean(axis=1))
        np.testing.assert_array_equal(own, mesh.cell_data["subregion"])
        comp = np.stack([field.composition(mesh.points[mesh.triangles[:, k]], region=own)
                         for k in range(3)], axis=1)
        delta = (comp.max(axis=1) - comp.min(axis=1)).max(axis=1)
        # no element crosses a discontinuity: a node off every curve has its elements' region
        curves = meshed.domain.curve_batch
        free = curves.distance(mesh.points) > 1e-9 * model.domain.diameter
        vreg = field.region(mesh.points)
        t = mesh.triangles
        assert np.all((vreg[t] == own[:, None]) | ~free[t])
        assert not crossing_elements(field, mesh.points, t, curves,
                                     tol=2e-5 * model.domain.diameter).any()
    else:
        delta = delta_vertices(field.composition(mesh.points), mesh.triangles)
    assert delta.max() < threshold
    assert np.all(delta <= mesh.cell_data["delta"] + 1e-12)  # dense sampling only adds
    # every constraint edge is an edge of the triangulation (conforming)
    t = mesh.triangles
    sides = np.concatenate([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]])
    tri_edges = {tuple(sorted(e)) for e in sides.tolist()}
    assert all(tuple(sorted(e)) in tri_edges for e in mesh.edges.tolist())
    # boundary edges of the mesh are all constraint edges on the outer loop or holes
    cons = {tuple(sorted(e)) for e in mesh.edges.tolist()}
    assert all(tuple(e) in cons for e in mesh.boundary_edges.tolist())
    # minimum angle everywhere except at sharp input corners
    ang = min_angle(mesh.points, mesh.triangles)
    low = np.flatnonzero(ang < min_angle_deg - 1e-9)
    if low.size:
        corners = meshed.domain.corners
        scale = 1e-9 * model.domain.diameter
        on = meshed.domain.curve_batch.distance(mesh.points) <= scale
        for i in low:
            tri = mesh.points[mesh.triangles[i]]
            d = np.linalg.norm(tri[:, None, :] - corners[None], axis=2)
            if d.min() < scale:
                continue  # at a sharp input corner
            # or in the wedge of a small input angle: two curve nodes seen from the nearest
            # corner at less than 60 degrees (a seditious edge, left alone by design)
            c = corners[np.argmin(d.min(axis=0))]
            v = tri[on[mesh.triangles[i]]] - c
            cos = [v[j] @ v[k] / np.linalg.norm(v[j]) / np.linalg.norm(v[k])
                   for j in range(len(v)) for k in range(j + 1, len(v))]
            assert len(v) >= 2 and max(cos) > 0.5, f"triangle {i} has angle {ang[i]:.2f}"
    assert result.stats.delta_max < threshold
