"""The springs placement: the truss's forces, the relaxation, and its meshes."""

from __future__ import annotations

import tomllib

import numpy as np
import pytest

import hetmesh
from conftest import check_invariants
from hetmesh.errors import OptionError
from hetmesh.metrics import quality
from hetmesh.testing import independent_check, random_model
from hetmesh.tri.geometry import build_pslg
from hetmesh.tri.pipeline import candidates, prepare
from hetmesh.tri.placement import place_springs, sample_interior, size_fn, start_size
from hetmesh.tri.springs import relax, spring_forces
from hetmesh.tri.workset import FREE, add_free_points, triangulate, workset_from_pslg


def test_a_short_bar_pushes_its_ends_apart():
    P = np.array([[0.0, 0.0], [0.5, 0.0], [3.0, 0.0]])
    bars = np.array([[0, 1], [1, 2]])
    F = spring_forces(P, bars, np.ones(3), fscale=1.0)
    # rest lengths scaled so that sum L0^2 = sum L^2: L0 = sqrt((0.25 + 6.25) / 2) = 1.80
    L0 = np.sqrt(6.5 / 2)
    assert F[0] == pytest.approx([-(L0 - 0.5), 0.0])
    assert F[1] == pytest.approx([L0 - 0.5, 0.0])  # the long bar (2.5 > L0) does not pull
    assert F[2] == pytest.approx([0.0, 0.0])
    assert F.sum(axis=0) == pytest.approx([0.0, 0.0])  # action and reaction


def test_forces_follow_the_size_at_the_ends():
    # two bars of length 1 whose ends want sizes 1 and 2: the rest lengths, scaled to
    # sum L0^2 = sum L^2 = 2, are 0.63 and 1.26, so only the second bar pushes
    P = np.array([[0.0, 0.0], [1.0, 0.0], [10.0, 0.0], [11.0, 0.0]])
    bars = np.array([[0, 1], [2, 3]])
    F = spring_forces(P, bars, np.array([1.0, 1.0, 2.0, 2.0]), fscale=1.0)
    assert F[:2] == pytest.approx(np.zeros((2, 2)))
    assert F[3, 0] == pytest.approx(2.0 * np.sqrt(2.0 / 5.0) - 1.0)


def _start(name, threshold):
    model = hetmesh.load_model(hetmesh.example_path(name))
    ctx, _ = prepare(model, threshold, None)
    h = size_fn(ctx, 1.0 / np.sqrt(1.3))
    ws = workset_from_pslg(build_pslg(ctx.domain, h, ctx.chord_tol))
    add_free_points(ws, sample_interior(ctx, h, np.random.default_rng(0)))
    return ws, ctx, h


FLAT_RECTANGLE = """
[model]
name = "flat"
[domain.outer]
start = [0, 0]
path = [{ to = [3, 0] }, { to = [3, 2] }, { to = [0, 2] }, { to = [0, 0] }]
[material]
constituents = ["ceramic", "metal"]
[material.composition]
metal = "0.3 + 0.01*x"
"""


def test_the_start_size_is_the_largest_size_where_the_material_is_flat():
    # random-0002-power: f = lo + (hi - lo) max((y0 - y) / L, 0)^5, flat in the upper part
    ctx, _ = prepare(random_model(2).load(), 0.15, None)
    x0, y0, x1, y1 = ctx.domain.bounds
    xs = np.linspace(x0, x1, 41)
    upper = ctx.domain.contains(np.column_stack([xs, np.full(41, y1 - 0.1 * (y1 - y0))]))
    top = np.column_stack([xs, np.full(41, y1 - 0.1 * (y1 - y0))])[upper]
    h13 = start_size(ctx, 1.3)
    np.testing.assert_allclose(h13(top), ctx.h_max, rtol=1e-9)
    np.testing.assert_allclose(size_fn(ctx, 1.0 / np.sqrt(1.3))(top), ctx.h_max / np.sqrt(1.3))
    # where the material sets a size far below h_max, 1.3 x its node count
    steep = np.array([[x, y] for x in np.linspace(x0, x1, 80) for y in np.linspace(y0, y1, 80)])
    steep = steep[ctx.domain.contains(steep)]
    hm = np.minimum(ctx.threshold / ctx.g(steep), ctx.h_max)
    fine = hm < 0.3 * ctx.h_max  # 1 / sqrt(1.3 - 0.3 (h_m / h_max)^2): within 1.1 %
    assert fine.sum() > 10
    np.testing.assert_allclose(h13(steep[fine]), hm[fine] / np.sqrt(1.3), rtol=0.012)
    # everywhere between the two: h_m / sqrt(1.3) <= h <= h_m (both capped by h_at)
    h, cap = h13(steep), ctx.h_at(steep)
    assert (h <= np.minimum(hm, cap) * (1 + 1e-12)).all()
    assert (h >= np.minimum(hm / np.sqrt(1.3), cap) * (1 - 1e-12)).all()


def test_springs_meshes_a_flat_field_as_a_geometric_mesher_would():
    # 3 x 2 rectangle, near-constant composition: every size is h_max (diameter / 8); 68
    # equilateral triangles of side h_max tile it. With h_max scaled by 1 / sqrt(1.3) the
    # springs start had 94 elements of mean edge 0.86 h_max
    model = hetmesh.io.model.parse_model(tomllib.loads(FLAT_RECTANGLE))
    r = hetmesh.generate(model, 0.1, method="springs")
    assert independent_check(r, r.model, 0.1) == []
    P, e = r.mesh.points, r.mesh.unique_edges[0]
    mean_edge = np.linalg.norm(P[e[:, 0]] - P[e[:, 1]], axis=1).mean()
    h_max = r.options["max_size"]
    tiling = 6.0 / (np.sqrt(3.0) / 4.0 * h_max ** 2)
    assert mean_edge > 0.95 * h_max
    assert r.stats.n_elements < 1.15 * tiling
    assert r.stats.q_avg > 0.95


def test_springs_aims_below_an_explicit_max_size():
    # aimed at the bound itself, the relaxed edges above it were split: 329 elements of
    # q_avg 0.940 on this rectangle with max_size 0.3 (the springs-dense start: 239 of 0.966)
    model = hetmesh.io.model.parse_model(tomllib.loads(FLAT_RECTANGLE))
    r = hetmesh.generate(model, 0.1, method="springs", max_size=0.3)
    assert independent_check(r, r.model, 0.1) == []
    P, e = r.mesh.points, r.mesh.unique_edges[0]
    assert np.linalg.norm(P[e[:, 0]] - P[e[:, 1]], axis=1).max() <= 0.3
    assert r.stats.n_elements < 260
    assert r.stats.q_avg > 0.97


def test_relaxation_raises_the_shape_and_keeps_the_curves():
    ws, ctx, h = _start("fgm_plate", 0.1)
    before = quality(ws.P, triangulate(ws, ctx)).mean()
    curve_nodes = ws.P[ws.vcurve != FREE].copy()
    tris = relax(ws, ctx, h)
    after = quality(ws.P, tris).mean()
    assert before < 0.8 < 0.95 < after  # random start -> nearly equilateral (0.73 -> 0.96)
    np.testing.assert_array_equal(ws.P[ws.vcurve != FREE], curve_nodes)
    used = np.zeros(ws.n, bool)
    used[tris.ravel()] = True
    assert used.all()
    assert ctx.inside(ws.P[ws.vcurve == FREE]).all()


@pytest.mark.parametrize("name, threshold", [("fgm_plate", 0.1), ("bracket", 0.05),
                                             ("three_phase", 0.1)])
def test_springs_meshes_meet_every_claim(name, threshold):
    model = hetmesh.load_model(hetmesh.example_path(name))
    r = hetmesh.generate(model, threshold, method="springs")
    check_invariants(r, model, threshold)
    assert independent_check(r, r.model, threshold) == []
    assert r.options["method"] == "springs"


def test_springs_has_a_better_shape_than_the_cvt_start():
    # a plate with a hole, graded across: where the element count allows, the springs
    # start's elements are nearly equilateral
    model = hetmesh.load_model(hetmesh.example_path("fgm_plate"))
    s = hetmesh.generate(model, 0.1, method="springs").stats
    c = hetmesh.generate(model, 0.1, method="cvt").stats  # measured: 2,364 @ 0.971 against
    assert s.q_avg > c.q_avg + 0.01                        # 2,417 @ 0.940
    assert s.n_elements < 1.2 * c.n_elements


def test_springs_is_deterministic():
    model = hetmesh.load_model(hetmesh.example_path("bracket"))
    a = hetmesh.generate(model, 0.1, method="springs", seed=4)
    b = hetmesh.generate(model, 0.1, method="springs", seed=4)
    np.testing.assert_array_equal(a.mesh.points, b.mesh.points)
    np.testing.assert_array_equal(a.mesh.triangles, b.mesh.triangles)


def test_auto_compares_layers_and_springs_on_small_models():
    model = hetmesh.load_model(hetmesh.example_path("power_plate"))  # two constituents
    ctx, _ = prepare(model, 0.05, None)
    assert candidates("auto", ctx, 1_000) == ["layers", "springs", "springs-dense"]
    assert candidates("auto", ctx, 10_000_000) == ["layers"]
    three = hetmesh.load_model(hetmesh.example_path("bracket"))  # three: always both
    assert candidates("auto", prepare(three, 0.05, None)[0], 10_000_000)[1:] == \
        ["springs", "springs-dense"]
    r = hetmesh.generate(model, 0.1)
    assert set(r.options["placements"]) == {"layers", "springs", "springs-dense"}
    kept = r.options["placements"][r.options["method"]]
    assert kept["elements"] == r.stats.n_elements


def test_starts_name_the_placements_auto_compares():
    model = hetmesh.load_model(hetmesh.example_path("power_plate"))
    r = hetmesh.generate(model, 0.1, starts=("layers", "cvt"))
    assert set(r.options["placements"]) == {"layers", "cvt"}
    with pytest.raises(OptionError, match="starts must name placements"):
        hetmesh.generate(model, 0.1, starts=("layers", "frontal"))
    with pytest.raises(OptionError, match="starts must name placements"):
        hetmesh.generate(model, 0.1, starts=())
    with pytest.raises(OptionError, match="starts is for method 'auto'"):
        hetmesh.generate(model, 0.1, method="layers", starts=("layers",))


def _boundary_and_beside(P, tris):
    """Lengths of the boundary edges and of the other edges with an end on the boundary."""
    e = np.sort(tris[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
    u, inv, cnt = np.unique(e, axis=0, return_inverse=True, return_counts=True)
    L = np.hypot(*(P[u[:, 0]] - P[u[:, 1]]).T)
    on = np.zeros(len(P), bool)
    on[u[cnt == 1].ravel()] = True
    beside = (cnt == 2) & (on[u[:, 0]] | on[u[:, 1]])
    return L[cnt == 1], L[beside], (cnt[inv.ravel()] == 1).reshape(-1, 3).any(axis=1)


def test_the_curves_are_spaced_like_the_relaxed_truss_beside_them():
    # random-0044-power at 0.19: sampled at the interior size with the count rounded up, the
    # boundary edges were 0.81 x the relaxed bars beside them; at 1.1 x that size 0.89 x
    # while the start scaled h_max too, 0.857 x since it keeps h_max where nothing varies
    # (:func:`start_size`; the meshed boundary triangles: the next test)
    ctx, _ = prepare(random_model(44).load(), 0.19, None)
    ws = place_springs(ctx, np.random.default_rng(0), ctx.chord_tol)
    lb, ln, _ = _boundary_and_beside(ws.P, triangulate(ws, ctx))
    assert lb.mean() > 0.845 * ln.mean()


def test_boundary_triangles_are_not_tall():
    # the same model meshed: its boundary triangles had a mean quality of 0.909 (0.960
    # inside; Gmsh's 0.974) and the mesh 0.945 against Gmsh's 0.957 (now 0.935 and 0.962)
    r = hetmesh.generate(random_model(44).load(), 0.19)
    _, _, at = _boundary_and_beside(r.mesh.points, r.mesh.triangles)
    q = quality(r.mesh.points, r.mesh.triangles)
    assert q[at].mean() > 0.93
    assert r.stats.q_avg > 0.957 - 0.01
