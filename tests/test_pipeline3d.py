"""A solid model through the whole pipeline: the model file, hetmesh.generate's tetrahedral
kernel, the file writers and readers, and the 3D analysis against the exact solution."""

from __future__ import annotations

import math

import numpy as np
import pytest

import hetmesh
import hetmesh.fea as fea
from hetmesh.errors import OptionError
from hetmesh.fea import verification
from hetmesh.io.read import read_mesh


@pytest.fixture(scope="module")
def cylinder():
    model = hetmesh.load_model(hetmesh.example_path("graded_cylinder"))
    return model, hetmesh.generate(model, 0.1)


def test_generate_dispatches_a_solid_to_the_tetrahedral_kernel(cylinder):
    model, r = cylinder
    assert model.dim == 3 and r.mesh.dim == 3 and r.mesh.cell_type == "tetra"
    assert r.stats.delta_max < 0.1 and r.stats.n_elements == r.mesh.n_elements
    assert r.mesh.problems() == []
    assert {"inner", "outside", "x0", "y0", "bottom", "top"} <= set(r.mesh.marker_names.values())
    # the quarter tube's volume, up to the chords of its arcs
    assert r.mesh.measure == pytest.approx(0.25 * math.pi * (20**2 - 10**2) * 5, rel=2e-3)
    stats = hetmesh.mesh_statistics(r.mesh, model)
    assert stats.delta_max == pytest.approx(r.stats.delta_max)


def test_two_d_only_options_are_refused_for_a_solid(cylinder):
    model, _ = cylinder
    with pytest.raises(OptionError, match="min_angle=20.0 is not available for 3D models"):
        hetmesh.generate(model, 0.1, min_angle=20.0)
    with pytest.raises(OptionError, match="max_size=0.5 is not available for uniform 3D"):
        hetmesh.uniform(model, 0.1, max_size=0.5)


def test_the_generated_mesh_solves_to_the_exact_radial_solution(cylinder, tmp_path):
    """Mesh file written and read back, quadratic elements: radial and hoop stress at R1..R3
    within 1 % of the exact plane-strain solution (hetmesh.fea.radial)."""
    model, r = cylinder
    back = read_mesh(r.mesh.write(tmp_path / "cyl.vtu"))
    assert back.dim == 3 and np.array_equal(back.cells, r.mesh.cells)
    res = fea.solve(back, model)
    ref = verification.reference("pressure")
    for name, q in verification.case_probes("pressure").items():
        sr, st = verification.radial_hoop("pressure", res.probes[name])
        rr = math.hypot(q[0], q[1])
        assert abs(sr - ref.sigma_r(rr)) < 0.01 * abs(ref.sigma_r(rr)), name
        assert abs(st - ref.sigma_t(rr)) < 0.01 * abs(ref.sigma_t(rr)), name
