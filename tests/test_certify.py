"""Interval arithmetic on formulas and the certified element variation."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from hetmesh import generate
from hetmesh.certify import CertificationUnavailable, certified_delta
from hetmesh.expr import compile_expr
from hetmesh.material import AnalyticField, CallableField
from hetmesh.metrics import delta_dense

FORMULAS = [
    "x**2 - y", "exp(-((x - 0.3)**2 + (y - 0.5)**2)/0.0004)", "sin(5*x)*cos(3*y)",
    "atan2(y - 0.5, x - 0.5)", "sqrt(x)*log(1 + y)", "where(x < 0.5, x, 1 - y)", "tan(x)",
    "x**-2", "x**y", "abs(x - y)", "clip(3*x - 1, 0, 1)", "arccos(x) + arcsin(y)",
    "cosh(x - y) + sinh(x)", "tanh(4*x) + log10(y + 1)", "min(x, y)**3", "x**0.5",
    "sign(x - 0.3)", "1/(x - 0.5)", "max(x, 1 - y) if x*y > 0.2 else -y", "x**3 - 2*x*y",
    "exp(x)/(1 + exp(y))", "(x - y)**4 - x**5", "cos(40*x*y)",
]
coord = st.floats(-0.3, 1.3, allow_nan=False)


@pytest.mark.parametrize("text", FORMULAS)
@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(x0=coord, x1=coord, y0=coord, y1=coord, seed=st.integers(0, 2 ** 31))
def test_interval_encloses_sampled_values(text, x0, x1, y0, y1, seed):
    e = compile_expr(text)
    (x0, x1), (y0, y1) = sorted((x0 + 0.0, x1 + 0.0)), sorted((y0 + 0.0, y1 + 0.0))  # no -0.0
    lo, hi = e.interval(x=(x0, x1), y=(y0, y1))
    rng = np.random.default_rng(seed)
    x = np.r_[rng.uniform(x0, x1, 200), x0, x1, x0, x1]
    y = np.r_[rng.uniform(y0, y1, 200), y0, y1, y1, y0]
    v = e(x=x, y=y)
    v = v[np.isfinite(v)]
    assert lo <= hi or (np.isinf(lo) and np.isinf(hi))
    if len(v):
        assert lo <= v.min() and v.max() <= hi


def test_interval_is_tight_on_small_boxes_and_exact_on_points():
    e = compile_expr("exp(-((x - 0.3)**2 + (y - 0.5)**2)/0.0004)")
    lo, hi = e.interval(x=0.31, y=0.52)
    v = float(e(x=0.31, y=0.52))
    assert lo <= v <= hi and hi - lo < 1e-14
    lo, hi = e.interval(x=(0.29, 0.31), y=(0.49, 0.51))  # the peak inside: 1
    assert lo < 0.61 and 1.0 <= hi < 1.0 + 1e-12


def test_interval_conditions_are_three_valued():
    e = compile_expr("where(x < 0.5, 0.2, 0.8)")
    assert [float(v) for v in e.interval(x=(0.0, 0.4))] == [0.2, 0.2]
    assert [float(v) for v in e.interval(x=(0.6, 0.9))] == [0.8, 0.8]
    assert [float(v) for v in e.interval(x=(0.4, 0.6))] == [0.2, 0.8]
    lo, hi = compile_expr("1/x").interval(x=(-1.0, 1.0))
    assert lo == -math.inf and hi == math.inf
    with pytest.raises(TypeError, match="missing value for 'y'"):
        compile_expr("x + y").interval(x=(0.0, 1.0))


def _grid(n):
    xs = np.linspace(0.0, 1.0, n + 1)
    X, Y = np.meshgrid(xs, xs)
    P = np.c_[X.ravel(), Y.ravel()]
    idx = np.arange((n + 1) ** 2).reshape(n + 1, n + 1)
    a, b, c, d = (idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel(), idx[1:, 1:].ravel(),
                  idx[1:, :-1].ravel())
    return P, np.r_[np.c_[a, b, c], np.c_[a, c, d]]


@pytest.mark.parametrize("text", ["x*y", "exp(-((x - 0.31)**2 + (y - 0.52)**2)/4e-4)",
                                  "0.5 + 0.5*sin(9*x)*cos(7*y)", "where(x < 0.43, x/2, 0.9)"])
def test_certified_bound_is_above_the_fine_lattice_and_close_to_it(text):
    f = AnalyticField({"b": text}, ["a", "b"])
    P, T = _grid(12)
    bound = certified_delta(f, P, T)
    fine = delta_dense(f, P, T, order=60)
    assert (bound >= fine - 1e-12).all()
    # tight: within the settling tolerance (1 % + 1e-4) of the samples, plus lattice misses
    assert (bound <= fine * 1.02 + 2e-3).all()


def test_certified_sees_a_peak_between_every_sample():
    f = AnalyticField({"b": "exp(-((x - 0.3)**2 + (y - 0.3)**2)/1e-6)"}, ["a", "b"])
    P = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])
    T = np.array([[0, 1, 2]])
    assert delta_dense(f, P, T)[0] < 1e-6  # the 15-point lattice misses it
    assert 1.0 <= certified_delta(f, P, T)[0] < 1.02


def test_certified_bound_in_the_local_frame_of_a_far_away_model():
    from hetmesh.tri.frame import local_field, local_frame
    f = AnalyticField({"b": "exp(-((x - 1e6 - 0.3)**2 + (y - 0.3)**2)/1e-4)"}, ["a", "b"])
    frame = local_frame((1e6, 0.0, 1e6 + 1.0, 1.0))
    fl = local_field(f, frame)
    P = frame.to_local(np.array([[1e6, 0.0], [1e6 + 1.0, 0.0], [1e6, 1.0]]))
    assert 1.0 <= certified_delta(fl, P, np.array([[0, 1, 2]]))[0] < 1.02


def test_callable_fields_fall_back_to_dense_sampling_with_a_warning():
    f = CallableField(lambda x, y: x * y, ["a", "b"])
    P, T = _grid(4)
    with pytest.warns(CertificationUnavailable, match="no expression to enclose"):
        d = certified_delta(f, P, T)
    np.testing.assert_array_equal(d, delta_dense(f, P, T))


def _bump_model(tmp_path, a, b, w):
    from hetmesh.io.model import load_model
    from hetmesh.testing import bump_toml
    path = tmp_path / "bump.toml"
    path.write_text(bump_toml(a, b, w))
    return load_model(path)


def _true_delta(P, T, c, w):
    """The exact variation of a radial bump over every triangle: its value at the
    triangle's point nearest the centre minus its smallest corner value."""
    c = np.asarray(c, float)
    best, dist = None, None
    for i, j in ((0, 1), (1, 2), (2, 0)):
        p, q = P[T[:, i]], P[T[:, j]]
        e = q - p
        t = np.clip(((c - p) * e).sum(1) / (e * e).sum(1), 0.0, 1.0)
        x = p + t[:, None] * e
        dd = ((x - c) ** 2).sum(1)
        if best is None:
            best, dist = x, dd
        else:
            k = dd < dist
            best[k], dist[k] = x[k], dd[k]
    a, b, d = P[T[:, 0]], P[T[:, 1]], P[T[:, 2]]
    cr = lambda u, v: u[:, 0] * v[:, 1] - u[:, 1] * v[:, 0]  # noqa: E731
    s = np.stack([cr(b - a, c - a), cr(d - b, c - b), cr(a - d, c - d)], 1)
    best[(s >= 0).all(1) | (s <= 0).all(1)] = c
    f = lambda q: np.exp(-((q - c) ** 2).sum(-1) / w)  # noqa: E731
    return f(best) - f(P[T]).min(axis=1)


@pytest.mark.parametrize("centre,w", [((0.55, 0.91), 4e-4), ((0.2093, 0.6517), 1e-4),
                                      ((0.8, 0.13), 2.5e-5)])
def test_narrow_bump_meshes_with_no_element_above_threshold(tmp_path, centre, w):
    model = _bump_model(tmp_path, *centre, w)
    res = generate(model, 0.1, sampling="certified")
    P, T = res.mesh.points, res.mesh.triangles
    true = _true_delta(P, T, centre, w)
    assert true.max() < 0.1
    assert res.stats.delta_max < 0.1 and res.stats.delta_max >= true.max() - 1e-12
    assert res.stats.delta_max_certified == res.stats.delta_max


def test_piecewise_field_bounded_on_each_element_own_branch():
    from hetmesh.material import element_subregions

    f = AnalyticField({"b": "where(x < 0.43, 0.5*x + 0.1*sin(20*y), 0.9 - 0.2*y)"}, ["a", "b"])
    P, T = _grid(10)
    regions = element_subregions(f, P, T)
    bound = certified_delta(f, P, T, regions=regions)
    fine = delta_dense(f, P, T, order=40, regions=regions)
    assert (bound >= fine - 1e-12).all() and (bound <= fine * 1.02 + 2e-3).all()
    # without regions an element across the jump is bounded across it
    across = certified_delta(f, P, T)
    assert across.max() > 0.3 and (across >= delta_dense(f, P, T, order=40) - 1e-12).all()


def test_feature_tree_bound_is_above_a_fine_lattice():
    from importlib import resources

    from hetmesh.io.model import load_model
    from hetmesh.material import element_subregions

    with resources.as_file(resources.files("hetmesh") / "examples" / "hft_ring.toml") as p:
        model = load_model(p)
    res = generate(model, 0.2)
    f, P, T = model.material, res.mesh.points, res.mesh.triangles
    regions = element_subregions(f, P, T)
    bound = certified_delta(f, P, T, regions=regions, threshold=0.2)
    fine = delta_dense(f, P, T, order=24, regions=regions)
    assert (bound >= fine - 1e-9).all()
    # decided against delta_0 = 0.2: below it where the lattice is clearly below it
    assert (bound[fine < 0.15] < 0.2).all()


@pytest.mark.parametrize("sampling", ["vertices", "dense"])
def test_a_narrow_bump_near_the_boundary_meshes_with_every_sampling(tmp_path, sampling):
    res = generate(_bump_model(tmp_path, 0.55, 0.91, 4e-4), 0.1, sampling=sampling)
    assert res.stats.delta_max < 0.1 and res.mesh.is_valid()


# --------------------------------------------------------------------------- feature trees
def _lattice_delta(f, P, T, regions, order=24):
    """max - min of every constituent over an order-``order`` lattice of every element,
    each evaluated on its own subregion."""
    i, j = np.meshgrid(np.arange(order + 1), np.arange(order + 1), indexing="ij")
    keep = i + j <= order
    lam = np.stack([order - i[keep] - j[keep], i[keep], j[keep]], 1) / order
    X = np.einsum("kv,mvd->mkd", lam, P[T]).reshape(-1, 2)
    c = f.composition(X, region=np.repeat(regions, len(lam))).reshape(len(T), len(lam), -1)
    return (c.max(axis=1) - c.min(axis=1)).max(axis=1)


def _example(name):
    from importlib import resources

    from hetmesh.io.model import load_model
    with resources.as_file(resources.files("hetmesh") / "examples" / f"{name}.toml") as p:
        return load_model(p)


@pytest.mark.parametrize("name", ["hft_ring", "hft_complex", "fgm_plate"])
def test_feature_tree_interval_bound_is_above_a_fine_lattice_and_tight(name):
    from hetmesh.material import element_subregions
    from hetmesh.material.hft import HFTField

    model = _example(name)
    f = model.material
    assert isinstance(f, HFTField) and f.unenclosable() is None
    res = generate(model, 0.3)
    P, T = res.mesh.points, res.mesh.triangles
    regions = element_subregions(f, P, T)
    with warnings.catch_warnings():
        warnings.simplefilter("error", CertificationUnavailable)  # a proof, no fallback
        bound = certified_delta(f, P, T, regions=regions)
    fine = _lattice_delta(f, P, T, regions)
    assert (bound >= fine).all()
    # tight: the settling tolerance (1 % + 1e-4) of the samples, plus what the lattice misses
    assert (bound <= fine * 1.02 + 2e-3).all()


def _random_tree(seed, free_select=True):
    """A seeded random feature tree on [0, 1]^2: points, segments, arcs and circles with
    constant or linear compositions, nearest and select parents, nested blends with
    per-subregion weights. ``free_select``: a select may also be a blend's distance only
    (not one of its children), where no subregion forces its choice: its rules are opaque
    predicates, so it is enclosed by the hull of its children."""
    from hetmesh.material.hft import (
        BlendFeature,
        CurveFeature,
        HFTField,
        NearestFeature,
        PointFeature,
        SelectFeature,
    )
    from hetmesh.tri.geometry import Arc, Segment

    rng = np.random.default_rng(seed)
    count = iter(range(1000))

    def comp():
        a = float(rng.uniform())
        return [a, 1.0 - a]

    def leaf():
        kind = rng.integers(4)
        fid = f"L{next(count)}"
        lin = rng.uniform() < 0.5
        if kind == 0:
            return PointFeature(fid, rng.uniform(0, 1, 2), comp())
        if kind == 1:
            curve = Segment(tuple(rng.uniform(0, 1, 2)), tuple(rng.uniform(0, 1, 2)))
        else:
            c = rng.uniform(0.2, 0.8, 2)
            r = float(rng.uniform(0.05, 0.4))
            t0 = float(rng.uniform(-np.pi, np.pi))
            sweep = 2 * np.pi * (1 if rng.uniform() < 0.5 else -1) if kind == 3 else \
                float(rng.uniform(-5.5, 5.5))
            curve = Arc(tuple(c), r, t0, t0 + sweep)
        return CurveFeature(fid, curve, comp(), comp() if lin else None)

    def curve_like(select=True):
        if rng.uniform() < 0.4:
            return NearestFeature(f"N{next(count)}", [leaf() for _ in range(rng.integers(2, 4))])
        if rng.uniform() < 0.3 and select:
            a = float(rng.uniform(0.3, 0.7))
            return SelectFeature(f"S{next(count)}", [leaf(), leaf()],
                                 [(0, lambda p, a=a: p[:, 0] < a), (1, None)])
        return leaf()

    weights = ["d1/(d1 + d2)", "exp(-3*d1)", "(d2/(d1 + d2))**2", "1/(1 + 4*d1**2)",
               "0.5 + 0.5*tanh(3*(d2 - d1))", "min(d1, 0.5)*2*(1 - d2)"]

    def blend(depth):
        first = blend(depth - 1) if depth and rng.uniform() < 0.5 else curve_like()
        second = curve_like()
        d1 = first if first.geometric else curve_like(free_select)
        w = [(weights[rng.integers(len(weights))], None)]
        if rng.uniform() < 0.5:  # a weight of its own for the subregions of one leaf
            owner = next(f for f in _leaves(second))
            w.insert(0, (weights[rng.integers(len(weights))], owner.id))
        return BlendFeature(f"B{next(count)}", first, second, {"d1": d1, "d2": second}, w)

    return HFTField(blend(2), ["a", "b"])


def _leaves(feature):
    if not feature.children:
        yield feature
    for c in feature.children:
        yield from _leaves(c)


@pytest.mark.parametrize("seed", range(12))
def test_random_feature_tree_enclosure_holds_on_random_boxes(seed):
    f = _random_tree(seed)
    rng = np.random.default_rng(100 + seed)
    k = 300
    lo_xy = rng.uniform(-0.1, 1.0, (k, 2))
    size = rng.uniform(0.0, 0.3, (k, 2)) * (rng.uniform(size=(k, 1)) < 0.9)  # some points
    box = (lo_xy[:, 0], lo_xy[:, 0] + size[:, 0], lo_xy[:, 1], lo_xy[:, 1] + size[:, 1])
    u = rng.uniform(size=(k, 60, 2))
    u[:, :4] = [[0, 0], [1, 0], [0, 1], [1, 1]]  # the corners too
    pts = lo_xy[:, None, :] + u * size[:, None, :]
    region = rng.integers(f.n_regions, size=k)
    for reg in (None, region):
        lo, hi = f.enclose(box, reg)
        r = None if reg is None else np.repeat(reg, 60)
        c = f.composition(pts.reshape(-1, 2), region=r).reshape(k, 60, -1)
        ok = np.isfinite(c)
        assert (np.where(ok, c >= lo[:, None], True)).all()
        assert (np.where(ok, c <= hi[:, None], True)).all()



@pytest.mark.parametrize("seed", range(12))
def test_random_feature_tree_enclosure_shrinks_with_the_box(seed):
    f = _random_tree(seed, free_select=False)
    rng = np.random.default_rng(200 + seed)
    k, h = 300, 1e-4
    lo_xy = rng.uniform(0.0, 1.0, (k, 2))
    region = f.region(lo_xy)  # where the subregion's field is the field
    lo, hi = f.enclose((lo_xy[:, 0], lo_xy[:, 0] + h, lo_xy[:, 1], lo_xy[:, 1] + h), region)
    pts = lo_xy[:, None, :] + rng.uniform(size=(k, 100, 2)) * h
    c = f.composition(pts.reshape(-1, 2), region=np.repeat(region, 100)).reshape(k, 100, -1)
    true = (c.max(axis=1) - c.min(axis=1)).max(axis=1)
    width = (hi - lo).max(axis=1)
    # first-order tight: over boxes of side 1e-4 the enclosure is a few times the variation
    # (the distances are enclosed independently of each other); boxes a curve's end or a
    # subregion's extrapolation crosses may be wider
    assert np.median(width) < 20 * np.median(true) + 1e-9
    assert np.mean(width < 1e-2) > 0.9


@pytest.mark.parametrize("seed", range(6))
def test_random_feature_tree_certified_bound_is_above_a_fine_lattice(seed):
    from hetmesh.material import element_subregions

    f = _random_tree(seed, free_select=seed % 2 == 0)
    P, T = _grid(8)
    regions = element_subregions(f, P, T)
    bound = certified_delta(f, P, T, regions=regions, max_depth=6)
    fine = _lattice_delta(f, P, T, regions, order=16)
    assert (bound >= fine).all()
    finite = np.isfinite(bound)
    assert finite.mean() > 0.9
    # without regions an element across a discontinuity is bounded across it
    across = certified_delta(f, P, T, max_depth=4)
    assert (across >= delta_dense(f, P, T, order=16)).all()


def test_a_feature_without_an_enclosure_falls_back_with_a_warning_naming_it():
    from hetmesh.material.hft import BlendFeature, CurveFeature, HFTField, PointFeature
    from hetmesh.material.hft.features import LeafFeature
    from hetmesh.tri.geometry import Segment

    class Wavy(PointFeature):  # a user's leaf kind: a point whose enclosure is unknown
        enclose = LeafFeature.enclose

    bot = CurveFeature("bot", Segment((0, 0), (1, 0)), [1.0, 0.0])
    top = Wavy("W", (0.5, 1.0), [0.0, 1.0])
    f = HFTField(BlendFeature("r", bot, top, {"d_b": bot, "d_t": top},
                              [("d_t/(d_b + d_t)", None)]), ["a", "b"])
    assert f.unenclosable() == "Wavy 'W'"
    P, T = _grid(3)
    with pytest.warns(CertificationUnavailable, match="feature Wavy 'W' has no interval"):
        bound = certified_delta(f, P, T)
    assert (bound >= _lattice_delta(f, P, T, f.region(P[T].mean(axis=1)))).all()


# ----------------------------------------------------------------------------- tetrahedra
FORMULAS3 = [
    "x**2 - y*z", "exp(-((x - 0.3)**2 + (y - 0.5)**2 + (z - 0.2)**2)/0.002)",
    "sin(5*x)*cos(3*y)*z", "sqrt(x**2 + y**2) - z", "where(z < 0.4, x, 1 - y)",
    "abs(x - z)", "clip(3*z - 1, 0, 1)", "tanh(8*(x + y - z - 0.2))",
]


def _random_tets(rng, k: int) -> tuple[np.ndarray, np.ndarray]:
    """``k`` separate random tetrahedra in [0, 1]^3 (positive volume)."""
    P = rng.uniform(0.0, 1.0, (k, 4, 3))
    e = P[:, 1:] - P[:, :1]
    vol = np.einsum("ki,ki->k", e[:, 0], np.cross(e[:, 1], e[:, 2]))
    P[vol < 0, 1], P[vol < 0, 2] = P[vol < 0, 2].copy(), P[vol < 0, 1].copy()
    return P.reshape(-1, 3), np.arange(4 * k).reshape(k, 4)


def test_tetrahedron_children_tile_their_parent():
    from hetmesh.certify import split_simplices
    rng = np.random.default_rng(3)
    P, T = _random_tets(rng, 20)
    kids = split_simplices(P[T])
    assert kids.shape == (160, 4, 3)

    def vol(c):
        e = c[:, 1:] - c[:, :1]
        return np.abs(np.einsum("ki,ki->k", e[:, 0], np.cross(e[:, 1], e[:, 2]))) / 6

    np.testing.assert_allclose(vol(kids).reshape(20, 8).sum(axis=1), vol(P[T]), rtol=1e-12)
    assert (vol(kids) > 0).all()
    # every point of the parent is in a child: barycentric coordinates of random points
    lam = rng.dirichlet(np.ones(4), 500)
    x = np.einsum("nv,vd->nd", lam, P[T][0])
    inside = np.zeros(len(x), bool)
    for c in kids[:8]:
        M = np.column_stack([c[1] - c[0], c[2] - c[0], c[3] - c[0]])
        b = np.linalg.solve(M, (x - c[0]).T).T
        inside |= (b >= -1e-12).all(axis=1) & (b.sum(axis=1) <= 1 + 1e-12)
    assert inside.all()


@pytest.mark.parametrize("text", FORMULAS3)
def test_certified_bound_on_tetrahedra_is_above_a_fine_lattice_and_close_to_it(text):
    f = AnalyticField({"b": text}, ["a", "b"], dim=3)
    P, T = _random_tets(np.random.default_rng(11), 24)
    with np.errstate(all="ignore"):
        fine = delta_dense(f, P, T, order=40)
    bound = certified_delta(f, P, T)
    assert (bound >= fine - 1e-12).all()
    # tight: the lattice itself is below the true maximum near narrow peaks and jumps
    assert (bound <= 1.1 * fine + 0.005).all()


def test_certified_bound_on_a_tetrahedron_sees_a_peak_inside_it():
    f = AnalyticField({"b": "exp(-((x - 0.3)**2 + (y - 0.3)**2 + (z - 0.2)**2)/1e-4)"},
                      ["a", "b"], dim=3)
    P = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
    T = np.array([[0, 1, 2, 3]])
    assert delta_dense(f, P, T)[0] < 0.01  # the 35-point lattice misses the peak
    assert 1.0 <= certified_delta(f, P, T)[0] < 1.02


def _prism_and_revolution():
    from hetmesh.tet.revolve import Revolution
    from hetmesh.tet.solid import box
    prism = box((0.0, 0.0, 0.0), (1.0, 1.0, 1.0))
    return prism, Revolution(box((0.5, -0.5, 0.0), (1.5, 0.5, 1.0)).section)


def test_section_and_revolved_fields_are_bounded_through_their_2d_field():
    from hetmesh.certify import certifiable
    from hetmesh.tet.extrude import SectionField
    from hetmesh.tet.revolve import RevolvedField
    prism, rev = _prism_and_revolution()
    f2 = AnalyticField({"b": "exp(-((x - 0.9)**2 + (y - 0.1)**2)/0.003)"}, ["a", "b"])
    rng = np.random.default_rng(5)
    for field in (SectionField(f2, prism), RevolvedField(f2, rev)):
        assert certifiable(field) is None
        P, T = _random_tets(rng, 60)
        P = 2.0 * P - 1.0 if isinstance(field, RevolvedField) else P
        fine = delta_dense(field, P, T, order=14)
        bound = certified_delta(field, P, T)
        assert (bound >= fine - 1e-12).all(), type(field).__name__
        assert np.median(bound - fine) < 0.01


def test_revolved_box_radius_range_holds_every_point_of_the_box():
    from hetmesh.certify import radial_range
    rng = np.random.default_rng(8)
    a, b = rng.uniform(-2, 2, (200, 3)), rng.uniform(-2, 2, (200, 3))
    lo, hi = np.minimum(a, b), np.maximum(a, b)
    rlo, rhi = radial_range(lo, hi)
    u = rng.uniform(size=(200, 400, 3))
    pts = lo[:, None] + u * (hi - lo)[:, None]
    r = np.hypot(pts[..., 0], pts[..., 1])
    assert (r >= rlo[:, None]).all() and (r <= rhi[:, None]).all()
    # tight: the corners reach the top, the nearest point of the rectangle the bottom
    corners = np.hypot(np.where(np.abs(lo[:, :2]) > np.abs(hi[:, :2]), lo[:, :2], hi[:, :2])[:, 0],
                       np.where(np.abs(lo[:, :2]) > np.abs(hi[:, :2]), lo[:, :2], hi[:, :2])[:, 1])
    np.testing.assert_allclose(rhi, corners, rtol=1e-12)


def test_a_field_constant_along_a_prism_bounds_its_tetrahedra_by_their_shadow():
    """An extruded field's tetrahedra are bounded on their shadows on the section: those of
    a swept prism (and of its layers) get exactly the bound of their section triangle."""
    from hetmesh.tet.extrude import SectionField, prism_tets
    prism, _ = _prism_and_revolution()
    f2 = AnalyticField({"b": "exp(-((x - 0.9)**2 + (y - 0.1)**2)/0.003)"}, ["a", "b"])
    rng = np.random.default_rng(9)
    tri = rng.uniform(0.0, 1.0, (30, 3, 2))
    P2, T2 = tri.reshape(-1, 2), np.arange(90).reshape(30, 3)
    pts, tets, _ = prism_tets(P2, T2, np.array([0.0, 0.4, 1.0]))
    field = SectionField(f2, prism)
    for threshold in (None, 0.3):
        b3 = certified_delta(field, pts, tets, threshold=threshold)
        b2 = certified_delta(f2, P2, T2, threshold=threshold)
        np.testing.assert_array_equal(b3.reshape(2, 30, 3), np.broadcast_to(
            b2[None, :, None], (2, 30, 3)))
    assert (b3 >= delta_dense(field, pts, tets, order=14) - 1e-12).all()


def test_a_call_past_its_piece_budget_stops_with_upper_bounds(monkeypatch):
    """The piece budget stops the subdivision early (one call's work is bounded); the
    elements left open keep their looser bounds, still above the true variation."""
    import hetmesh.certify as certify
    f = AnalyticField({"b": "exp(-((x - 0.3)**2 + (y - 0.5)**2 + (z - 0.2)**2)/0.002)"},
                      ["a", "b"], dim=3)
    P, T = _random_tets(np.random.default_rng(4), 24)
    full = certified_delta(f, P, T)
    monkeypatch.setattr(certify, "MAX_PIECES", 200)  # a level may hold 200
    monkeypatch.setattr(certify, "WORK_PER_ELEMENT", 2)
    capped = certified_delta(f, P, T)
    fine = delta_dense(f, P, T, order=30)
    assert (full >= fine - 1e-12).all() and (capped >= fine - 1e-12).all()
    assert (capped > full + 0.01).any()
