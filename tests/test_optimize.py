"""The post-refinement optimisation pass (hetmesh.tri.optimize): it raises the quality and keeps
every claim of the repaired mesh."""

from __future__ import annotations

import copy

import numpy as np
import pytest

import hetmesh
from conftest import check_invariants
from hetmesh.delta import element_delta
from hetmesh.material import element_subregions, has_subregions
from hetmesh.metrics import quality, signed_area2
from hetmesh.tri import pipeline as adapt
from hetmesh.tri.discontinuity import embed_discontinuities
from hetmesh.tri.optimize import KEEP, DeltaEvaluator, independent_sets, optimize, sweep
from hetmesh.tri.workset import FIXED


def _repaired(name, threshold, sampling="vertices", method="layers"):
    """The work set, context and triangles that generate() hands to the pass."""
    model = embed_discontinuities(hetmesh.load_model(hetmesh.example_path(name)))
    ctx, _ = adapt.prepare(model, threshold, None)
    if ctx.scalar is None:
        method = "cvt"
    ws = adapt.PLACEMENTS[method](ctx, np.random.default_rng(0), 1e-3 * ctx.domain.diameter)
    tris, _, _ = adapt.repair(ws, ctx, min_angle_deg=30.0, min_quality=0.6, sampling=sampling,
                              max_elements=10**6, history=[])
    return ws, ctx, tris


def _delta(ctx, P, tris, sampling):
    reg = element_subregions(ctx.field, P, tris) if has_subregions(ctx.field) else None
    return element_delta(ctx.field, P, tris, sampling, regions=reg)


@pytest.fixture(scope="module")
def plate():
    return _repaired("power_plate", 0.1)


@pytest.fixture(scope="module")
def ring():
    return _repaired("hft_ring", 0.1)


@pytest.mark.parametrize("case", ["plate", "ring"])
def test_pass_keeps_delta_and_raises_quality(case, request):
    ws0, ctx, tris0 = request.getfixturevalue(case)
    ws = copy.deepcopy(ws0)
    tris, comp, delta = optimize(ws, ctx, tris0)
    assert tris.shape == tris0.shape and ws.n == ws0.n  # same nodes and elements
    assert delta.max() < ctx.threshold
    np.testing.assert_array_equal(delta, _delta(ctx, ws.P, tris, "vertices"))
    np.testing.assert_array_equal(comp, ctx.field.composition(ws.P))
    q0, q1 = quality(ws0.P, tris0), quality(ws.P, tris)
    assert q1.min() >= q0.min()
    assert q1.mean() > q0.mean() + 0.005
    assert (signed_area2(*(ws.P[tris[:, k]] for k in range(3))) > 0).all()


def test_curve_nodes_stay_on_their_curves_and_fixed_nodes_stay(ring):
    ws0, ctx, tris0 = ring
    ws = copy.deepcopy(ws0)
    optimize(ws, ctx, tris0)
    on = np.flatnonzero(ws.vcurve >= 0)
    assert np.any(ws.vt[on] != ws0.vt[on])  # curve nodes did slide
    for c in np.unique(ws.vcurve[on]):
        s = on[ws.vcurve[on] == c]
        off = np.hypot(*(ctx.curves[c].point(ws.vt[s]) - ws.P[s]).T).max()
        assert off <= 1e-9 * ctx.domain.diameter
    held = ws0.pinned | (ws0.vcurve == FIXED)
    np.testing.assert_array_equal(ws.P[held], ws0.P[held])
    np.testing.assert_array_equal(ws.E, ws0.E)


def _one_set_sweep(case, request, keep=None):
    """One smoothing sweep of the first independent set of the fixture ``case``'s mesh
    (``keep``: the mean rule's bound): ``(ws before, ws after, ctx, tris, active, moved)``."""
    ws0, ctx, tris = request.getfixturevalue(case)
    ws = copy.deepcopy(ws0)
    ev = DeltaEvaluator(ctx, "vertices")
    comp, _, reg = ev.full(ws.P, tris)
    e = np.concatenate([tris[:, [0, 1]], tris[:, [1, 2]], tris[:, [2, 0]]])
    movable = ~ws.pinned & (ws.vcurve != FIXED)
    one = independent_sets(ws.n, e, movable)[0]
    active = np.zeros(ws.n, bool)
    active[one] = True
    moved = sweep(ws, ctx, tris, comp, reg, ev, active, min_angle_deg=30.0,
                  steps=(1.0, 0.5, 0.25), grad_steps=(0.1, 0.03), salt=0, keep=keep)
    return ws0, ws, ctx, tris, active, moved


@pytest.mark.parametrize("case", ["plate", "ring"])
def test_one_independent_set_never_lowers_a_star_minimum(case, request):
    """Within one independent set every node's star changes by its own move only: each
    moved node's star minimum quality (and every star element's delta) is checked."""
    ws0, ws, ctx, tris, active, moved = _one_set_sweep(case, request)
    assert moved.sum() > 0 and not (moved & ~active).any()
    q0, q1 = quality(ws0.P, tris), quality(ws.P, tris)
    star0 = np.ones(ws.n)
    star1 = np.ones(ws.n)
    np.minimum.at(star0, tris.ravel(), np.repeat(q0, 3))
    np.minimum.at(star1, tris.ravel(), np.repeat(q1, 3))
    assert (star1[moved] >= star0[moved]).all()
    assert (q1 > q0).sum() > 0
    assert _delta(ctx, ws.P, tris, "vertices").max() < ctx.threshold


@pytest.mark.parametrize("case", ["plate", "ring"])
def test_mean_rule_keeps_every_triangle_above_the_lower_of_its_quality_and_keep(case, request):
    """The mean-quality phase's rule on one independent set: a triangle may lose quality,
    but never below KEEP, and one below KEEP never loses any."""
    ws0, ws, ctx, tris, active, moved = _one_set_sweep(case, request, keep=KEEP)
    assert moved.sum() > 0 and not (moved & ~active).any()
    q0, q1 = quality(ws0.P, tris), quality(ws.P, tris)
    assert (q1 >= np.minimum(q0, KEEP) - 1e-12).all()
    assert q1.mean() > q0.mean()
    assert _delta(ctx, ws.P, tris, "vertices").max() < ctx.threshold


@pytest.mark.parametrize("case", ["plate", "ring"])
def test_mean_rule_pass_after_the_pass_raises_the_mean_and_keeps_the_minimum(case, request):
    """The pass with the mean rule on the pass's result (as generate() makes it): a larger
    mean quality, and a minimum no lower than the lower of the one before and KEEP."""
    ws0, ctx, tris0 = request.getfixturevalue(case)
    ws = copy.deepcopy(ws0)
    tris, comp, delta = optimize(ws, ctx, tris0)
    q1 = quality(ws.P, tris)
    tris, _, delta = optimize(ws, ctx, tris, comp, delta, keep=KEEP)
    q2 = quality(ws.P, tris)
    assert delta.max() < ctx.threshold
    np.testing.assert_array_equal(delta, _delta(ctx, ws.P, tris, "vertices"))
    assert q2.mean() > q1.mean()
    assert q2.min() >= min(q1.min(), KEEP)


def test_generate_polishes_the_kept_mesh():
    """generate() compares the placements as the first pass leaves them, then makes the
    mean-rule pass on the one it keeps: same elements, a mean quality at least as large."""
    model = hetmesh.load_model(hetmesh.example_path("power_plate"))
    r = hetmesh.generate(model, 0.1)
    check_invariants(r, model, 0.1)
    kept = r.options["placements"][r.options["method"]]
    assert r.history[-1]["stage"] == "optimize" and r.history[-1]["rule"] == "mean"
    assert "optimize_mean" in r.timings
    assert r.stats.n_elements == kept["elements"]
    assert r.stats.q_avg > kept["q_avg"]
    off = hetmesh.generate(model, 0.1, optimize=False)
    assert all(h.get("rule") != "mean" for h in off.history)


def test_independent_sets_cover_and_are_independent(plate):
    ws, _, tris = plate
    e = np.concatenate([tris[:, [0, 1]], tris[:, [1, 2]], tris[:, [2, 0]]])
    act = np.ones(ws.n, bool)
    act[::7] = False
    sets = independent_sets(ws.n, e, act)
    allv = np.concatenate(sets)
    assert len(allv) == len(np.unique(allv)) == act.sum()
    for s in sets:
        m = np.zeros(ws.n, bool)
        m[s] = True
        assert not (m[e[:, 0]] & m[e[:, 1]]).any()


def test_pass_is_deterministic(ring):
    ws0, ctx, tris0 = ring
    out = []
    for _ in range(2):
        ws = copy.deepcopy(ws0)
        tris, _, _ = optimize(ws, ctx, tris0)
        out.append((ws.P.copy(), ws.vt.copy(), tris))
    for a, b in zip(*out):
        np.testing.assert_array_equal(a, b)


def test_dense_sampling_is_respected():
    ws, ctx, tris0 = _repaired("three_phase", 0.1, sampling="dense")
    tris, _, delta = optimize(ws, ctx, tris0, sampling="dense")
    assert delta.max() < ctx.threshold
    np.testing.assert_array_equal(delta, _delta(ctx, ws.P, tris, "dense"))


@pytest.mark.parametrize("name, threshold, kw", [
    ("power_plate", 0.05, {"method": "layers"}),
    ("power_plate", 0.1, {"method": "cvt"}),
    ("hft_ring", 0.1, {"method": "layers"}),
    ("plate_with_holes", 0.1, {"sampling": "dense", "method": "layers"}),
])
def test_invariants_with_and_without_the_pass(name, threshold, kw):
    model = hetmesh.load_model(hetmesh.example_path(name))
    on = hetmesh.generate(model, threshold, **kw)
    off = hetmesh.generate(model, threshold, optimize=False, **kw)
    check_invariants(on, model, threshold)
    # the pass moves nodes and flips edges, and removes interior nodes (hetmesh.tri.coarsen):
    # two triangles fewer for each
    assert on.stats.n_points <= off.stats.n_points
    assert off.stats.n_elements - on.stats.n_elements == 2 * (off.stats.n_points
                                                             - on.stats.n_points)
    assert on.stats.q_avg > off.stats.q_avg
    assert on.stats.q_min >= off.stats.q_min
    assert on.options["optimize"] and not off.options["optimize"]
