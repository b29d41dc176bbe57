"""The uniform baseline of extrusions and revolutions minus primitives
(:func:`hetmesh.tet.uniform.uniform_carved_at` through :func:`hetmesh.tet.uniform.uniform_model`):
checked from the arrays alone (validity, conformity, delta from the formula, the planar faces
exact and the curved ones within the chord tolerance, the volume against its closed form)."""

from __future__ import annotations

import math

import pytest

import hetmesh
from hetmesh.io.model import load_model
from hetmesh.tet.carve import CarvedSolid
from test_carve import LID_POCKET, check_boundary, cylinder_z, volume, write
from test_tet import check_tet_mesh


def _metal(p):
    return (p[:, 0] ** 2 + p[:, 1] ** 2) / 4


@pytest.mark.slow
def test_the_lid_pocket_gets_a_verified_uniform_mesh(tmp_path):
    """The full revolution with a square pocket in its lid at delta_0 = 0.3: the coarsest
    size that passes of those tried, every size that failed larger; the mesh checked
    independently, every face named, the pocket's bottom whole."""
    m = load_model(write(tmp_path, LID_POCKET))
    assert isinstance(m.solid, CarvedSolid)
    d0 = 0.3
    r = hetmesh.uniform(m, d0)
    mesh = r.mesh
    assert r.options["placement"] == "uniform remeshed"
    bnd = check_tet_mesh(mesh.points, mesh.cells, _metal, d0)
    diam = m.solid.diameter
    chord = 2e-3 * diam
    planes = [((0, 0, 1), 0.0), ((0, 0, 1), 2.0), ((0, 0, 1), 1.5), ((1, 0, 0), -0.4),
              ((1, 0, 0), 0.4), ((0, 1, 0), -0.4), ((0, 1, 0), 0.4)]
    area = check_boundary(mesh.points, bnd, planes, [cylinder_z(0, 0, 2)], chord, diam)
    assert abs(volume(mesh.points, mesh.cells) - (8 * math.pi - 0.32)) <= chord * area.sum()
    assert set(mesh.marker_names.values()) == set(m.solid.face_names)
    # the size search: the mesh is the fewest elements of the sizes that passed, and every
    # size that failed is larger than the one used
    passed = [h for h in r.history if h["pass"]]
    assert len(mesh.cells) == min(h["elements"] for h in passed)
    assert all(h["h"] > r.options["size"] for h in r.history if h["pass"] is False)
    assert any(h["pass"] is False for h in r.history)
