"""The 3-D section of ``hetmesh reproduce`` and the 3-D probe study (small plans: the real
plans are benchmarks/bench_study3d.py's)."""

from __future__ import annotations

import math

import numpy as np
import pytest

import hetmesh
from hetmesh import peers
from hetmesh.cli import main
from hetmesh.errors import FEAError
from hetmesh.fea import probe_study as ps
from hetmesh.fea import verification
from hetmesh.io.model import load_model
from hetmesh.reproduce import plan, split_cases
from hetmesh.reproduce.report import render3d
from hetmesh.reproduce.study3d import CASES3D, Section3D, mesh_run3d

HAVE_GMSH = peers.available()["gmsh"] is not None


@pytest.fixture(scope="module")
def cylinder():
    return load_model(hetmesh.example_path("graded_cylinder"))


def test_radial_reference_is_the_exact_tube_solution(cylinder):
    """The reference built from the model file (arcs, composition, [fea] table) is the
    validation case's radial solution: von Mises of (sigma_r, sigma_t, sigma_z)."""
    ref = ps.radial_reference(cylinder)
    sol = verification.reference("pressure")
    for name, q in cylinder.fea.probes.items():
        r = math.hypot(q[0], q[1])
        s = np.array([sol.sigma_r(r), sol.sigma_t(r), sol.sigma_z(r)], dtype=float)
        vm = math.sqrt(0.5 * ((s[0] - s[1]) ** 2 + (s[1] - s[2]) ** 2 + (s[2] - s[0]) ** 2))
        assert ref["von_mises"][name] == pytest.approx(vm, rel=1e-10)
    assert ref["error_estimate"] < 1e-8


def test_radial_reference_refuses_a_solid_that_is_not_a_tube():
    plate = load_model(hetmesh.example_path("fgm_plate_3d"))
    with pytest.raises(FEAError, match="radial reference"):
        ps.radial_reference(plate)


def test_plane_strain_reference_needs_matching_probes():
    plate = load_model(hetmesh.example_path("fgm_plate_3d"))
    other = load_model(hetmesh.example_path("power_plate"))
    with pytest.raises(FEAError):
        ps.plane_strain_reference(plate, other, elements=500)


def test_study3d_small_plan_against_the_exact_solution(cylinder):
    """Two uniform and two adaptive meshes: errors against the exact solution, recomputed
    here from the recorded stresses, and the tets-needed bookkeeping."""
    ref = ps.radial_reference(cylinder)
    s = ps.study3d(cylinder, ref, uniform_elements=(800, 3000), thresholds=(0.4, 0.25),
                   chord_tol=1e-3)
    assert s.dim == 3 and s.primary == "R" and s.order == 2
    assert [m["family"] for m in s.meshes] == ["uniform"] * 2 + ["adaptive"] * 2
    for m in s.meshes:
        assert "error" not in m, m
        err = max(abs(m["von_mises"][k] - ref["von_mises"][k]) / ref["von_mises"][k]
                  for k in ("R1", "R2", "R3"))
        assert m["max_error"] == pytest.approx(err, rel=1e-12)
        assert m["max_error"] < 0.05   # quadratic tetrahedra: a few per cent at worst
    u = [m["elements"] for m in s.meshes if m["family"] == "uniform"]
    assert u[0] < u[1]
    d = s.to_dict()
    assert d["dim"] == 3 and d["needed"]["probes"] == "R"


def test_h_for_tets_gives_about_the_count(cylinder):
    from hetmesh.tet.uniform import uniform_tets_at

    h = ps.h_for_tets(cylinder.solid.volume, 5000)
    n = len(uniform_tets_at(cylinder, h, 0.5).tets)
    assert 0.5 * 5000 < n < 2.0 * 5000


def test_mesh_run3d_and_its_table(cylinder):
    run = mesh_run3d(CASES3D["graded_cylinder"], 0.3, cylinder, [])
    assert run.error is None
    assert run.adaptive["delta_max"] < 0.3 and run.uniform["delta_max"] < 0.3
    assert run.ratio == pytest.approx(run.adaptive["elements"] / run.uniform["elements"])
    text = "\n".join(render3d(Section3D(quick=True, runs=[run])))
    assert "## 3-D" in text and f"| graded_cylinder | 0.3 | {run.adaptive['elements']} |" \
        in text


def test_case_names_split_between_the_sections():
    assert split_cases(["power_plate", "graded_cylinder"]) == (["power_plate"],
                                                                ["graded_cylinder"])
    assert split_cases(["graded_cylinder"]) == ([], ["graded_cylinder"])
    assert plan(["graded_cylinder"]) == []
    assert [c.name for c, _ in plan(["power_plate", "fgm_plate_3d"], quick=True)] == \
        ["power_plate"]


@pytest.mark.skipif(not HAVE_GMSH, reason="gmsh is not installed")
def test_gmsh_3d_peer_meets_the_threshold(cylinder):
    r = peers.search3d("gmsh", cylinder, 0.3)
    assert r.stats.delta_max < 0.3 and r.stats.n_elements > 0
    p = r.mesh.points
    assert len(r.mesh.tets) == r.stats.n_elements
    assert np.hypot(p[:, 0], p[:, 1]).min() >= 10 * (1 - 1e-6)
    assert any(not x["pass"] for x in r.trace)  # the search saw a failing scale


def test_gmsh_3d_peer_refuses_a_solid_that_is_not_an_extrusion():
    cube = load_model(hetmesh.example_path("unit_cube"))
    with pytest.raises(hetmesh.errors.HetmeshError):
        peers.search3d("gmsh", cube, 0.2)


@pytest.mark.slow
def test_cli_reproduce_3d_quick(tmp_path, capsys):
    out = tmp_path / "rep"
    code = main(["reproduce", "--quick", "--cases", "graded_cylinder", "--out", str(out)])
    o, err = capsys.readouterr()
    assert code == 0, err
    text = (out / "report.md").read_text()
    assert "## 3-D" in text and "### 3-D FEA study" in text
    assert "3-D FEA graded_cylinder" in o


def test_run3d_with_a_plan_of_its_own():
    """The study's plan can be overridden (benchmarks/bench_study3d.py --uniform,
    --thresholds), and the mesh table skipped."""
    from hetmesh.reproduce.study3d import run3d

    sec = run3d(cases=["graded_cylinder"], meshes=False, uniform_elements=[800],
                thresholds=[])
    assert sec.runs == [] and not sec.study_errors
    s = sec.studies["graded_cylinder"]
    assert [m["family"] for m in s.meshes] == ["uniform"] and "error" not in s.meshes[0]
    text = "\n".join(render3d(sec))
    assert "graded_cylinder" in text and "| R |" in text


def test_refine_case_takes_the_solids_start_and_mollifier(cylinder):
    """Each solid's refined family starts from its own chord tolerance and aims the goal
    functional with its own mollifier floor (the plate's differ from the cylinder's)."""
    from dataclasses import replace

    from hetmesh.reproduce.study3d import REFINE_START_CHORD_TOL, refine_case

    tube, plate = CASES3D["graded_cylinder"], CASES3D["fgm_plate_3d"]
    assert tube.refine_start_chord == REFINE_START_CHORD_TOL
    assert tube.refine_element_factor is None
    assert plate.refine_start_chord == REFINE_START_CHORD_TOL
    assert plate.refine_element_factor < 1.0
    ref = ps.radial_reference(cylinder)
    s = ps.study3d(cylinder, ref, uniform_elements=(800,), thresholds=(0.4,), chord_tol=2e-4)
    plan = {"uniform_elements": [800], "thresholds": [0.4]}
    case = replace(tube, refine_start_chord=2e-3, refine_element_factor=0.5)
    r = refine_case(case, cylinder, s, True, plan, steps=1)
    assert r["start_chord_tol"] == 2e-3 and r["goal_element_factor"] == 0.5
    assert r["edges"] == "stress"
    start = hetmesh.generate(cylinder, 0.4, chord_tol=2e-3).mesh
    counts = [m["elements"] for m in r["meshes"]]
    assert counts[0] == start.n_elements < counts[1] and len(counts) == 2
    text = "\n".join(render3d(Section3D(quick=True, studies={"graded_cylinder": s},
                                        refinements={"graded_cylinder": r})))
    assert "chord tolerance 0.002" in text and "mollifier at least 0.5 x" in text
    default = refine_case(tube, cylinder, s, True, plan, steps=0)
    assert default["goal_element_factor"] == 1.0
    assert default["start_chord_tol"] == REFINE_START_CHORD_TOL
