"""Heterogeneous Feature Tree material fields (hetmesh.material.hft): the paper's fgm_plate
(case study 3) and hft_ring (Fig. 7) against hand computations, gradients against finite
differences, NaN safety, and the model-file errors."""

from __future__ import annotations

import math
import time
import tomllib
from pathlib import Path

import numpy as np
import pytest

import hetmesh
from hetmesh.errors import FormulaError, MaterialError, ModelFileError
from hetmesh.geometry import Arc, Segment
from hetmesh.io.model import load_model, parse_model
from hetmesh.material.hft import (BlendFeature, CurveFeature, HFTField, NearestFeature,
                                  PointFeature, inside_predicate)

EXAMPLES = Path(hetmesh.__file__).resolve().parent / "examples"
PLATE = EXAMPLES / "fgm_plate.toml"
RING = EXAMPLES / "hft_ring.toml"
COMPLEX = EXAMPLES / "hft_complex.toml"


@pytest.fixture(scope="module")
def plate():
    return load_model(PLATE)


@pytest.fixture(scope="module")
def ring():
    return load_model(RING)


# ------------------------------------------------------------------ fgm_plate by hand

def _bottom_samples(n=200_001):
    """The bottom curve A..H sampled densely, with the ceramic fraction at each sample."""
    parts = []
    for (x0, x1, c) in ((0, 7, 1.0), (23, 37, 0.75), (53, 60, 0.5)):
        x = np.linspace(x0, x1, n // 10)
        parts.append((np.column_stack([x, 0 * x]), np.full(len(x), c)))
    for (cx, c0, c1) in ((15, 1.0, 0.75), (45, 0.75, 0.5)):
        s = np.linspace(0, 1, n)                       # arc length fraction from the left end
        a = math.pi * (1 - s)
        parts.append((np.column_stack([cx + 8 * np.cos(a), 8 * np.sin(a)]), c0 + s * (c1 - c0)))
    return np.concatenate([p for p, _ in parts]), np.concatenate([c for _, c in parts])


def _plate_by_hand(points):
    """CASES.md section 5: ceramic = W M_b + (1 - W) M_t, W = exp(-5 d_b/(d_b + d_t))."""
    curve, comp = _bottom_samples()
    out = []
    for p in points:
        d = np.hypot(curve[:, 0] - p[0], curve[:, 1] - p[1])
        i = int(np.argmin(d))
        d_b, m_b = d[i], comp[i]
        d_t = abs(20.0 - p[1])
        w = math.exp(-5 * d_b / (d_b + d_t))
        out.append(w * m_b + (1 - w) * 0.0)
    return np.array(out)


E = 1e-6
TABLE4 = {  # point just inside the domain near each Table 4 location -> bottom composition
    "A": ((E, E), 1.0), "B": ((7 - E, E), 1.0), "D": ((23 + E, E), 0.75),
    "E": ((37 - E, E), 0.75), "G": ((53 + E, E), 0.5), "H": ((60 - E, E), 0.5),
}


@pytest.mark.parametrize("name", sorted(TABLE4))
def test_plate_table4_bottom(plate, name):
    p, ceramic = TABLE4[name]
    c = plate.material.composition([p])[0]
    assert c[0] == pytest.approx(ceramic, abs=1e-5)
    assert c.sum() == pytest.approx(1.0, abs=1e-12)


@pytest.mark.parametrize("p", [(E, 20 - E), (60 - E, 20 - E)], ids=["M", "N"])
def test_plate_table4_top(plate, p):
    # The leaf composition at M, N is [0, 1] (Table 4). The field there is W M_b with
    # W -> exp(-5 d_b/(d_b + 0)) = exp(-5) (Eq. 28), not 0; M_b is taken on the nearest
    # groove arc (17 mm away, closer than A or H at 20 mm).
    top = plate.material.root.second
    assert top.evaluate(np.array([p])).comp[0].tolist() == [0.0, 1.0]
    c = plate.material.composition([p])[0, 0]
    assert c == pytest.approx(_plate_by_hand([p])[0], abs=2e-6)
    assert 0.5 * math.exp(-5) < c < math.exp(-5)


def test_plate_interior_vs_hand(plate):
    pts = np.array([[3.0, 4.0], [15.0, 9.0], [15.0, 14.0], [11.0, 6.0], [20.5, 3.0],
                    [30.0, 10.0], [45.0, 12.0], [50.0, 7.0], [57.0, 1.0], [1.0, 19.0]])
    got = plate.material.composition(pts)
    assert np.allclose(got[:, 0], _plate_by_hand(pts), atol=2e-6)  # sampling error 6e-7
    assert np.allclose(got.sum(axis=1), 1.0)


def test_plate_regions(plate):
    f = plate.material
    assert f.region_names == ["AB|top", "BCD|top", "DE|top", "EFG|top", "GH|top"]
    pts = np.array([[2.0, 1.0], [15.0, 9.0], [30.0, 1.0], [45.0, 9.0], [58.0, 1.0]])
    assert f.region(pts).tolist() == [0, 1, 2, 3, 4]
    assert f.evaluate(pts)[2].tolist() == [0, 1, 2, 3, 4]


def test_plate_forced_region_is_smooth_extension(plate):
    f = plate.material
    # AB and BCD own the points below / above the parabola 16 y + 64 = (x - 15)^2 (equal
    # distance to the line and to the arc), through (3, 5): the field jumps there.
    p = np.array([[3.0, 5.0 + 1e-4], [3.0, 5.0 - 1e-4]])
    own = f.composition(p)
    assert f.region(p).tolist() == [1, 0]
    assert own[1, 0] - own[0, 0] > 5e-3                       # a genuine discontinuity
    forced = f.composition(p, region=[0, 0])                  # AB's field on both sides
    assert forced[1].tolist() == own[1].tolist()
    assert forced[0, 0] == pytest.approx(own[1, 0], abs=1e-4)  # continuous within AB's field
    forced = f.composition(p, region=[1, 1])                  # and BCD's
    assert forced[1, 0] == pytest.approx(own[0, 0], abs=1e-4)
    assert np.isfinite(f.gradient([[3.0, 5.0]])).all()        # (nearly) equidistant


def _fd(field, pts, region, h=1e-6):
    g = np.empty(pts.shape[:1] + (len(field.constituents), 2))
    for k in range(2):
        e = np.zeros(2)
        e[k] = h
        g[:, :, k] = (field.composition(pts + e, region=region)
                      - field.composition(pts - e, region=region)) / (2 * h)
    return g


def test_plate_gradient_vs_finite_differences(plate):
    f = plate.material
    rng = np.random.default_rng(1)
    pts = rng.uniform([0.5, 0.5], [59.5, 19.5], (400, 2))
    pts = pts[plate.domain.contains(pts)]
    reg = f.region(pts)
    g = f.gradient(pts, region=reg)
    fd = _fd(f, pts, reg)
    assert np.allclose(g, fd, atol=2e-6, rtol=1e-5)
    # the composition gradient along the arcs contributes: check a point above BCD's apex
    p = np.array([[15.0, 10.0]])
    assert f.gradient(p)[0, 0, 0] != 0.0
    assert np.allclose(f.gradient(p), _fd(f, p, f.region(p)), atol=1e-7)


def test_plate_gradient_on_boundary_uses_left_normal(plate):
    # On AB (d_b = 0) grad d_b is the inward normal (0, 1): the one-sided limit from inside.
    f = plate.material
    g = f.gradient([[3.0, 0.0]])
    fd = (f.composition([[3.0, 1e-6]]) - f.composition([[3.0, 0.0]])) / 1e-6
    assert g[0, 0, 1] == pytest.approx(fd[0, 0], rel=1e-4)


# ------------------------------------------------------------------ hft_ring closed forms

def _ring_by_hand(pts):
    rho = np.hypot(pts[:, 0], pts[:, 1])
    unit = pts / rho[:, None]
    inner = rho < 28
    d_c, d_b = rho - 8, 38 - rho
    f = np.where(inner, 1 + (0.4 - 1) * (d_c / 20) ** 3, 0 + 0.4 * (d_b / 10) ** 2)
    dfdr = np.where(inner, 3 * (0.4 - 1) * d_c ** 2 / 20 ** 3, -2 * 0.4 * d_b / 100)
    return f, dfdr[:, None] * unit


def test_ring_closed_forms(ring):
    rng = np.random.default_rng(2)
    rho = rng.uniform(8, 38, 2000)
    a = rng.uniform(0, 2 * np.pi, 2000)
    pts = np.column_stack([rho * np.cos(a), rho * np.sin(a)])
    f, g = _ring_by_hand(pts)
    comp = ring.material.composition(pts)
    grad = ring.material.gradient(pts)
    assert np.allclose(comp[:, 0], f, atol=1e-12)
    assert np.allclose(comp[:, 1], 1 - f, atol=1e-12)
    assert np.allclose(grad[:, 0], g, atol=1e-12)
    assert np.allclose(grad[:, 1], -g, atol=1e-12)
    reg = ring.material.region(pts)
    assert ring.material.region_names == ["A|C", "A|B"]
    assert np.array_equal(reg, (rho >= 28).astype(int))
    assert np.allclose(grad, _fd(ring.material, pts, reg), atol=1e-6)


def test_ring_values_at_circles(ring):
    pts = np.array([[8.0, 0.0], [0.0, -28.0 + 1e-9], [0.0, 28.0 + 1e-9], [-38.0, 0.0]])
    assert np.allclose(ring.material.composition(pts)[:, 0], [1.0, 0.4, 0.4, 0.0], atol=1e-9)


# ------------------------------------------------------------------ NaN safety

def test_no_nan_on_features_and_equidistant(plate, ring):
    on_plate = np.array([[0, 0], [7, 0], [15, 8], [23, 0], [45, 8], [60, 0], [0, 20], [60, 20],
                         [30, 20], [15, 0], [45, 0], [3.5, 0],
                         # equidistant from two features / two sub-features
                         [30, 10], [7 - 2, 5.0], [30, 4.0], [15, 4.0]], dtype=float)
    on_plate = np.vstack([on_plate, [[15 + 8 * np.cos(t), 8 * np.sin(t)]
                                     for t in np.linspace(0, np.pi, 7)]])
    on_ring = np.array([[0, 0], [8, 0], [0, 28], [-38, 0], [0, 23], [1e-300, 0]], dtype=float)
    for model, pts in ((plate, on_plate), (ring, on_ring)):
        c, g, r = model.material.evaluate(pts)
        assert np.isfinite(c).all() and np.isfinite(g).all()
        for reg in range(model.material.n_regions):
            c, g, _ = model.material.evaluate(pts, region=np.full(len(pts), reg))
            assert np.isfinite(c).all() and np.isfinite(g).all()


def test_leaf_features_direct():
    pf = PointFeature("P", (1.0, 1.0), [0.2, 0.8])
    ev = pf.evaluate(np.array([[1.0, 1.0], [4.0, 5.0]]))
    assert ev.dist.tolist() == [0.0, 5.0]
    assert ev.ddist.tolist() == [[0.0, 0.0], [0.6, 0.8]]
    seg = CurveFeature("S", Segment((0, 0), (4, 0)), [1.0, 0.0], [0.0, 1.0])
    ev = seg.evaluate(np.array([[1.0, 2.0], [-3.0, -4.0], [2.0, 0.0]]))
    assert ev.dist.tolist() == [2.0, 5.0, 0.0]
    assert ev.comp[0].tolist() == [0.75, 0.25]
    assert ev.dcomp[0].tolist() == [[-0.25, 0.0], [0.25, 0.0]]
    assert ev.dcomp[1].tolist() == [[0.0, 0.0], [0.0, 0.0]]   # nearest point is an end
    assert ev.ddist[2].tolist() == [0.0, 1.0]                 # left normal on the curve
    arc = CurveFeature("Q", Arc((0, 0), 2.0, 0.0, np.pi / 2), [1.0, 0.0], [0.0, 1.0])
    ev = arc.evaluate(np.array([[3.0, 3.0], [0.0, 0.0]]))
    assert ev.dist[0] == pytest.approx(3 * math.sqrt(2) - 2)
    assert ev.comp[0] == pytest.approx([0.5, 0.5])
    # d(comp)/dp = dc * dtheta/dp / sweep, dtheta/dp = (-y, x)/rho^2
    assert ev.dcomp[0, 1] == pytest.approx(np.array([-3.0, 3.0]) / 18 / (np.pi / 2))
    assert np.isfinite(ev.dcomp[1]).all() and np.isfinite(ev.ddist[1]).all()


def test_inside_predicate_stadium():
    # hft_complex's interface A: a stadium of radius 30 around (-40, 0) and (40, 0).
    curves = [Segment((-40, -30), (40, -30)), Arc.from_center((40, -30), (40, 30), (40, 0)),
              Segment((40, 30), (-40, 30)), Arc.from_center((-40, 30), (-40, -30), (-40, 0))]
    inside = inside_predicate(curves[::-1])
    rng = np.random.default_rng(3)
    p = rng.uniform([-80, -40], [80, 40], (20000, 2))
    dx = np.maximum(np.abs(p[:, 0]) - 40, 0)
    assert np.array_equal(inside(p), np.hypot(dx, p[:, 1]) < 30)


def test_programmatic_tree_and_shift():
    bot = NearestFeature("bot", [CurveFeature("l", Segment((0, 0), (1, 0)), [1.0, 0.0]),
                                 CurveFeature("r", Segment((1, 0), (2, 0)), [0.5, 0.5])])
    top = CurveFeature("top", Segment((2, 1), (0, 1)), [0.0, 1.0])
    f = HFTField(BlendFeature("r", bot, top, {"d_b": bot, "d_t": top},
                              [("d_t/(d_b + d_t)", None)]), ["ceramic", "metal"])
    p = np.array([[0.5, 0.25], [1.5, 0.5]])
    assert f.composition(p).tolist() == [[0.75, 0.25], [0.25, 0.75]]
    g = f.shifted((100.0, -50.0))
    assert np.allclose(g.composition(p - [100.0, -50.0]), f.composition(p))
    with pytest.raises(MaterialError, match="region"):
        f.composition(p, region=[0, 7])


# ------------------------------------------------------------------ bad model files

def _ring_data():
    return tomllib.loads(RING.read_text())


def _feature(data, fid):
    return next(f for f in data["material"]["features"] if f["id"] == fid)


def test_error_cycle():
    data = _ring_data()
    _feature(data, "boundary")["rules"][1]["child"] = "ring"
    with pytest.raises(ModelFileError, match=r"features\.\w+: cycle in the feature tree: "
                                             r"ring -> boundary -> ring"):
        parse_model(data, "r.toml")


def test_error_unknown_reference():
    data = _ring_data()
    _feature(data, "ring")["distances"]["d_b"] = "boundry"
    with pytest.raises(ModelFileError, match=r"^r.toml: material.features.ring: "
                                             r"distances.d_b: unknown feature 'boundry'$"):
        parse_model(data, "r.toml")
    data = _ring_data()
    data["material"]["root"] = "rink"
    with pytest.raises(ModelFileError, match="material.root: unknown feature 'rink'"):
        parse_model(data, "r.toml")


def test_error_composition_length():
    data = _ring_data()
    _feature(data, "A")["composition"] = [0.4, 0.3, 0.3]
    with pytest.raises(MaterialError, match=r"^r.toml: material.features.A: composition has "
                                            r"3 values but there are 2 constituents"):
        parse_model(data, "r.toml")
    data = _ring_data()
    _feature(data, "A")["composition"] = [0.4, 0.4]
    with pytest.raises(MaterialError, match="features.A: composition .* summing to 1"):
        parse_model(data, "r.toml")


def test_error_weight_out_of_range():
    data = _ring_data()
    _feature(data, "ring")["weight"] = "1.5*(d_b/(d_int + d_b))**2"
    with pytest.raises(MaterialError, match=r"^r.toml: feature 'ring': weight .* is 1\.5 at "
                                            r".* in subregion 'A\|B', outside \[0, 1\]$"):
        parse_model(data, "r.toml")


def test_error_misc():
    data = _ring_data()
    _feature(data, "ring")["weight"] = "d_q"
    with pytest.raises(FormulaError, match="feature 'ring': weight"):
        parse_model(data, "r.toml")
    data = _ring_data()
    _feature(data, "C")["kind"] = "ellipse"
    with pytest.raises(ModelFileError, match="features.C.kind: unknown kind 'ellipse'"):
        parse_model(data, "r.toml")
    data = _ring_data()
    _feature(data, "boundary")["rules"][0] = {"child": "C", "where": "x**2 + y**2 < 28**2"}
    assert parse_model(data, "r.toml").material.region([[0, 20], [0, 30]]).tolist() == [0, 1]
    data = _ring_data()
    data["material"]["features"].append({"id": "near", "kind": "nearest",
                                         "children": ["C", "ring"]})
    with pytest.raises(ModelFileError, match="child 'ring' is a blend"):
        parse_model(data, "r.toml")


# ------------------------------------------------------------------ timing (printed)

def test_timing_plate_1m(plate, capsys):
    f = plate.material
    p = np.random.default_rng(0).uniform([0, 0], [60, 20], (1_000_000, 2))
    f.evaluate(p[:1000])
    t0 = time.perf_counter()
    c = f.composition(p)
    g = f.gradient(p)           # same points: served from the one-entry cache
    t1 = time.perf_counter()
    q = p.copy()
    q[0, 0] += 1e-9             # new contents: no cache hit
    f.gradient(q)
    t2 = time.perf_counter()
    with capsys.disabled():
        print(f"\nfgm_plate, 1e6 points: composition + gradient {t1 - t0:.2f} s; "
              f"one uncached evaluation {t2 - t1:.2f} s")
    assert c.shape == (1_000_000, 2) and g.shape == (1_000_000, 2, 2)
