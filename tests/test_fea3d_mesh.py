"""hetmesh.fea.solve on a tetrahedral Mesh: conditions on named faces, the 3-D [fea] table,
the JSON report and the section plot."""

from __future__ import annotations

import json

import numpy as np
import pytest

import hetmesh.fea as fea
from hetmesh.errors import FEAError, ModelFileError
from hetmesh.fea import verification as v
from hetmesh.fea.analysis3d import Part3D
from hetmesh.fea.config3d import parse_fea3d
from hetmesh.io.schema import SchemaContext


@pytest.fixture(scope="module")
def mesh():
    return v.annulus_mesh(10.0, 20.0, 5.0, nr=8, nt=19, nz=4)


@pytest.fixture(scope="module")
def pressure_result(mesh):
    return fea.solve(mesh, Part3D("graded_cylinder", v.graded_field(),
                                  v.case_config("pressure")))


def test_solve_reads_the_dimension_from_the_mesh(mesh, pressure_result):
    """A 3-D mesh goes to the 3-D analysis; conditions on the mesh's named faces give the
    same probe stresses as the array-level run of the same case (within 1 % of exact)."""
    r = pressure_result
    assert isinstance(r, fea.FEAResult3D) and mesh.dim == 3
    arrays = v.run_case("pressure", 8, 2)
    for name, p in r.probes.items():
        sr, st = v.radial_hoop("pressure", p)
        assert sr == pytest.approx(arrays.values[name]["sigma_r"], rel=1e-9)
        assert st == pytest.approx(arrays.values[name]["sigma_t"], rel=1e-9)
        assert abs(st / arrays.exact[name]["sigma_t"] - 1) < 0.01
    assert r.displacement.shape == (mesh.n_points, 3)
    assert set(r.mesh.point_data) >= {"temperature", "displacement", "stress_xx", "stress_yz",
                                      "stress_xz", "von_mises"}
    assert np.allclose(r.temperature, v.T_REF)       # no temperature condition: isothermal


def test_report_and_section_plot(pressure_result, tmp_path):
    path = fea.write_report(pressure_result, tmp_path / "fea.json", mesh="cyl.vtu")
    doc = json.loads(path.read_text())
    assert doc["dimension"] == 3 and doc["elements"] == 3648 and doc["order"] == 2
    probe = doc["probes"]["R2"]
    for k in ("x", "y", "z", "ux", "uy", "uz", "temperature", "stress_xx", "stress_yy",
              "stress_zz", "stress_xy", "stress_yz", "stress_xz", "von_mises"):
        assert isinstance(probe[k], (int, float)), k
    assert doc["solver"]["elastic"]["unknowns"] > 0
    png = fea.plot_von_mises(pressure_result, tmp_path / "vm.png", units="mm")
    assert png.stat().st_size > 10_000


def test_section_of_a_tet_mesh_covers_the_cut(mesh):
    """The cut of the quarter tube at z = 2.5 has the area of the quarter annulus (up to
    the chords) and the interpolated values of a linear field are exact."""
    from hetmesh.fea.report import tet_section

    P, T = np.asarray(mesh.points), np.asarray(mesh.cells)
    q, tri, val = tet_section(P, T, 3.0 * P[:, 0] - P[:, 1], 2, 2.5)
    a = q[tri]
    e1, e2 = a[:, 1] - a[:, 0], a[:, 2] - a[:, 0]
    area = 0.5 * np.abs(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]).sum()
    nt = 19
    chord = 0.5 * nt * np.sin(np.pi / 2 / nt) * (20.0 ** 2 - 10.0 ** 2)
    assert area == pytest.approx(chord, rel=1e-9)
    np.testing.assert_allclose(val, 3.0 * q[:, 0] - q[:, 1], atol=1e-9)


def test_conditions_name_the_problem(mesh):
    part = Part3D("c", v.graded_field(), v.case_config("pressure"))
    from dataclasses import replace

    from hetmesh.fea.config3d import PressureBC, Selection

    bad = replace(part.fea, pressure=(PressureBC(Selection(faces=("innr",)), 1e6,
                                                 "fea.pressure[0]"),))
    with pytest.raises(FEAError, match=r"fea.pressure\[0\]: no face 'innr'.*inner, outer"):
        fea.solve(mesh, part, config=bad)
    off = replace(part.fea, displacement=part.fea.displacement[:2])  # x0 free: a rigid mode
    with pytest.raises(FEAError, match="remove 5 of the 6 rigid-body modes"):
        fea.solve(mesh, part, config=off)
    plate = fea.FEAConfig(properties=part.fea.properties, temperature=(), displacement=())
    with pytest.raises(FEAError, match="2-D model, the mesh is 3-D"):
        fea.solve(mesh, part, config=plate)


TABLE = {
    "reference_temperature": 273.15, "order": 2, "solver": "amg",
    "properties": {"ceramic": {"conductivity": 35.0, "youngs_modulus": 393e9,
                               "poisson_ratio": 0.25, "expansion": 7.4e-6},
                   "metal": {"conductivity": 90.7, "youngs_modulus": 199.5e9,
                             "poisson_ratio": 0.3, "expansion": 15.4e-6}},
    "temperature": [{"faces": ["inner"], "value": 1173.15}],
    "displacement": [{"faces": ["bottom", "top"], "uz": 0}, {"edge": ["y0", "x0"], "ux": 0},
                     {"point": [10, 0, 0], "uy": 0}],
    "pressure": [{"faces": "inner", "value": 1e8}],
    "probes": {"R1": [12.5, 0, 2.5]},
}


def test_parse_fea3d():
    cfg = parse_fea3d(SchemaContext("cyl.toml"), TABLE, None, ("ceramic", "metal"), "mm")
    assert cfg.dim == 3 and cfg.order == 2 and cfg.solver == "amg"
    assert cfg.length_scale == 1e-3
    assert cfg.displacement[1].where.edge == ("y0", "x0")
    assert cfg.displacement[2].where.point == (10.0, 0.0, 0.0)
    assert cfg.pressure[0].where.faces == ("inner",)
    assert cfg.probes["R1"] == (12.5, 0.0, 2.5)


@pytest.mark.parametrize("change, message", [
    ({"solver": "cholesky"}, "fea.solver: expected one of"),
    ({"displacement": [{"faces": ["top"]}]}, r"fea.displacement\[0\]: fixes nothing"),
    ({"displacement": [{"faces": ["top"], "point": [0, 0, 0], "uz": 0}]},
     r"fea.displacement\[0\]: give exactly one of"),
    ({"displacement": [{"edge": ["top", "top"], "uz": 0}]}, "two different face names"),
    ({"probes": {"R1": [1, 2]}}, r"fea.probes.R1: expected a point \[x, y, z\]"),
    ({"displacement": []}, "at least one displacement condition"),
    ({"plane": "strain"}, "plane"),
])
def test_parse_fea3d_errors(change, message):
    with pytest.raises(ModelFileError, match=message) as e:
        parse_fea3d(SchemaContext("cyl.toml"), {**TABLE, **change}, None,
                    ("ceramic", "metal"), "mm")
    assert str(e.value).startswith("cyl.toml")
    assert "\n" not in str(e.value)


def test_extruded_fgm_plate_is_the_plane_strain_solution():
    """Case study 4 in 3-D: fgm_plate's mesh extruded (one layer), u_z = 0 on both end faces,
    the point supports held along their vertical lines: the stresses at Q1..Q6 agree with
    the 2-D plane-strain solution on the same mesh within 1 % of von Mises (quadratic
    elements, as the model sets)."""
    import hetmesh

    model = hetmesh.load_model(hetmesh.example_path("fgm_plate"))
    mesh = hetmesh.generate(model, 0.2).mesh
    out = v.plane_strain_check(model, mesh)
    assert len(out["3d"].tets) == 3 * mesh.n_elements
    for name in ("Q1", "Q2", "Q3", "Q4", "Q5", "Q6"):
        p = out["probes"][name]
        assert p["difference"] < 0.01, (name, p)
        assert abs(p["vm_3d"] / p["vm_2d"] - 1) < 0.01

