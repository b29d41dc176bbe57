"""Solution-adaptive refinement of tetrahedral meshes (hetmesh.fea.adapt): the
Zienkiewicz-Zhu estimator, Doerfler marking, the refined mesh checked here independently of
hetmesh's own verification, the graded cylinder's probe error, determinism, and the CLI."""

from __future__ import annotations

import math

import numpy as np
import pytest

import hetmesh
from hetmesh.cli import main
from hetmesh.errors import OptionError
from hetmesh.fea import adapt as ad
from hetmesh.fea import goal
from hetmesh.fea.solid import Displacement, solve_tets

E0, NU0 = 200e9, 0.3
CHORD = 2e-4          # the 3-D study's chord tolerance (x the diameter)
START_CHORD = 1e-3    # the chord tolerance of the refined family's start


def homogeneous(x):
    one = np.ones(len(x))
    return {"conductivity": 40.0 * one, "youngs_modulus": E0 * one,
            "poisson_ratio": NU0 * one, "expansion": 1.2e-5 * one}


@pytest.fixture(scope="module")
def cylinder():
    return hetmesh.load_model(hetmesh.example_path("graded_cylinder"))


@pytest.fixture(scope="module")
def start(cylinder):
    return hetmesh.generate(cylinder, 0.4, chord_tol=CHORD).mesh


@pytest.mark.parametrize("order", [1, 2])
def test_estimator_vanishes_for_uniform_stress(order):
    """A homogeneous block under a uniform pressure on x = 1 with roller supports: the
    exact displacement is linear and the stress uniform, which both element orders
    represent exactly, so sigma* = sigma_h and the indicator is zero to rounding."""
    from skfem import MeshTet

    m = MeshTet.init_tensor(*(np.linspace(0.0, 1.0, 4),) * 3)
    P, T = m.p.T.copy(), m.t.T.copy()
    disp = [Displacement(np.isclose(P[:, 0], 0), ux=0.0),
            Displacement(np.isclose(P[:, 1], 0), uy=0.0),
            Displacement(np.isclose(P[:, 2], 0), uz=0.0)]
    r = solve_tets(P, T, homogeneous, order=order, displacement=disp,
                   pressure=[(np.isclose(P[:, 0], 1), 50e6)], solver="direct")
    assert r.energy > 0
    np.testing.assert_allclose(r.stress[:, 0], -50e6, rtol=1e-9)   # the problem is right
    assert ad.relative_estimate(r.error_indicator, r.energy) < 1e-8
    assert r.error_indicator.max() < 1e-8 * r.energy


def test_estimator_sees_a_stress_gradient():
    """Bending-like loading (a linearly varying pressure is not available; a point-like
    support instead): P1 elements cannot represent it, the indicator is not zero."""
    from skfem import MeshTet

    m = MeshTet.init_tensor(*(np.linspace(0.0, 1.0, 4),) * 3)
    P, T = m.p.T.copy(), m.t.T.copy()
    corner = np.isclose(P[:, 0], 0) & np.isclose(P[:, 1], 0)
    disp = [Displacement(corner, ux=0.0, uy=0.0),
            Displacement(np.isclose(P[:, 2], 0), uz=0.0),
            Displacement(np.isclose(P[:, 0], 0) & np.isclose(P[:, 1], 1), ux=0.0)]
    r = solve_tets(P, T, homogeneous, order=1, displacement=disp,
                   pressure=[(np.isclose(P[:, 0], 1), 50e6)], solver="direct")
    assert ad.relative_estimate(r.error_indicator, r.energy) > 1e-3


def test_doerfler_marking():
    eta = np.array([1.0, 3.0, 2.0, 0.5, 2.0])
    got = ad.doerfler_mark(eta, 0.5)
    # eta^2 = 1, 9, 4, .25, 4 (18.25): 9 < 9.125, 9 + 4 >= 9.125 -> two, the tie by index
    assert got.tolist() == [False, True, True, False, False]
    assert ad.doerfler_mark(eta, 1.0).all()
    assert not ad.doerfler_mark(np.zeros(3), 0.5).any()


def independent_problems(mesh, model, threshold: float) -> list[str]:
    """The refined cylinder checked without hetmesh's verification: orientation,
    conformity, the boundary equal to the facets and on the exact surfaces, volume, delta."""
    P, T = np.asarray(mesh.points), np.asarray(mesh.cells, dtype=np.int64)
    out = []
    a, b, c, d = (P[T[:, k]] for k in range(4))
    vol = np.einsum("ij,ij->i", np.cross(b - a, c - a), d - a) / 6.0
    if not (vol > 0).all():
        out.append(f"{int((vol <= 0).sum())} tetrahedra without positive volume")
    faces = np.sort(np.concatenate([T[:, [1, 2, 3]], T[:, [0, 2, 3]], T[:, [0, 1, 3]],
                                    T[:, [0, 1, 2]]]), axis=1)
    uniq, count = np.unique(faces, axis=0, return_counts=True)
    if (count > 2).any():
        out.append("a face shared by more than two tetrahedra")
    bnd = uniq[count == 1]
    facets = np.unique(np.sort(np.asarray(mesh.facets), axis=1), axis=0)
    if bnd.shape != facets.shape or (bnd != facets).any():
        out.append("the boundary triangles are not the mesh's facets")
    names = {m: n for m, n in mesh.marker_names.items()}
    want = {"inner": 10.0, "outside": 20.0}
    for f, mk in zip(np.asarray(mesh.facets), np.asarray(mesh.facet_markers)):
        name = names[int(mk)]
        q = P[f]
        if name in want:
            r = np.hypot(q[:, 0], q[:, 1])
            if np.abs(r - want[name]).max() > 1e-9 * want[name]:
                out.append(f"a vertex of face {name} off its cylinder")
                break
        else:
            k, v = {"x0": (0, 0.0), "y0": (1, 0.0), "bottom": (2, 0.0), "top": (2, 5.0)}[name]
            if np.abs(q[:, k] - v).max() > 1e-12:
                out.append(f"a vertex of face {name} off its plane")
                break
    exact = math.pi / 4 * (20 ** 2 - 10 ** 2) * 5
    if not (0 < exact - vol.sum() < 0.002 * exact):
        out.append(f"volume {vol.sum():.9g} against {exact:.9g}")
    comp = np.asarray(model.material.composition(P))
    ct = comp[T]
    delta = (ct.max(axis=1) - ct.min(axis=1)).max(axis=1)
    if not delta.max() < threshold:
        out.append(f"delta_max {delta.max():.6g} not below {threshold}")
    for j, name in enumerate(model.constituents):
        if not np.allclose(mesh.point_data[name], comp[:, j], rtol=0, atol=1e-12):
            out.append(f"point data {name} is not the composition")
    return out


def _refined_once(model, mesh, fraction=0.3):
    r = hetmesh.fea.solve(mesh, model)
    marked = ad.doerfler_mark(r.error_indicator, fraction)
    faces, markers = ad.mesh_faces(mesh, model.solid)
    ref = ad.refine_marked(mesh.points, mesh.cells, faces, markers, marked, solid=model.solid,
                           field=model.material, threshold=0.4,
                           chord_tol=CHORD * model.solid.diameter)
    return r, marked, ref


def _refine_inner(model, mesh, times):
    """Refine the tetrahedra touching the inner face ``times`` times (the mesher's default
    chord tolerance: long chords, whose new vertices must go onto the cylinder)."""
    faces, markers = ad.mesh_faces(mesh, model.solid)
    inner = 1 + model.solid.face_names.index("inner")
    P, T = np.asarray(mesh.points), np.asarray(mesh.cells)
    snapped, refs = 0, []
    for _ in range(times):
        on = np.zeros(len(P), dtype=bool)
        on[faces[markers == inner].ravel()] = True
        ref = ad.refine_marked(P, T, faces, markers, on[T].any(axis=1), solid=model.solid,
                               field=model.material, threshold=0.4)
        assert len(ref.tets) > len(T)
        P, T, faces, markers = ref.points, ref.tets, ref.faces, ref.markers
        snapped += ref.snapped
        refs.append(ref)
    return refs[-1], snapped


def test_refined_mesh_passes_independent_checks_and_is_deterministic(cylinder):
    coarse = hetmesh.generate(cylinder, 0.4).mesh
    ref, snapped = _refine_inner(cylinder, coarse, 2)
    assert snapped > 10                    # new vertices of the inner chords moved out
    mesh = ad.refined_mesh(ref, cylinder.constituents, cylinder.solid.face_names)
    assert independent_problems(mesh, cylinder, 0.4) == []
    # the check can fail: midpoints of chords left where they are are off the cylinder
    from hetmesh.tet.refine import bisect_edges
    from hetmesh.tet.sampling import bisect_faces

    tri = ref.faces[ref.markers == 1 + cylinder.solid.face_names.index("inner")][0]
    pairs = [(tri[0], tri[1]), (tri[1], tri[2]), (tri[2], tri[0])]
    split = np.array([max(pairs, key=lambda e: np.hypot(*(ref.points[e[0], :2]
                                                            - ref.points[e[1], :2])))])
    F, Mk = bisect_faces(ref.faces, ref.markers, split, len(ref.points))
    P2, T2 = bisect_edges(ref.points, ref.tets, split)
    C2 = cylinder.material.composition(P2)
    bad = ad.Refined(P2, T2, C2, np.zeros(len(T2)), None, F, Mk, 0, 0, 0)
    assert np.hypot(*P2[-1, :2]) < 10 - 1e-9
    assert any("off its cylinder" in p for p in independent_problems(
        ad.refined_mesh(bad, cylinder.constituents, cylinder.solid.face_names), cylinder, 0.4))
    again, _ = _refine_inner(cylinder, coarse, 2)
    assert np.array_equal(again.points, ref.points) and np.array_equal(again.tets, ref.tets)
    assert np.array_equal(again.faces, ref.faces) and np.array_equal(again.markers,
                                                                     ref.markers)


def test_refinement_of_marked_elements(cylinder, start):
    r, marked, ref = _refined_once(cylinder, start)
    assert 0 < marked.sum() < len(marked)
    assert len(ref.tets) >= len(start.cells) + marked.sum()   # every marked one bisected
    mesh = ad.refined_mesh(ref, cylinder.constituents, cylinder.solid.face_names)
    assert independent_problems(mesh, cylinder, 0.4) == []


def test_snap_to_surface_puts_chord_midpoints_on_the_arc(cylinder):
    solid = cylinder.solid
    a = np.array([10 * math.cos(0.3), 10 * math.sin(0.3), 1.0])
    b = np.array([10 * math.cos(0.4), 10 * math.sin(0.4), 2.0])
    c = np.array([10 * math.cos(0.35), 10 * math.sin(0.35), 4.0])
    P = np.array([a, b, c, 0.5 * (a + b)])
    inner = 1 + solid.face_names.index("inner")
    q = ad.snap_to_surface(solid, P, np.array([3]), np.array([[0, 1, 3], [3, 1, 2]]),
                           np.array([inner, inner]))
    assert math.isclose(math.hypot(*q[3, :2]), 10.0, rel_tol=1e-14)
    assert q[3, 2] == 1.5 and np.array_equal(q[:3], P[:3])
    angle = math.atan2(q[3, 1], q[3, 0])
    assert math.isclose(angle, 0.35, rel_tol=1e-12)


def test_refinement_goes_where_the_mesh_is_coarse_for_the_stress(cylinder, start):
    """The grading is flat near the inner face and the chord tolerance keeps the elements
    along the inner arc small, so the material-adaptive mesh is coarsest in the middle of
    the wall, where the pressure's stress still varies: the estimator marks elements there,
    and none at the inner or outer face."""
    r, marked, _ = _refined_once(cylinder, start)
    P, T = np.asarray(start.points), np.asarray(start.cells)
    rc = np.hypot(*P[T].mean(axis=1)[:, :2].T)
    mid, faces = (rc > 12.5) & (rc < 17.5), (rc < 11) | (rc > 19)
    assert marked[mid].mean() > 0.1 and marked[faces].mean() < 0.01


def test_refinement_reduces_the_cylinder_probe_error(cylinder, start):
    from hetmesh.fea.probe_study import radial_reference

    ref = radial_reference(cylinder)["von_mises"]
    a = ad.adapt(start, cylinder, 0.4, tolerance=1e-6, steps=3, fraction=0.5, chord_tol=CHORD)
    assert a.reason == "steps" and len(a.steps) == 4

    def err(st):
        return max(abs(st["von_mises"][k] - ref[k]) / ref[k] for k in ref)

    counts = [s["elements"] for s in a.steps]
    assert counts == sorted(counts) and counts[0] < counts[-1]
    est = [s["estimate"] for s in a.steps]
    assert est[-1] < 0.8 * est[0]
    assert err(a.steps[-1]) < 0.6 * err(a.steps[0])
    assert a.mesh.n_elements == counts[-1]
    assert "error_indicator" in a.result.mesh.cell_data
    assert independent_problems(a.mesh, cylinder, 0.4) == []


def test_adapt_stops_at_the_tolerance_and_the_budget(cylinder, start):
    a = ad.adapt(start, cylinder, 0.4, tolerance=0.5, steps=4)
    assert a.reason == "tolerance" and len(a.steps) == 1
    b = ad.adapt(start, cylinder, 0.4, tolerance=1e-6, steps=4,
                 max_elements=start.n_elements + 1)
    assert b.reason == "max_elements" and len(b.steps) == 1


@pytest.mark.parametrize("kw, word", [
    ({"tolerance": 0.0}, "--adapt"), ({"tolerance": 1e-3, "steps": -1}, "--adapt-steps"),
    ({"tolerance": 1e-3, "fraction": 1.5}, "--adapt-fraction"),
    ({"tolerance": 1e-3, "max_elements": 0}, "--max-elements")])
def test_bad_options_are_named(cylinder, start, kw, word):
    with pytest.raises(OptionError, match=word):
        ad.adapt(start, cylinder, 0.4, **kw)


def test_cli_adapt(tmp_path, capsys, cylinder, start):
    model = hetmesh.example_path("graded_cylinder")
    mesh = tmp_path / "cyl.vtu"
    start.write(mesh)
    out, rep = tmp_path / "a.vtu", tmp_path / "a.json"
    rc = main(["fea", str(model), "--mesh", str(mesh), "--adapt", "0.001", "-d", "0.4",
               "--adapt-steps", "1", "--adapt-fraction", "0.2", "-o", str(out),
               "--report", str(rep)])
    assert rc == 0
    import json

    doc = json.loads(rep.read_text())
    assert [s["step"] for s in doc["adaptive"]["steps"]] == [0, 1]
    got = hetmesh.io.read.read_mesh(out)
    assert got.n_elements == doc["adaptive"]["steps"][1]["elements"] == doc["elements"]
    capsys.readouterr()
    for argv, word in [(["--adapt", "0.01"], "--threshold"),
                       (["--adapt-steps", "2"], "--adapt-steps"),
                       (["--adapt", "2", "-d", "0.4"], "--adapt"),
                       (["--adapt", "0.01", "-d", "0.1"], "delta_0"),
                       (["--adapt", "x", "-d", "0.4"], "--adapt")]:
        rc = main(["fea", str(model), "--mesh", str(mesh), *argv])
        err = capsys.readouterr().err.strip()
        assert rc == 2, argv
        assert len(err.splitlines()) == 1 and word in err, err


@pytest.mark.slow  # 10-28 s: the default step stays under 10 minutes
def test_refinement_study_and_its_table(cylinder):
    """The 3-D study's third family on a small plan: every step a mesh with its errors,
    the counts for 0.5 % of the three families, and the table of ``reproduce --3d``."""
    from hetmesh.fea import probe_study as ps
    from hetmesh.reproduce.report import render3d
    from hetmesh.reproduce.study3d import Section3D

    ref = ps.radial_reference(cylinder)
    s = ps.study3d(cylinder, ref, uniform_elements=(800, 3000), thresholds=(0.4,),
                   chord_tol=CHORD)
    r = ad.refinement_study(cylinder, ref, s, threshold=0.4, chord_tol=CHORD, steps=1,
                            fraction=0.3)
    assert [m["param"] for m in r["meshes"]] == [0, 1]
    first = r["meshes"][0]
    adaptive = next(m for m in s.meshes if m["family"] == "adaptive")
    assert first["elements"] == adaptive["elements"]          # the same starting mesh
    # the same solve up to rounding: the two solves are not always bit-identical (a
    # relative 1.02e-12 was seen in a parallel run; the cause is not identified)
    assert first["von_mises"] == pytest.approx(adaptive["von_mises"], rel=1e-9)
    nd = r["needed"]["R"]
    assert nd["uniform"] == s.needed_by_set["R"]["uniform"]
    if nd["ratio"] is not None:
        assert nd["ratio"] == pytest.approx(nd["refined"] / nd["uniform"])
    sec = Section3D(quick=True, studies={"graded_cylinder": s},
                    refinements={"graded_cylinder": r})
    text = "\n".join(render3d(sec))
    assert "(c) adaptive + refined" in text and "probe estimate" in text
    assert r["indicator"] == "goal" and r["start_chord_tol"] == CHORD
    assert "uniform_start_chord" not in r and "(a') uniform" not in text
    # a coarser start, and the uniform family again at its chord tolerance (like for like)
    c = ad.refinement_study(cylinder, ref, s, threshold=0.4, chord_tol=CHORD,
                            start_chord_tol=START_CHORD, uniform_elements=(800, 3000),
                            steps=1, fraction=0.3)
    assert c["meshes"][0]["elements"] < first["elements"]    # fewer chords on the arcs
    assert len(c["uniform_start_chord"]) == 2
    same = [m["elements"] for m in c["uniform_start_chord"]]
    theirs = [m["elements"] for m in s.meshes if m["family"] == "uniform"]
    assert same[0] < theirs[0]             # the coarse uniform mesh has fewer chords too
    nd = c["needed"]["R"]
    if nd["ratio_start_chord"] is not None:
        assert nd["ratio_start_chord"] == pytest.approx(nd["refined"]
                                                        / nd["uniform_start_chord"])
    sec = Section3D(quick=True, studies={"graded_cylinder": s},
                    refinements={"graded_cylinder": c})
    assert "(a') uniform, chord 0.001" in "\n".join(render3d(sec))


@pytest.fixture(scope="module")
def coarse_start(cylinder):
    """The refined family's start in the 3-D study: chord tolerance 1e-3 (1,287 tets)."""
    return hetmesh.generate(cylinder, 0.4, chord_tol=START_CHORD).mesh


def test_von_mises_direction_is_the_relative_derivative():
    s = np.array([120e6, -30e6, 10e6, 25e6, -5e6, 40e6])
    n = goal.von_mises_direction(s)

    def vm(v):
        return math.sqrt(0.5 * ((v[0] - v[1]) ** 2 + (v[1] - v[2]) ** 2 + (v[2] - v[0]) ** 2)
                         + 3 * (v[3] ** 2 + v[4] ** 2 + v[5] ** 2))

    d = np.array([1e3, 3e3, -2e3, 4e3, 1e3, -3e3])
    D = np.array([[d[0], d[3], d[5]], [d[3], d[1], d[4]], [d[5], d[4], d[2]]])
    # n : d sigma is the relative change of von Mises to first order
    assert float((n * D).sum()) == pytest.approx((vm(s + d) - vm(s)) / vm(s), rel=1e-3)
    assert abs(np.trace(n)) < 1e-20 and np.allclose(n, n.T)
    assert not goal.von_mises_direction(np.array([5.0, 5, 5, 0, 0, 0])).any()


def test_dual_load_is_the_probe_functional(cylinder, coarse_start):
    """The dual problem's load applied to the primal displacement is J(u_h): the sum over
    the probes of the mollified n_i : sigma_h, each about 1 (relative von Mises), so about
    the number of probes (P1, whose dofs are the vertices the result reports)."""
    from dataclasses import replace

    cfg = replace(cylinder.fea, order=1)
    r = hetmesh.fea.solve(coarse_start, cylinder, config=cfg)
    d = goal.dual_solution(coarse_start, cylinder, cfg, r.probes)
    J = float(d.load @ np.asarray(r.displacement).ravel())
    assert J == pytest.approx(3.0, rel=0.03)
    assert set(d.rho) == {"R1", "R2", "R3"}
    one = goal.dual_solution(coarse_start, cylinder, cfg, r.probes, names=["R2"])
    assert float(one.load @ np.asarray(r.displacement).ravel()) == pytest.approx(1.0, rel=0.03)
    with pytest.raises(hetmesh.errors.FEAError, match="R9"):
        goal.dual_solution(coarse_start, cylinder, cfg, r.probes, names=["R9"])


def test_goal_functional_mollifier_floor(cylinder, coarse_start):
    """The mollifier's floor is ``element_factor`` x the longest edge of the probe's
    element: a smaller factor narrows the functional (J(u_h) still about 1 for one probe)
    and pulls the dual's error towards the probe; a factor <= 0 is refused before any
    solve."""
    from dataclasses import replace

    cfg = replace(cylinder.fea, order=1)
    r = hetmesh.fea.solve(coarse_start, cylinder, config=cfg)
    u = np.asarray(r.displacement).ravel()
    P, T = np.asarray(coarse_start.points), np.asarray(coarse_start.cells)
    dist = np.linalg.norm(P[T].mean(axis=1) - np.array(cylinder.fea.probes["R2"]), axis=1)
    floor = goal.DEFAULT_RADIUS * cylinder.solid.diameter
    wide = goal.dual_solution(coarse_start, cylinder, cfg, r.probes, names=["R2"])
    assert goal.DEFAULT_ELEMENT_FACTOR == 1.0 and wide.rho["R2"] > 4 * floor
    spread = []
    for f in (0.5, 0.25):
        d = goal.dual_solution(coarse_start, cylinder, cfg, r.probes, names=["R2"],
                               element_factor=f)
        assert d.rho["R2"] == pytest.approx(max(floor, f * wide.rho["R2"]))
        assert float(d.load @ u) == pytest.approx(1.0, rel=0.05)
        eta_z, _ = goal.dual_indicator(d)
        spread.append(float((eta_z ** 2 * dist).sum() / (eta_z ** 2).sum()))
    eta_w, _ = goal.dual_indicator(wide)
    assert spread[1] < spread[0] < float((eta_w ** 2 * dist).sum() / (eta_w ** 2).sum())
    with pytest.raises(hetmesh.errors.FEAError, match="element factor"):
        goal.dual_solution(coarse_start, cylinder, cfg, r.probes, element_factor=0.0)
    with pytest.raises(OptionError, match="goal_element_factor"):
        ad.adapt(coarse_start, cylinder, 0.4, tolerance=1e-3, indicator="goal",
                 goal_element_factor=-1.0)


def test_goal_oriented_marks_go_to_the_probes(cylinder, coarse_start):
    """With the dual weights the marks gather around R1..R3; ZZ's energy-norm marks spread
    over the wall."""
    r = hetmesh.fea.solve(coarse_start, cylinder)
    eta_z, energy = goal.dual_indicator(goal.dual_solution(coarse_start, cylinder,
                                                           cylinder.fea, r.probes))
    assert energy > 0 and eta_z.shape == r.error_indicator.shape
    P, T = np.asarray(coarse_start.points), np.asarray(coarse_start.cells)
    probes = np.array(list(cylinder.fea.probes.values()))
    dist = np.linalg.norm(P[T].mean(axis=1)[:, None] - probes[None], axis=2).min(axis=1)
    near = dist < 3.0                      # a quarter of the elements
    assert (eta_z[near] ** 2).sum() > 0.5 * (eta_z ** 2).sum()
    by_goal = ad.doerfler_mark(goal.goal_indicator(r.error_indicator, eta_z), 0.3)
    by_energy = ad.doerfler_mark(r.error_indicator, 0.3)
    assert by_goal.any() and by_energy.any()
    assert dist[by_goal].mean() < 0.5 * dist[by_energy].mean()


def test_goal_oriented_refinement_keeps_the_probes_within_the_target(cylinder, coarse_start):
    """From the coarser start the probe error is below 0.5 % and stays there as the
    dual-weighted marks refine; the meshes pass the independent checks."""
    from hetmesh.fea.probe_study import radial_reference

    ref = radial_reference(cylinder)["von_mises"]
    a = ad.adapt(coarse_start, cylinder, 0.4, tolerance=1e-6, steps=2, fraction=0.5,
                 chord_tol=START_CHORD, indicator="goal")
    assert a.indicator == "goal" and a.report()["indicator"] == "goal"
    errs = [max(abs(st["von_mises"][k] - ref[k]) / ref[k] for k in ref) for st in a.steps]
    assert all(e < 0.005 for e in errs), errs
    assert all(st["estimate_of"] == "probes" for st in a.steps)
    est = [st["estimate"] for st in a.steps]
    assert est[-1] < 0.8 * est[0]
    counts = [st["elements"] for st in a.steps]
    assert counts[0] == coarse_start.n_elements < counts[1] < counts[2]
    assert independent_problems(a.mesh, cylinder, 0.4) == []
    with pytest.raises(OptionError, match="indicator: expected"):
        ad.adapt(coarse_start, cylinder, 0.4, tolerance=1e-3, indicator="dual")


def test_cli_adapt_needs_a_tetrahedral_mesh(tmp_path, capsys):
    model = hetmesh.example_path("fgm_plate")
    mesh = tmp_path / "plate.vtu"
    hetmesh.generate(hetmesh.load_model(model), 0.4).mesh.write(mesh)
    rc = main(["fea", str(model), "--mesh", str(mesh), "--adapt", "0.01", "-d", "0.4"])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and len(err.splitlines()) == 1 and "tetrahedral" in err, err


def test_stress_metric_keeps_the_directions_the_stress_varies_along():
    """Where the stress varies along every axis the metric is a rotation (the longest edges
    are bisected, as without it); a direction without variation is shrunk by 1/STRETCH."""
    rng = np.random.default_rng(5)
    x = rng.random((40, 3))
    from scipy.spatial import Delaunay

    T = Delaunay(x).simplices
    s = np.zeros((40, 6))
    s[:, 0], s[:, 1], s[:, 3] = x[:, 0] + x[:, 2], 2 * x[:, 1], 0.7 * x[:, 2]
    A = ad.stress_metric(x, T, s)
    np.testing.assert_allclose(A @ A.T, np.eye(3), atol=1e-12)
    np.testing.assert_array_equal(ad.stress_metric(x, T, np.ones((40, 6))), np.eye(3))
    s[:, 3] = 0.0
    s[:, 0] = x[:, 0] + 1e-3 * x[:, 2]                     # hardly any change along z
    A = ad.stress_metric(x, T, s)
    assert np.isclose(np.linalg.norm(A[2]), 1 / ad.STRETCH, rtol=1e-5)
    np.testing.assert_allclose(np.linalg.norm(A[:2], axis=1), 1.0, rtol=1e-5)


def test_stress_edges_split_across_the_tube_not_along_its_axis(cylinder, coarse_start):
    """The tube is in plane strain: its stress does not vary along z, so with
    ``edge_key`` from :func:`stress_edge_key` the marked tetrahedra are bisected across the
    axis -- no new vertex on a vertical line of the swept start, where the longest edges
    put some -- and the mesh passes the independent checks."""
    r = hetmesh.fea.solve(coarse_start, cylinder)
    key, A = ad.stress_edge_key(r, coarse_start.points)
    assert np.isclose(np.abs(A[2]).max(), 1 / ad.STRETCH, rtol=1e-3)
    marked = ad.doerfler_mark(r.error_indicator, 0.5)
    faces, markers = ad.mesh_faces(coarse_start, cylinder.solid)
    P0 = np.asarray(coarse_start.points)
    columns = {tuple(p) for p in P0[:, :2].round(9)}

    def vertical(ref):
        new = ref.points[len(P0):, :2].round(9)
        return sum(tuple(p) in columns for p in new), len(new)

    got = {}
    for name, k in (("longest", None), ("stress", key)):
        ref = ad.refine_marked(P0, coarse_start.cells, faces, markers, marked,
                               solid=cylinder.solid, field=cylinder.material, threshold=0.4,
                               chord_tol=START_CHORD * cylinder.solid.diameter, edge_key=k)
        got[name] = vertical(ref)
        mesh = ad.refined_mesh(ref, cylinder.constituents, cylinder.solid.face_names)
        assert independent_problems(mesh, cylinder, 0.4) == []
    assert got["longest"][0] > 0 and got["stress"][0] == 0 and got["stress"][1] > 10, got
    with pytest.raises(OptionError, match="edges"):
        ad.adapt(coarse_start, cylinder, 0.4, tolerance=1e-3, edges="shortest")
