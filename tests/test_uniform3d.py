"""The uniform tetrahedral baseline (hetmesh.tet.uniform): every kind of solid, the size
search, verification, determinism, the budget, the CLI."""

from __future__ import annotations

import math

import meshio
import numpy as np
import pytest

import hetmesh
from conftest import EXAMPLES_3D
from hetmesh.cli import main
from hetmesh.errors import BudgetError, OptionError
from hetmesh.io.model import load_model
from hetmesh.tet.carve import CarvedSolid
from hetmesh.tet.implicit import CSGSolid
from hetmesh.tet.uniform import uniform_model, uniform_tets_at
from test_tet import check_tet_mesh

#: every example solid at a threshold coarse enough for a fast test
COARSE = {"unit_cube": 0.3, "graded_rod": 0.3, "graded_cylinder": 0.3, "graded_ring": 0.3,
          "fgm_plate_3d": 0.4, "blade_3d": 0.4}


def _model(name):
    return load_model(hetmesh.example_path(name))


def _edges(p, t):
    e = np.sort(t[:, [0, 0, 0, 1, 1, 2, 1, 2, 3, 2, 3, 3]].reshape(-1, 2, 6)
                .transpose(0, 2, 1).reshape(-1, 2), axis=1)
    e = np.unique(e, axis=0)
    return np.linalg.norm(p[e[:, 0]] - p[e[:, 1]], axis=1)


def _delta_independent(model, mesh):
    """delta over the four vertices, the compositions evaluated again (each vertex in its
    tetrahedron's subregion when the mesh has subregions)."""
    p, t = mesh.points, mesh.cells
    sub = mesh.cell_data.get("subregion")
    if sub is None:
        c = model.material.composition(p)[t]
    else:
        c = model.material.composition(p[t.ravel()], region=np.repeat(sub, 4))
        c = c.reshape(len(t), 4, -1)
    return (c.max(axis=1) - c.min(axis=1)).max(axis=1)


#: examples whose uniform size search takes a minute or more: in the slow step
#: (tests/test_tet_jumps.py meshes a solid of primitives' uniform baseline in the default
#: step). The graded sphere's search (it remeshes every size until it settles) is made once,
#: by test_a_sphere_of_primitives_gets_a_verified_uniform_mesh, which checks it as below too
SLOW = {"carved_plate"}
CHECKED_ELSEWHERE = {"graded_sphere"}


@pytest.mark.parametrize("path", [pytest.param(p, marks=pytest.mark.slow) if p.stem in SLOW
                                  else p for p in EXAMPLES_3D
                                  if p.stem not in CHECKED_ELSEWHERE], ids=lambda p: p.stem)
def test_every_3d_example_gets_a_verified_uniform_mesh(path):
    model = load_model(path)
    d0 = COARSE.get(model.name, 0.4)
    check_example_uniform(model, hetmesh.uniform(model, d0), d0)


def check_example_uniform(model, r, d0):
    """An example's uniform mesh at ``d0``: valid, delta below ``d0`` (evaluated again), the
    named faces kept, the volume up to the chords, one size."""
    primitives = isinstance(model.solid, (CSGSolid, CarvedSolid))
    m = r.mesh
    assert m.dim == 3 and m.cell_type == "tetra" and m.problems() == []
    delta = _delta_independent(model, m)
    assert delta.max() < d0 and r.stats.delta_max == pytest.approx(delta.max())
    # the named faces are kept
    names = set(m.marker_names.values())
    want = {n for i, n in enumerate(model.solid.face_names)
            if not (getattr(model.solid, "full", False) and n in ("start", "end"))
            and i - 2 not in getattr(model.solid, "axis_curves", ())}
    assert want <= names
    # volume up to the chords of curved faces: within (chord tolerance x surface area)
    f = np.sort(m.cells[:, [1, 2, 3, 0, 2, 3, 0, 1, 3, 0, 1, 2]].reshape(-1, 3), axis=1)
    u, cnt = np.unique(f, axis=0, return_counts=True)
    q = m.points[u[cnt == 1]]
    surface = 0.5 * np.linalg.norm(np.cross(q[:, 1] - q[:, 0], q[:, 2] - q[:, 0]), axis=1).sum()
    chord = 2e-3 * model.solid.diameter
    exact = model.solid.exact_volume if primitives else model.solid.volume
    if exact is not None:
        assert abs(m.measure - exact) <= chord * surface + 1e-9 * exact
    # one size: the longest edges are a small multiple of the size used
    h = r.options["size"]
    assert _edges(m.points, m.cells).max() <= 2.0 * h


@pytest.mark.slow  # 45 s: the size search remeshes every size until it settles
def test_a_sphere_of_primitives_gets_a_verified_uniform_mesh():
    """A solid of primitives (a hollow sphere): MMG's mesh at one size, checked from the
    arrays (volumes, delta, the two spheres within the chord tolerance); the fewest elements
    of the sizes tried that pass (here the chords on the curved faces set the mesh: the
    search stops when a larger size no longer coarsens it)."""
    model = _model("graded_sphere")
    r = hetmesh.uniform(model, 0.4)
    check_example_uniform(model, r, 0.4)
    m = r.mesh
    radii = [model.solid.base.radius] + [s.radius for s in model.solid.subtract]
    check_tet_mesh(m.points, m.cells, lambda x: model.material.composition(x)[:, 1], 0.4)
    d = np.linalg.norm(m.points - model.solid.base.center, axis=1)
    chord = 2e-3 * model.solid.diameter
    assert d.max() <= max(radii) + 1e-9 and d.min() >= min(radii) - chord
    # the fewest elements of the sizes tried that pass; every size that failed is larger
    hist = r.history
    passed = [h for h in hist if h["pass"]]
    assert len(m.cells) == min(h["elements"] for h in passed)
    assert all(h["h"] > r.options["size"] for h in hist if h["pass"] is False)


def test_the_search_ends_at_the_coarsest_passing_size():
    """Every size tried is recorded; the chosen one passes, and a size at most 25 % larger
    was tried and failed (the bracket the search narrows to 2 %)."""
    model = _model("graded_cylinder")
    r = hetmesh.uniform(model, 0.2)
    h = r.options["size"]
    tried = r.history
    assert any(t["pass"] and t["h"] == h for t in tried)
    fails = [t["h"] for t in tried if not t["pass"] and t["h"] > h]
    assert fails and min(fails) <= 1.25 * h
    # the failing size really fails, measured on its own mesh
    bad = uniform_tets_at(model, min(fails), 0.2)
    assert bad.delta.max() >= 0.2
    # and the swept search's delta is the 3D mesh's
    good = uniform_tets_at(model, h, 0.2)
    assert good.delta.max() == pytest.approx(r.stats.delta_max, rel=1e-12)
    assert len(good.tets) == r.stats.n_elements


def test_a_box_is_exact_and_its_delta_recomputed_independently():
    model = _model("unit_cube")
    res = uniform_model(model, 0.2)
    check_tet_mesh(res.points, res.tets, lambda p: (1 - p[:, 2]) ** 2, 0.2,
                   box_bounds=((0, 0, 0), (1, 1, 1)))
    assert res.info["placement"] == "uniform swept"
    # a uniform mesh is finer than the adaptive one where the material changes slowly
    a = hetmesh.generate(model, 0.2)
    assert len(res.tets) > a.stats.n_elements


def test_a_cylinder_primitive_keeps_its_curved_face_within_the_chord_tolerance():
    model = _model("graded_rod")
    res = uniform_model(model, 0.3)
    f = res.faces[np.asarray([res.face_names[k - 1] == "side" for k in res.face_markers])]
    p = res.points
    mids = 0.5 * (p[f] + p[f[:, [1, 2, 0]]])
    r = np.hypot(mids[..., 0], mids[..., 1])
    assert np.abs(r - 10).max() <= 2e-3 * model.solid.diameter * (1 + 1e-6)


def test_a_feature_tree_extrusion_keeps_its_subregions():
    model = _model("fgm_plate_3d")
    r = hetmesh.uniform(model, 0.4)
    sub = r.mesh.cell_data["subregion"]
    assert len(np.unique(sub)) > 1
    assert _delta_independent(model, r.mesh).max() < 0.4


def test_a_feature_tree_extrusion_records_its_discontinuities_as_faces():
    """As in the adaptive sweep: the material discontinuities the section mesher embedded
    follow the solid's faces as faces discontinuity[k], every triangle a face of two
    tetrahedra on either side of a jump (their subregions differ), none on the boundary."""
    model = _model("fgm_plate_3d")
    res = uniform_model(model, 0.4)
    k = len(model.solid.face_names)
    assert res.face_names[:k] == tuple(model.solid.face_names)
    assert res.face_names[k:] and all(n.startswith("discontinuity[") for n in
                                      res.face_names[k:])
    disc = res.face_markers > k
    assert disc.any() and not disc[:np.argmax(disc)].any()
    # every recorded triangle is shared by two tetrahedra of different subregions
    t = res.tets.astype(np.int64)
    tf = np.sort(t[:, [[1, 2, 3], [0, 2, 3], [0, 1, 3], [0, 1, 2]]].reshape(-1, 3), axis=1)
    owner = np.repeat(np.arange(len(res.tets)), 4)
    n = len(res.points)
    key = (tf[:, 0] * n + tf[:, 1]) * n + tf[:, 2]
    order = np.argsort(key, kind="stable")
    rf = np.sort(res.faces[disc].astype(np.int64), axis=1)
    rk = (rf[:, 0] * n + rf[:, 1]) * n + rf[:, 2]
    lo = np.searchsorted(key[order], rk, "left")
    hi = np.searchsorted(key[order], rk, "right")
    assert (hi - lo == 2).all()
    sub = res.info["regions"]
    assert (sub[owner[order[lo]]] != sub[owner[order[lo + 1]]]).all()


def test_a_revolution_is_swept_about_its_axis():
    model = _model("graded_ring")
    res = uniform_model(model, 0.3)
    assert res.info["placement"] == "uniform revolved" and res.info["angular_steps"] >= 3
    r = np.hypot(res.points[:, 0], res.points[:, 1])
    assert r.min() >= 20 * (1 - 1e-9) and r.max() <= 30 * (1 + 1e-9)


def test_same_input_same_mesh():
    model = _model("graded_cylinder")
    a, b = uniform_model(model, 0.25), uniform_model(model, 0.25)
    assert np.array_equal(a.points, b.points) and np.array_equal(a.tets, b.tets)


def test_the_budget_ends_the_search():
    model = _model("graded_cylinder")
    with pytest.raises(BudgetError, match="within the budget"):
        hetmesh.uniform(model, 0.01, max_elements=10_000)


def test_options_of_the_2d_kernel_are_refused():
    model = _model("unit_cube")
    with pytest.raises(OptionError, match="max_size"):
        hetmesh.uniform(model, 0.2, max_size=0.1)
    with pytest.raises(OptionError, match="threshold"):
        hetmesh.uniform(model, 1.5)
    with pytest.raises(TypeError):
        hetmesh.uniform(model, 0.2, colour="red")


def test_cli_uniform_on_a_solid(tmp_path, capsys):
    out = tmp_path / "u.vtu"
    code = main(["uniform", str(hetmesh.example_path("graded_cylinder")), "-d", "0.3",
                 "-o", str(out), "--stats", str(tmp_path / "u.json")])
    o, err = capsys.readouterr()
    assert code == 0 and "tetrahedra" in o and err == ""
    m = meshio.read(out)
    assert m.cells[0].type == "tetra"
    assert (tmp_path / "u.json").exists()
    # the budget: one line, exit 2, nothing written
    out2 = tmp_path / "v.vtu"
    code = main(["uniform", str(hetmesh.example_path("graded_cylinder")), "-d", "0.01",
                 "-o", str(out2), "--max-elements", "10000"])
    o, err = capsys.readouterr()
    assert code == 2 and len(err.strip().splitlines()) == 1 and "budget" in err
    assert not out2.exists()


def test_the_estimate_is_close_to_the_count():
    """The a-priori count the budget is checked with is within a factor 2 of the mesh's."""
    from hetmesh.tet.uniform import estimate_uniform

    model = _model("graded_cylinder")
    for h in (0.5, 1.0):
        res = uniform_tets_at(model, h, 0.5)
        ratio = estimate_uniform(model.solid, h) / len(res.tets)
        assert 0.5 < ratio < 2.0, (h, ratio)
    assert math.isfinite(ratio)
