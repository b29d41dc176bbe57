"""The vertex-removal pass (hetmesh.tri.coarsen): fewer elements, every claim kept, the mean
quality not lowered; checked here with this file's own computations."""

from __future__ import annotations

import copy
import tempfile

import numpy as np
import pytest

import hetmesh
from hetmesh.delta import element_delta
from hetmesh.material import element_subregions, has_subregions
from hetmesh.testing import robust_suite
from hetmesh.tri import pipeline as adapt
from hetmesh.tri.coarsen import collapse, star_table
from hetmesh.tri.discontinuity import embed_discontinuities
from hetmesh.tri.workset import FREE, WorkSet


def _repaired(model, threshold, method="layers", **prepare):
    """The work set, context, triangles, compositions and delta that generate() hands on
    after the repair loop."""
    model = embed_discontinuities(model)
    ctx, _ = adapt.prepare(model, threshold, None, **prepare)
    if ctx.scalar is None:
        method = "cvt"
    ws = adapt.PLACEMENTS[method](ctx, np.random.default_rng(0), 1e-3 * ctx.domain.diameter)
    tris, comp, delta = adapt.repair(ws, ctx, min_angle_deg=30.0, min_quality=0.6,
                                     sampling="vertices", max_elements=10**6, history=[])
    return ws, ctx, tris, comp, delta


def _bumps():
    """A random model of the robustness set with two Gaussian bumps (with ungraded sizes its
    repair inserts many nodes where the size changes fast, which the collapse removes)."""
    rm = robust_suite(48)[25]
    with tempfile.NamedTemporaryFile("w", suffix=".toml", delete=False) as f:
        f.write(rm.toml)
    return hetmesh.load_model(f.name)


@pytest.fixture(scope="module")
def bumps():
    return _repaired(_bumps(), 0.098, method="cvt", gradation=0.0)


@pytest.fixture(scope="module")
def ring():
    return _repaired(hetmesh.load_model(hetmesh.example_path("hft_ring")), 0.1)


def _quality(P, t):
    a = np.linalg.norm(P[t[:, 1]] - P[t[:, 2]], axis=1)
    b = np.linalg.norm(P[t[:, 2]] - P[t[:, 0]], axis=1)
    c = np.linalg.norm(P[t[:, 0]] - P[t[:, 1]], axis=1)
    return (b + c - a) * (c + a - b) * (a + b - c) / (a * b * c)


def _check(ws0: WorkSet, ws: WorkSet, ctx, tris0, tris, comp, delta):
    """Every claim, recomputed: valid and conforming, the same region, constraint nodes and
    edges kept, delta below the threshold and as returned, mean quality not lower."""
    P = ws.P
    assert np.unique(tris).tolist() == list(range(ws.n))  # no unused node
    X = P[tris]
    area2 = (X[:, 1, 0] - X[:, 0, 0]) * (X[:, 2, 1] - X[:, 0, 1]) - \
        (X[:, 1, 1] - X[:, 0, 1]) * (X[:, 2, 0] - X[:, 0, 0])
    assert (area2 > 0).all()
    X0 = ws0.P[tris0]
    a0 = (X0[:, 1, 0] - X0[:, 0, 0]) * (X0[:, 2, 1] - X0[:, 0, 1]) - \
        (X0[:, 1, 1] - X0[:, 0, 1]) * (X0[:, 2, 0] - X0[:, 0, 0])
    assert np.isclose(area2.sum(), a0.sum(), rtol=1e-12)  # the same region, no overlap
    e = np.sort(np.concatenate([tris[:, [0, 1]], tris[:, [1, 2]], tris[:, [2, 0]]]), axis=1)
    _, cnt = np.unique(e, axis=0, return_counts=True)
    assert cnt.max() <= 2  # manifold: no edge in three triangles
    # the constraint nodes and edges are those of the input
    kept = ws0.vcurve != FREE
    assert (ws.vcurve != FREE).sum() == kept.sum()
    np.testing.assert_array_equal(ws.P[ws.vcurve != FREE], ws0.P[kept])
    np.testing.assert_array_equal(ws.P[ws.E], ws0.P[ws0.E])
    reg = element_subregions(ctx.field, P, tris) if has_subregions(ctx.field) else None
    d = element_delta(ctx.field, P, tris, "vertices", regions=reg)
    np.testing.assert_array_equal(comp, ctx.field.composition(P))
    np.testing.assert_allclose(delta, d, rtol=0, atol=1e-15)
    assert d.max() < ctx.threshold
    q0, q1 = _quality(ws0.P, tris0), _quality(P, tris)
    assert q1.mean() >= q0.mean() - 1e-12


@pytest.mark.parametrize("case", ["bumps", "ring"])
def test_collapse_removes_nodes_and_keeps_every_claim(case, request):
    ws0, ctx, tris0, comp0, delta0 = request.getfixturevalue(case)
    ws = copy.deepcopy(ws0)
    tris, comp, delta = collapse(ws, ctx, tris0, comp0, delta0)
    _check(ws0, ws, ctx, tris0, tris, comp, delta)
    removed = ws0.n - ws.n
    assert len(tris0) - len(tris) == 2 * removed  # interior nodes: two triangles each
    if case == "bumps":
        assert removed >= 5


def test_a_regular_lattice_is_left_alone():
    """Equilateral triangles everywhere: no node is a candidate, nothing changes."""
    from scipy.spatial import Delaunay

    n = 8
    i, j = np.meshgrid(np.arange(n + 1), np.arange(n + 1))
    P = np.column_stack([(i + 0.5 * (j % 2)).ravel(), (j * np.sqrt(3) / 2).ravel()]) / n / 20
    t = Delaunay(P).simplices
    X = P[t]
    neg = ((X[:, 1, 0] - X[:, 0, 0]) * (X[:, 2, 1] - X[:, 0, 1])
           - (X[:, 1, 1] - X[:, 0, 1]) * (X[:, 2, 0] - X[:, 0, 0])) < 0
    t[neg] = t[neg][:, [0, 2, 1]]
    q = _quality(P, t)
    interior = np.flatnonzero((i > 0) & (i < n - 1) & (j > 0) & (j < n))
    table, cnt = star_table(t, interior)
    assert (cnt == 6).all() and q[table].min() > 0.999
    _, ctx, _, _, _ = _repaired(hetmesh.load_model(hetmesh.example_path("unit_square")), 0.1)
    ws = WorkSet(P=P, vcurve=np.where(np.isin(np.arange(len(P)), interior), FREE, -1),
                 vt=np.full(len(P), np.nan), pinned=np.zeros(len(P), bool),
                 level=np.full(len(P), np.nan), E=np.zeros((0, 2), np.int64),
                 ecurve=np.zeros(0, np.int64))
    comp = ctx.field.composition(P)
    delta = element_delta(ctx.field, P, t, "vertices")
    t2, _, _ = collapse(ws, ctx, t, comp, delta)
    assert t2 is t and ws.n == len(P)


def test_an_extra_node_is_removed():
    """A node put next to another in a flat field makes poor triangles: it goes. The centre
    node stays: removing it too would leave the mean quality where it is (four right
    triangles become two), a tie, which is refused."""
    ws0, ctx, _, _, _ = _repaired(hetmesh.load_model(hetmesh.example_path("unit_square")), 0.1)
    P = np.array([[0, 0], [1, 0], [1, 1], [0, 1], [0.5, 0.5], [0.55, 0.52]], float) * 0.05
    t = np.array([[0, 1, 4], [1, 2, 5], [2, 3, 4], [3, 0, 4], [1, 5, 4], [2, 4, 5]])
    ws = WorkSet(P=P, vcurve=np.array([-1, -1, -1, -1, FREE, FREE]),
                 vt=np.full(6, np.nan), pinned=np.zeros(6, bool), level=np.full(6, np.nan),
                 E=np.array([[0, 1], [1, 2], [2, 3], [3, 0]]), ecurve=np.zeros(4, np.int64))
    ws_in = copy.deepcopy(ws)
    comp = ctx.field.composition(P)
    delta = element_delta(ctx.field, P, t, "vertices")
    t2, c2, d2 = collapse(ws, ctx, t, comp, delta)
    assert ws.n == 5 and len(t2) == 4
    np.testing.assert_array_equal(ws.P[4], P[4])
    _check(ws_in, ws, ctx, t, t2, c2, d2)


def test_collapse_is_deterministic(bumps):
    ws0, ctx, tris0, comp0, delta0 = bumps
    out = []
    for _ in range(2):
        ws = copy.deepcopy(ws0)
        tris, _, _ = collapse(ws, ctx, tris0, comp0, delta0)
        out.append((ws.P.tobytes(), tris.tobytes()))
    assert out[0] == out[1]
