"""Heterogeneous Feature Tree material fields (hetmesh.material.hft): the paper's fgm_plate
(case study 3) and hft_ring (Fig. 7) against hand computations, gradients against finite
differences, NaN safety, and the model-file errors."""

from __future__ import annotations

import math
import re
import time
import tomllib
from pathlib import Path

import numpy as np
import pytest

import hetmesh
from hetmesh.errors import FormulaError, MaterialError, ModelFileError
from hetmesh.io.model import load_model, parse_model
from hetmesh.material.hft import (
    BlendFeature,
    CurveFeature,
    HFTField,
    NearestFeature,
    PointFeature,
    SelectFeature,
    inside_predicate,
)
from hetmesh.tri.geometry import Arc, Segment

EXAMPLES = Path(hetmesh.__file__).resolve().parent / "examples"
PLATE = EXAMPLES / "fgm_plate.toml"
RING = EXAMPLES / "hft_ring.toml"
COMPLEX = EXAMPLES / "hft_complex.toml"
CASES_DOC = Path(__file__).resolve().parents[1] / "docs" / "cases.md"


@pytest.fixture(scope="module")
def plate():
    return load_model(PLATE)


@pytest.fixture(scope="module")
def ring():
    return load_model(RING)


@pytest.mark.parametrize("path", [RING, COMPLEX, PLATE], ids=lambda p: p.stem)
def test_examples_say_their_geometry_is_reconstructed(path):
    text = path.read_text(encoding="utf-8")
    assert "RECONSTRUCTION (docs/cases.md, section" in text
    model = load_model(path)
    assert model.name == path.stem and model.units == "mm"
    assert hetmesh.example_path(path.stem).resolve() == path.resolve()



@pytest.mark.skipif(not CASES_DOC.exists(), reason="docs/cases.md not next to the tests")
def test_cited_sections_of_docs_cases_exist():
    """Every "docs/cases.md, section N" cited in the examples and the sources names a
    section of that file about the model that cites it."""
    text = CASES_DOC.read_text(encoding="utf-8")
    headings = {int(n): name for n, name in re.findall(r"^## (\d+)\. (?:`(\w+)`)?", text, re.M)}
    src = Path(hetmesh.__file__).resolve().parent
    cited = 0
    for path in [*EXAMPLES.glob("*.toml"), *src.rglob("*.py")]:
        for n in re.findall(r"docs/cases\.md, section (\d+)", path.read_text(encoding="utf-8")):
            assert int(n) in headings, (path.name, n)
            if path.suffix == ".toml":
                assert headings[int(n)] == path.stem, (path.name, n, headings[int(n)])
            cited += 1
    assert cited >= 6

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
    """docs/cases.md, section 5: ceramic = W M_b + (1 - W) M_t, W = exp(-5 d_b/(d_b + d_t))."""
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


# ------------------------------------------------------------------ hft_complex by hand

def _stadium_axis_distance(p):
    """Distance to the segment (-40, 0)-(40, 0): the stadiums C and A are its level sets
    10 and 30."""
    return np.hypot(np.maximum(np.abs(p[:, 0]) - 40.0, 0.0), p[:, 1])


def _rounded_rectangle_distance(p):
    """Distance from a point inside [-100, 100] x [-70, 70] (corner radius 20) to its
    boundary: to the corner arc (centre (+-80, +-50)) in the corner squares, else to the
    nearer side."""
    ax, ay = np.abs(p[:, 0]), np.abs(p[:, 1])
    qx, qy = ax - 80.0, ay - 50.0
    corner = (qx > 0) & (qy > 0)
    return np.where(corner, 20.0 - np.hypot(qx, qy), np.minimum(100.0 - ax, 70.0 - ay))


def _complex_by_hand(p):
    """docs/cases.md, section 4: f = W M_A + (1 - W) M_b, W = (d_b/(d_int + d_b))^3 inside A
    (M_b = M_C = 1, d_b to C), ^2 outside (M_b = M_B = 0, d_b to B)."""
    rho = _stadium_axis_distance(p)
    inner = rho < 30.0
    d_int = np.abs(rho - 30.0)
    d_b = np.where(inner, rho - 10.0, _rounded_rectangle_distance(p))
    w = (d_b / (d_int + d_b)) ** np.where(inner, 3, 2)
    return w * 0.4 + (1.0 - w) * np.where(inner, 1.0, 0.0)


@pytest.fixture(scope="module")
def complex_model():
    return load_model(COMPLEX)


def test_complex_by_hand_at_points(complex_model):
    f = complex_model.material
    r = 20 - 10 * math.sqrt(2)               # (90, 60): 20 - |(10, 10)| from the NE corner arc
    rho = math.hypot(50, 60)                 # and |(50, 60)| from the axis end (40, 0)
    w = (r / (r + rho - 30)) ** 2
    cases = {
        (0.0, 20.0): 0.125 * 0.4 + 0.875,    # above the straight part: d_C = d_A = 10
        (60.0, 0.0): 0.125 * 0.4 + 0.875,    # right of the right arc: the same
        (40.0, -10.0): 1.0,                  # on C, where its arc meets its bottom side
        (0.0, 50.0): 0.25 * 0.4,             # between A and B: d_A = 20, d_B = 20
        (-85.0, 0.0): (15 / 30) ** 2 * 0.4,  # left of A: d_A = 15, d_B = 15
        (-70.0 + 1e-9, 0.0): 0.4,            # on A (d_int = 1e-9): W = 1 - 1.5e-10
        (90.0, 60.0): w * 0.4,               # in the NE corner
        (0.0, -69.0): (1 / 40) ** 2 * 0.4,   # next to B's bottom side
    }
    pts = np.array(list(cases))
    got = f.composition(pts)
    assert np.allclose(got[:, 0], list(cases.values()), atol=1e-9, rtol=0)
    assert np.allclose(got[:, 0], _complex_by_hand(pts), atol=1e-12, rtol=0)
    assert np.allclose(got.sum(axis=1), 1.0)


def test_complex_vs_hand_and_gradient(complex_model):
    f = complex_model.material
    rng = np.random.default_rng(4)
    pts = rng.uniform([-100, -70], [100, 70], (4000, 2))
    pts = pts[complex_model.domain.contains(pts)]
    assert np.allclose(f.composition(pts)[:, 0], _complex_by_hand(pts), atol=1e-12, rtol=0)
    reg = f.region(pts)
    assert f.region_names == ["A|C", "A|B"]  # uniform composite curves: one subregion each
    assert np.array_equal(reg, (_stadium_axis_distance(pts) >= 30).astype(int))
    # away from the rectangle's medial axis, where grad d_B has a kink
    ax, ay = np.abs(pts[:, 0]), np.abs(pts[:, 1])
    smooth = (np.abs((100 - ax) - (70 - ay)) > 1e-3) & (ay > 1e-3)
    g = f.gradient(pts[smooth], region=reg[smooth])
    assert np.allclose(g, _fd(f, pts[smooth], reg[smooth]), atol=2e-6)


def test_uniform_composite_is_one_subregion():
    a = CurveFeature("a", Segment((0, 0), (1, 0)), [1.0, 0.0])
    b = CurveFeature("b", Segment((1, 0), (1, 1)), [1.0, 0.0])
    c = CurveFeature("c", Segment((1, 1), (0, 1)), [0.5, 0.5])
    ab = NearestFeature("ab", [a, b])
    assert ab.uniform and ab.n_regions == 1 and ab.region_name(0) == "ab"
    p = np.array([[0.5, -1.0], [2.0, 0.5]])
    assert ab.region(p).tolist() == [0, 0]
    assert ab.evaluate(p).dist.tolist() == [1.0, 1.0]
    assert ab.evaluate(p, np.zeros(2, dtype=int)).dist.tolist() == [1.0, 1.0]
    nested = NearestFeature("n", [ab, CurveFeature("d", Segment((0, 1), (0, 0)), [1.0, 0.0])])
    assert nested.uniform and nested.n_regions == 1
    mixed = NearestFeature("abc", [a, b, c])
    assert not mixed.uniform and mixed.n_regions == 3
    graded = CurveFeature("g", Segment((0, 2), (1, 2)), [1.0, 0.0], [0.0, 1.0])
    assert NearestFeature("ag", [a, graded]).n_regions == 2


# ------------------------------------------------------------------ NaN safety

def test_no_nan_on_features_and_equidistant(plate, ring, complex_model):
    on_plate = np.array([[0, 0], [7, 0], [15, 8], [23, 0], [45, 8], [60, 0], [0, 20], [60, 20],
                         [30, 20], [15, 0], [45, 0], [3.5, 0],
                         # equidistant from two features / two sub-features
                         [30, 10], [7 - 2, 5.0], [30, 4.0], [15, 4.0]], dtype=float)
    on_plate = np.vstack([on_plate, [[15 + 8 * np.cos(t), 8 * np.sin(t)]
                                     for t in np.linspace(0, np.pi, 7)]])
    on_ring = np.array([[0, 0], [8, 0], [0, 28], [-38, 0], [0, 23], [1e-300, 0]], dtype=float)
    on_complex = np.array([[0, 0], [40, 0], [-40, 0], [40, -10], [40, 10], [-50, 0], [0, 10],
                           [0, 30], [40, 30], [-70, 0], [80, -70], [100, 0], [90, 60],
                           [85, 0], [0, 50], [80, 50], [-20, 20], [70, 30]], dtype=float)
    for model, pts in ((plate, on_plate), (ring, on_ring), (complex_model, on_complex)):
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


def test_inside_predicate_on_arc_chords():
    # Points on the line joining an arc's ends lie inside the shape: the chord polygon's
    # crossing test and the circular segment's test must not both skip them (the mesher
    # puts a vertex at (40, -10), where C's arc meets C's bottom side, on A's chord x = 40).
    def stadium(swap):
        def P(x, y):
            return (y, x) if swap else (x, y)
        return [Segment(P(-40, -30), P(40, -30)),
                Arc.from_center(P(40, -30), P(40, 30), P(40, 0), ccw=not swap),
                Segment(P(40, 30), P(-40, 30)),
                Arc.from_center(P(-40, 30), P(-40, -30), P(-40, 0), ccw=not swap)]
    y = np.linspace(-29.5, 29.5, 61)
    pts = np.concatenate([np.column_stack([np.full_like(y, 40.0), y]),
                          np.column_stack([np.full_like(y, -40.0), y]),
                          np.column_stack([np.linspace(-69.5, 69.5, 101), np.zeros(101)])])
    for swap in (False, True):
        p = pts[:, ::-1] if swap else pts
        for curves in (stadium(swap), stadium(swap)[::-1]):
            assert inside_predicate(curves)(p).all()
            assert not inside_predicate(curves)(p + (p[:1] * 0 + 200.0)).any()


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


# ------------------------------------------------------------------ bad input via the CLI
# Bad feature trees: each a one-line error naming the feature, exit code 2, nothing written.

def _edit(text: str, old: str, new: str) -> str:
    assert text.count(old) == 1, old
    return text.replace(old, new)


RING_RULES = 'rules = [{ child = "C", inside = "A" }, { child = "B" }]'
RING_B = 'radius = 38\ncomposition = [0, 1]'
BAD_RING = {
    "cycle": ((RING_RULES, 'rules = [{ child = "C", inside = "A" }, { child = "ring" }]'),
              "boundary", "cycle in the feature tree: ring -> boundary -> ring"),
    "unknown": (('d_b = "boundary"', 'd_b = "boundry"'),
                "features.ring", "distances.d_b: unknown feature 'boundry'"),
    "composition-length": (("composition = [0.4, 0.6]", "composition = [0.4, 0.3, 0.3]"),
                           "features.A", "composition has 3 values but there are 2"),
    "weight-range": (('weight = "(d_b/', 'weight = "1.5*(d_b/'),
                     "feature 'ring'", "is 1.5 at ("),
    "unowned": ((RING_RULES, 'rules = [{ child = "C", inside = "A" }]'),
                "feature 'boundary'", "region rule leaves part of the domain unowned: "
                                      "no rule holds at ("),
    "unowned-where": ((RING_RULES, 'rules = [{ child = "C", inside = "A" }, '
                                   '{ child = "B", where = "x**2 + y**2 > 30**2" }]'),
                      "feature 'boundary'", "unowned: no rule holds at ("),
    "curve-outside": ((RING_B, 'radius = 40\ncomposition = [0, 1]'),
                      "feature 'B'", "curve lies outside the domain at (40, 0), 2 from"),
}


def _mesh_cli(tmp_path, text, capsys):
    from hetmesh.cli import main

    model = tmp_path / "bad.toml"
    model.write_text(text, encoding="utf-8")
    out = tmp_path / "out.vtu"
    code = main(["mesh", str(model), "--threshold", "0.1", "-o", str(out)])
    captured = capsys.readouterr()
    return code, captured.err, out


@pytest.mark.parametrize("case", sorted(BAD_RING))
def test_bad_ring_through_cli(case, tmp_path, capsys):
    (old, new), names, says = BAD_RING[case]
    code, err, out = _mesh_cli(tmp_path, _edit(RING.read_text(), old, new), capsys)
    assert code == 2, err
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert "Traceback" not in err
    assert lines[0].startswith("hetmesh: error: ") and "bad.toml: " in lines[0], lines[0]
    assert names in lines[0] and says in lines[0], lines[0]
    assert not out.exists()
    assert [p.name for p in tmp_path.iterdir()] == ["bad.toml"]


def test_good_ring_through_cli(tmp_path, capsys):
    # the same helper on the unedited model writes the mesh (the cases above are not
    # failing for another reason); a complete default-free rule list is accepted
    text = _edit(RING.read_text(), RING_RULES,
                 'rules = [{ child = "C", inside = "A" }, { child = "B", outside = "A" }]')
    code, err, out = _mesh_cli(tmp_path, text, capsys)
    assert code == 0, err
    assert out.exists()


def test_point_feature_outside_the_domain():
    data = _ring_data()
    data["material"]["features"].append({"id": "P", "kind": "point", "at": [0, 50],
                                         "composition": [0.5, 0.5]})
    _feature(data, "ring")["distances"]["d_p"] = "P"      # the root now depends on P
    with pytest.raises(MaterialError, match=r"^r.toml: feature 'P': point lies outside the "
                                            r"domain at \(0, 50\), 12 from its boundary$"):
        parse_model(data, "r.toml")
    _feature(data, "P")["at"] = [0, 4]                    # in the hole
    with pytest.raises(MaterialError, match=r"feature 'P': point lies outside the domain "
                                            r"at \(0, 4\), 4 from"):
        parse_model(data, "r.toml")
    _feature(data, "P")["at"] = [0, 8]                    # on the hole's circle: fine
    parse_model(data, "r.toml")
    # a feature no evaluation reaches is not checked against the domain
    del _feature(data, "ring")["distances"]["d_p"]
    _feature(data, "P")["at"] = [0, 50]
    parse_model(data, "r.toml")


def test_curve_outside_the_plate():
    data = tomllib.loads(PLATE.read_text())
    _feature(data, "top").update({"from": [60, 21], "to": [0, 21]})
    with pytest.raises(MaterialError, match=r"^p.toml: feature 'top': curve lies outside the "
                                            r"domain at \(60, 21\), 1 from its boundary$"):
        parse_model(data, "p.toml")
    # on the boundary to well within the tolerance (1e-6 x diameter): fine
    _feature(data, "top").update({"from": [60, 20 + 1e-9], "to": [0, 20 + 1e-9]})
    parse_model(data, "p.toml")


def test_select_of_blends_checks_only_routed_points():
    # The ring as a three-level tree: a select of two blends written in the closed forms of
    # Eqs. (21)-(22). Each W leaves [0, 1] in the other's subregion ((d_C/20)^3 > 1 outside
    # A) and the outer blend's boundary is a select without default owning only outside A:
    # both are fine because neither is evaluated there.
    data = _ring_data()
    feats = [f for f in data["material"]["features"] if f["id"] in ("A", "B", "C")]
    feats += [
        {"id": "outside_A", "kind": "select", "rules": [{"child": "B", "outside": "A"}]},
        {"id": "inner", "kind": "blend", "first": "A", "second": "C",
         "distances": {"d_C": "C"}, "weight": "(d_C/20)**3"},
        {"id": "outer", "kind": "blend", "first": "A", "second": "outside_A",
         "distances": {"d_B": "outside_A"}, "weight": "(d_B/10)**2"},
        {"id": "ring", "kind": "select",
         "rules": [{"child": "inner", "inside": "A"}, {"child": "outer"}]},
    ]
    data["material"]["features"] = feats
    model = parse_model(data, "r.toml")
    rng = np.random.default_rng(7)
    rho, a = rng.uniform(8, 38, 500), rng.uniform(0, 2 * np.pi, 500)
    pts = np.column_stack([rho * np.cos(a), rho * np.sin(a)])
    f, g = _ring_by_hand(pts)
    assert np.allclose(model.material.composition(pts)[:, 0], f, atol=1e-12)
    assert np.allclose(model.material.gradient(pts)[:, 0], g, atol=1e-12)
    assert model.material.region_names == ["A|C", "A|B"]
    # the same weights as one blend over the whole domain are rejected
    feats[-1] = {"id": "ring", "kind": "blend", "first": "A", "second": "C",
                 "distances": {"d_C": "C"}, "weight": "(d_C/20)**3"}
    with pytest.raises(MaterialError, match=r"feature 'ring': weight '\(d_C/20\)\*\*3' is 3\.375 "):
        parse_model(data, "r.toml")


def test_select_without_default_never_uses_owner_minus_one():
    c = CurveFeature("c", Arc.circle((0, 0), 1.0), [1.0, 0.0])
    b = CurveFeature("b", Arc.circle((0, 0), 3.0), [0.0, 1.0])
    a = CurveFeature("a", Arc.circle((0, 0), 2.0), [0.5, 0.5])
    inside_a = inside_predicate(a.curves(), "a")
    sel = SelectFeature("s", [c, b], [(0, inside_a), (1, lambda p: np.hypot(*p.T) > 2.5)])
    assert sel.owners(np.array([[0.0, 1.5], [0.0, 2.2], [0.0, 2.7]])).tolist() == [0, -1, 1]
    ok = np.array([[0.0, 1.5], [0.0, 2.7]])
    assert sel.region(ok).tolist() == [0, 1]
    assert sel.evaluate(ok).dist.tolist() == pytest.approx([0.5, 0.3])
    for call in (sel.region, sel.evaluate, sel.distance):
        with pytest.raises(MaterialError, match=r"^feature 's': region rule leaves part of the "
                                                r"domain unowned: no rule holds at \(0, 2.2\)"):
            call(np.array([[0.0, 1.5], [0.0, 2.2], [0.0, 2.7], [2.2, 0.0]]))
    f = HFTField(BlendFeature("r", a, sel, {"d_int": a, "d_b": sel}, [("d_b/(d_int + d_b)", None)]),
                 ["ceramic", "metal"])
    with pytest.raises(MaterialError, match="feature 's': region rule"):
        f.composition([[0.0, 2.2]])


# ------------------------------------------------------------------ docs/model-format.md

DOCS = Path(__file__).resolve().parents[1] / "docs" / "model-format.md"


def _hft_docs_section() -> str:
    text = DOCS.read_text(encoding="utf-8")
    return text[text.index("## Feature trees"):text.index("## Models in code")]


@pytest.mark.skipif(not DOCS.exists(), reason="docs/ not next to the tests")
def test_docs_hft_models_load():
    import re

    blocks = [b for b in re.findall(r"```toml\n(.*?)```", _hft_docs_section(), re.S)
              if "[domain" in b]
    assert len(blocks) == 2
    deeper = parse_model(tomllib.loads(blocks[0]), "deeper.toml")
    # plate = W M_top + (1 - W) M_sides, W = (1 - d_t/4)^2, sides = d_r/10 M_left + ...
    x, y = 2.0, 1.0
    w = (1 - (4 - y) / 4) ** 2
    top = 0.2 + (10 - x) / 10 * (0.6 - 0.2)        # graded from (10, 4) to (0, 4)
    sides = (10 - x) / 10 * 1.0
    assert deeper.material.composition([[x, y]])[0, 0] == pytest.approx(w * top + (1 - w) * sides)
    assert deeper.material.region_names == ["top|left|right"]
    disc = parse_model(tomllib.loads(blocks[1]), "disc.toml")
    assert disc.material.composition([[3.0, 4.0]])[0, 0] == pytest.approx(0.5)


@pytest.mark.skipif(not DOCS.exists(), reason="docs/ not next to the tests")
def test_docs_hft_error_lines_are_real():
    section = _hft_docs_section()
    shown = section[section.index("### Errors"):].split("```")[1].strip().splitlines()
    edits = [
        lambda d: _feature(d, "boundary")["rules"][1].update(child="ring"),
        lambda d: _feature(d, "ring")["distances"].update(d_b="boundry"),
        lambda d: _feature(d, "A").update(composition=[0.4, 0.3, 0.3]),
        lambda d: _feature(d, "ring").update(weight="1.5*(d_b/(d_int + d_b))**2"),
        lambda d: _feature(d, "boundary").update(rules=[{"child": "C", "inside": "A"}]),
        lambda d: _feature(d, "B").update(radius=40),
    ]
    got = []
    for edit in edits:
        data = _ring_data()
        edit(data)
        with pytest.raises((ModelFileError, MaterialError)) as info:
            parse_model(data, "m.toml")
        got.append(str(info.value))
    assert got == shown


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
