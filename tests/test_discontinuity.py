"""Material discontinuities (hetmesh.tri.discontinuity): traced, fitted and embedded curves against
their closed forms, and the meshes that embed them."""

from __future__ import annotations

import numpy as np
import pytest

import hetmesh
from conftest import check_invariants, square_domain
from hetmesh.errors import MaterialError
from hetmesh.io.model import Model
from hetmesh.material import has_subregions
from hetmesh.material.hft import (
    BlendFeature,
    CurveFeature,
    HFTField,
    NearestFeature,
    PointFeature,
    SelectFeature,
    inside_predicate,
)
from hetmesh.tri.discontinuity import (
    crossing_elements,
    embed_discontinuities,
    embedded_count,
    fit_curves,
    trace_discontinuities,
)
from hetmesh.tri.geometry import Arc, CurveBatch, Segment

EX = hetmesh.example_path


@pytest.fixture(scope="module")
def plate():
    return hetmesh.load_model(EX("fgm_plate"))


@pytest.fixture(scope="module")
def plate_embedded(plate):
    return embed_discontinuities(plate)


def _samples(path, n=200):
    return np.vstack([c.point(np.linspace(0, 1, n)) for c in path.curves])


def _parabola_residual(pts, x_apex, x_end):
    """|y - ((x_apex - x)^2 - 64)/16|: the medial curve between a groove of radius 8 centred
    at (x_apex, 0) and the bottom line (docs/cases.md, section 5)."""
    return np.abs(pts[:, 1] - ((x_apex - pts[:, 0]) ** 2 - 64.0) / 16.0)


def test_plate_discontinuities_match_closed_forms(plate_embedded):
    paths = [p for p in plate_embedded.domain.interfaces if p.name.startswith("discontinuity")]
    assert embedded_count(plate_embedded.domain) == len(paths) == 5
    tol = 2e-5 * plate_embedded.domain.diameter
    ends = set()
    for p in paths:
        pts = _samples(p)
        ends |= {tuple(np.round(p.curves[0].start, 9)), tuple(np.round(p.curves[-1].end, 9))}
        if np.ptp(pts[:, 0]) < 1e-9:  # the vertical line between the two arcs
            assert np.allclose(pts[:, 0], 30.0, atol=1e-9)
            assert pts[:, 1].min() == pytest.approx(10.0625, abs=1e-9)
            continue
        x = pts[:, 0]
        if x.max() <= 7 + 1e-9:
            res = _parabola_residual(pts, 15, 0)       # B .. MA
        elif x.min() >= 53 - 1e-9:
            res = _parabola_residual(pts, 45, 60)      # G .. HN
        elif x.max() <= 30 + 1e-9:
            res = _parabola_residual(pts, 15, 30)      # D .. junction
        else:
            res = _parabola_residual(pts, 45, 30)      # E .. junction
        assert res.max() < tol
    expected = {(0.0, 10.0625), (7.0, 0.0), (23.0, 0.0), (37.0, 0.0), (53.0, 0.0),
                (60.0, 10.0625), (30.0, 20.0), (30.0, 10.0625)}
    got = {(round(a, 7) + 0.0, round(b, 7) + 0.0) for a, b in ends}
    assert got == expected


def test_plate_boundary_split_keeps_names(plate, plate_embedded):
    before = [c.name for c in plate.domain.outer.curves]
    after = [c.name for c in plate_embedded.domain.outer.curves]
    assert sorted(set(after)) == sorted(set(before))
    assert after.count("MA") == 2 and after.count("HN") == 2 and after.count("NM") == 2
    assert plate_embedded.domain.area == pytest.approx(plate.domain.area, rel=1e-12)
    assert embed_discontinuities(plate_embedded) is plate_embedded  # idempotent


def test_plate_mesh_embeds_every_discontinuity(plate):
    r = hetmesh.generate(plate, 0.1)
    check_invariants(r, plate, 0.1)
    mesh = r.mesh
    names = mesh.marker_names
    disc = [k for k, n in names.items() if n.startswith("discontinuity")]
    assert disc and np.isin(mesh.edge_markers, disc).sum() > 20
    # the subregions of the elements on both sides of a discontinuity edge differ
    sub = mesh.cell_data["subregion"]
    assert set(np.unique(sub)) == set(range(5))


def _voronoi_model():
    """Three points of different compositions, nearest wins: the discontinuities are the
    perpendicular bisectors, meeting at the circumcentre (0.5, 0.375)."""
    feats = [PointFeature("a", (0.0, 0.0), [1.0, 0.0]), PointFeature("b", (1.0, 0.0), [0.5, 0.5]),
             PointFeature("c", (0.5, 1.0), [0.0, 1.0])]
    fld = HFTField(NearestFeature("n", feats), ["ceramic", "metal"])
    return Model(name="voronoi", domain=square_domain(), material=fld)


def test_voronoi_junction_and_straight_bisectors():
    m = embed_discontinuities(_voronoi_model())
    paths = [p for p in m.domain.interfaces if p.name.startswith("discontinuity")]
    assert len(paths) == 3
    for p in paths:
        assert all(isinstance(c, Segment) for c in p.curves) and len(p.curves) == 1
    ends = np.array([[p.curves[0].start, p.curves[-1].end] for p in paths]).reshape(-1, 2)
    centre = np.array([0.5, 0.375])
    assert np.hypot(*(ends - centre).T).min() < 1e-9
    # the bisector of a-b is x = 0.5 below the centre; the other two end on the sides
    others = ends[np.hypot(*(ends - centre).T) > 1e-6]
    assert sorted(map(tuple, np.round(others, 9).tolist())) == \
        [(0.0, 0.625), (0.5, 0.0), (1.0, 0.625)]


def test_voronoi_mesh_invariants():
    model = _voronoi_model()
    r = hetmesh.generate(model, 0.2)
    check_invariants(r, model, 0.2)
    # a jump of 0.5 between constant regions: every element is homogeneous
    assert r.stats.delta_max == pytest.approx(0.0, abs=1e-12)


def _where_model(closed: bool):
    """Constant compositions on both sides of x = 0.3 (a 'where' rule) or of a circle."""
    a = PointFeature("a", (0.1, 0.5), [1.0, 0.0])
    b = PointFeature("b", (0.9, 0.5), [0.0, 1.0])
    if closed:
        circ = [Arc.circle((0.55, 0.45), 0.25)]
        pred = inside_predicate(circ, "disk")
    else:
        def pred(p):
            return p[:, 0] > 0.3
    fld = HFTField(SelectFeature("s", [a, b], [(1, pred), (0, None)]), ["ceramic", "metal"])
    return Model(name="where", domain=square_domain(), material=fld)


@pytest.mark.parametrize("closed", [False, True], ids=["line", "circle"])
def test_select_rule_boundary_is_embedded(closed):
    model = _where_model(closed)
    m = embed_discontinuities(model)
    paths = [p for p in m.domain.interfaces if p.name.startswith("discontinuity")]
    assert len(paths) == 1
    pts = _samples(paths[0])
    if closed:
        assert np.abs(np.hypot(pts[:, 0] - 0.55, pts[:, 1] - 0.45) - 0.25).max() < 2e-5
        assert paths[0].is_closed()
    else:
        assert np.abs(pts[:, 0] - 0.3).max() < 1e-9
        assert pts[:, 1].min() == pytest.approx(0.0, abs=1e-9)
        assert pts[:, 1].max() == pytest.approx(1.0, abs=1e-9)
    r = hetmesh.generate(model, 0.1)
    check_invariants(r, model, 0.1)
    assert r.stats.delta_max == pytest.approx(0.0, abs=1e-12)


def test_crossing_elements_finds_straddling_elements():
    """The check can fail: a structured mesh that ignores x = 0.3 has crossing elements,
    exactly those whose x-range contains 0.3."""
    model = _where_model(False)
    n = 7  # x = 0.3 is not a grid line
    g = np.linspace(0, 1, n + 1)
    X, Y = np.meshgrid(g, g)
    P = np.column_stack([X.ravel(), Y.ravel()])
    idx = np.arange((n + 1) ** 2).reshape(n + 1, n + 1)
    a, b = idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel()
    c, d = idx[1:, 1:].ravel(), idx[1:, :-1].ravel()
    T = np.vstack([np.column_stack([a, b, c]), np.column_stack([a, c, d])])
    curves = CurveBatch.from_curves([Segment((0.3, 0.0), (0.3, 1.0))])
    bad = crossing_elements(model.material, P, T, curves)
    xs = P[T][:, :, 0]
    straddle = (xs.min(axis=1) < 0.3 - 1e-12) & (xs.max(axis=1) > 0.3 + 1e-12)
    assert bad.sum() > 0
    np.testing.assert_array_equal(bad, straddle)
    assert has_subregions(model.material)


def test_fit_curves_tolerance_and_ends():
    t = np.linspace(0, 1, 400)
    pts = np.column_stack([t * 10, np.sin(t * 3)])           # a smooth, non-circular curve
    curves = fit_curves(pts, 1e-4)
    assert np.allclose(curves[0].start, pts[0]) and np.allclose(curves[-1].end, pts[-1])
    dist = CurveBatch.from_curves(curves).distance(pts)
    assert dist.max() <= 1e-4 + 1e-12
    assert 2 <= len(curves) < 60
    line = fit_curves(np.column_stack([t, 2 * t]), 1e-9)
    assert len(line) == 1 and isinstance(line[0], Segment)


def test_analytic_models_are_untouched():
    model = hetmesh.load_model(EX("power_plate"))
    assert not has_subregions(model.material)
    assert embed_discontinuities(model) is model


def test_ring_interface_is_not_duplicated():
    """hft_ring's subregion boundary is circle A, already an interface: nothing is added."""
    model = hetmesh.load_model(EX("hft_ring"))
    assert has_subregions(model.material)
    assert embed_discontinuities(model).domain.interfaces == model.domain.interfaces
    assert trace_discontinuities(model.material, model.domain.bounds)


# ------------------------------------------------------------------ seeded random trees
def _random_tree(seed: int) -> Model:
    """A plate [0, 2] x [0, 1]: a bottom curve of 2-4 segments (random split points, constant
    or linear compositions), a top edge, blended by a random weight; half the seeds add a
    'where' rule switching to another bottom curve right of a random x (more subregions)."""
    rng = np.random.default_rng(seed)

    def comp():
        c = rng.uniform(0, 1)
        return [c, 1 - c]

    def bottom(tag):
        k = int(rng.integers(2, 5))
        xs = np.r_[0.0, np.sort(rng.uniform(0.2, 1.8, k - 1)), 2.0]
        kids = []
        for i in range(k):
            seg = Segment((xs[i], 0.0), (xs[i + 1], 0.0))
            end = comp() if rng.random() < 0.5 else None
            kids.append(CurveFeature(f"{tag}{i}", seg, comp(), end))
        return NearestFeature(tag, kids)

    bot = bottom("b")
    if rng.random() < 0.5:
        cut = float(rng.uniform(0.5, 1.5))
        bot = SelectFeature("s", [bottom("c"), bot], [(0, lambda p, c=cut: p[:, 0] > c),
                                                      (1, None)])
    top = CurveFeature("top", Segment((2.0, 1.0), (0.0, 1.0)), comp())
    a = float(rng.uniform(1.0, 5.0))
    fld = HFTField(BlendFeature("r", bot, top, {"d_b": bot, "d_t": top},
                                [(f"exp(-{a:.3f}*d_b/(d_b + d_t))", None)]), ["ceramic", "metal"])
    return Model(name=f"random{seed}", domain=square_domain(w=2.0), material=fld)


def test_random_tree_fast():
    model = _random_tree(3)
    r = hetmesh.generate(model, 0.15)
    check_invariants(r, model, 0.15)


@pytest.mark.slow
@pytest.mark.parametrize("seed", range(10))
@pytest.mark.parametrize("sampling", ["vertices", "dense"])
def test_random_trees(seed, sampling):
    model = _random_tree(seed)
    r = hetmesh.generate(model, 0.1, sampling=sampling)
    check_invariants(r, model, 0.1)
    u = hetmesh.uniform(model, 0.15) if seed < 3 and sampling == "vertices" else None
    if u is not None:
        check_invariants(u, model, 0.15)


def test_select_without_default_outside_the_domain():
    """Rules that cover the domain but not its bounding box: tracing labels the unowned
    outside -1 and still finds the one real discontinuity (x = 0.3)."""
    a = PointFeature("a", (0.1, 0.5), [1.0, 0.0])
    b = PointFeature("b", (0.9, 0.5), [0.0, 1.0])
    rules = [(1, lambda p: (p[:, 0] > 0.3) & (p[:, 0] <= 1.0) & (p[:, 1] >= 0) & (p[:, 1] <= 1)),
             (0, lambda p: (p[:, 0] <= 0.3) & (p[:, 0] >= 0.0) & (p[:, 1] >= 0) & (p[:, 1] <= 1))]
    fld = HFTField(SelectFeature("s", [a, b], rules), ["ceramic", "metal"])
    model = Model(name="partial", domain=square_domain(), material=fld)
    with pytest.raises(MaterialError, match="unowned"):
        fld.region(np.array([[2.0, 2.0]]))
    m = embed_discontinuities(model)
    paths = [p for p in m.domain.interfaces if p.name.startswith("discontinuity")]
    assert len(paths) == 1
    assert np.abs(_samples(paths[0])[:, 0] - 0.3).max() < 1e-9


def test_same_input_same_mesh(plate):
    a = hetmesh.generate(plate, 0.15).mesh
    b = hetmesh.generate(plate, 0.15).mesh
    np.testing.assert_array_equal(a.points, b.points)
    np.testing.assert_array_equal(a.triangles, b.triangles)


def test_discontinuity_crossing_an_interface_is_cut_there():
    """x = 0.5 (nearest of two points) crosses the domain's interface circle twice: three
    pieces, the circle split at the two crossings, and a valid mesh."""
    from hetmesh.tri.geometry import Loop, Path, make_domain

    sq = [(0, 0), (1, 0), (1, 1), (0, 1)]
    outer = Loop(tuple(Segment(a, b) for a, b in zip(sq, sq[1:] + sq[:1])), "outer")
    ring = Path((Arc.circle((0.5, 0.5), 0.3),), "A")
    feats = [PointFeature("a", (0.2, 0.5), [1.0, 0.0]), PointFeature("b", (0.8, 0.5), [0.0, 1.0])]
    model = Model(name="cross", domain=make_domain(outer, interfaces=[ring]),
                  material=HFTField(NearestFeature("n", feats), ["ceramic", "metal"]))
    m = embed_discontinuities(model)
    paths = [p for p in m.domain.interfaces if p.name.startswith("discontinuity")]
    assert len(paths) == 3
    ends = {tuple(np.round(e, 9)) for p in paths for e in (p.curves[0].start, p.curves[-1].end)}
    assert ends == {(0.5, 0.0), (0.5, 0.2), (0.5, 0.8), (0.5, 1.0)}
    a = next(p for p in m.domain.interfaces if p.name == "A")
    assert len(a.curves) == 2
    r = hetmesh.generate(model, 0.2)
    check_invariants(r, model, 0.2)
