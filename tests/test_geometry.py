"""Curves, domains (exact areas, validation) and the PSLG."""

from __future__ import annotations

import math
import pickle
import re

import numpy as np
import pytest

from hetmesh.errors import GeometryError
from hetmesh.tri.geometry import (
    PSLG,
    Arc,
    CurveBatch,
    Domain,
    Loop,
    Path,
    Segment,
    build_pslg,
    make_domain,
    sample_parameters,
)

SQUARE = [(0, 0), (1, 0), (1, 1), (0, 1)]
R_PLATE, C_PLATE = 39.75, (21.0, -9.75)


def power_plate() -> Domain:
    return make_domain(Loop((Segment((0, 0), (42, 0)), Segment((42, 0), (42, 24)),
                             Arc.through((42, 24), (21, 30), (0, 24)),
                             Segment((0, 24), (0, 0))), "outer"))


def power_plate_area() -> float:
    theta = 2 * math.asin(21 / R_PLATE)
    return 42 * 24 + 0.5 * R_PLATE**2 * (theta - math.sin(theta))


def circle(c, r, name=""):
    return Loop((Arc.circle(c, r),), name)


def square(name="outer", offset=(0.0, 0.0), size=1.0):
    return Loop.polygon(np.array(SQUARE, float) * size + offset, name)


# ----------------------------------------------------------------------------- segments
def test_segment_basics():
    s = Segment((1, 1), (4, 5), name="s")
    assert s.length == 5.0
    np.testing.assert_array_equal(s.start, [1, 1])
    np.testing.assert_array_equal(s.end, [4, 5])
    np.testing.assert_allclose(s.point([0, 0.5, 1]), [[1, 1], [2.5, 3], [4, 5]])
    np.testing.assert_allclose(s.tangent([0.2, 0.9]), [[0.6, 0.8]] * 2)
    assert s.point(0.5).shape == (2,)
    p = np.array([[2.5, 3], [1 - 4, 1 + 3], [-10, -10], [20, 20]])
    np.testing.assert_allclose(s.project(p), [0.5, 0, 0, 1])
    np.testing.assert_allclose(s.distance(p), [0, 5, math.hypot(11, 11), math.hypot(16, 15)])
    t = s.translated((1, -1))
    assert t.p0 == (2, 0) and t.p1 == (5, 4) and t.name == "s"


def test_segment_sampling_is_uniform():
    s = Segment((0, 0), (1, 0))
    np.testing.assert_allclose(s.sample_t(0.25), [0, 0.25, 0.5, 0.75, 1])
    np.testing.assert_allclose(s.sample_t(0.3), np.linspace(0, 1, 5))  # rounded up
    np.testing.assert_allclose(s.sample_t(10.0), [0, 1])  # at least one interval
    np.testing.assert_allclose(s.sample_t(np.inf), [0, 1])


# ----------------------------------------------------------------------------- arcs
def test_full_circle():
    c = Arc.circle((1, 2), 3)
    assert c.is_full and c.ccw
    assert c.length == pytest.approx(6 * math.pi)
    np.testing.assert_allclose(c.start, c.end, atol=1e-14)
    np.testing.assert_allclose(c.point([0, 0.25, 0.5]), [[4, 2], [1, 5], [-2, 2]], atol=1e-14)
    np.testing.assert_allclose(c.tangent(0), [0, 1], atol=1e-15)
    p = np.array([[1, 7], [1, 2.5], [-1, 2]])
    np.testing.assert_allclose(c.project(p), [0.25, 0.25, 0.5])
    np.testing.assert_allclose(c.distance(p), [2, 2.5, 1])
    assert c.distance([1, 2]) == pytest.approx(3)  # the centre
    assert c.bounds == pytest.approx((-2, -1, 4, 5))


def test_clockwise_arc():
    a = Arc.from_center((1, 0), (0, 1), (0, 0), ccw=False)  # the long way round, 270 degrees
    assert a.sweep == pytest.approx(-1.5 * math.pi) and not a.ccw
    assert a.length == pytest.approx(1.5 * math.pi)
    np.testing.assert_allclose(a.point([0, 1 / 3, 2 / 3, 1]), [[1, 0], [0, -1], [-1, 0], [0, 1]],
                               atol=1e-14)
    np.testing.assert_allclose(a.tangent(0), [0, -1], atol=1e-15)
    ang = np.array([-math.pi / 2, math.pi / 6, math.pi / 3])  # inside, near start, near end
    p = 2 * np.c_[np.cos(ang), np.sin(ang)]
    np.testing.assert_allclose(a.project(p), [1 / 3, 0, 1])
    np.testing.assert_allclose(a.distance(p), [1, math.dist(p[1], (1, 0)), math.dist(p[2], (0, 1))])
    assert a.bounds == pytest.approx((-1, -1, 1, 1))
    short = Arc.from_center((1, 0), (0, 1), (0, 0))
    assert short.sweep == pytest.approx(math.pi / 2)
    assert short.bounds == pytest.approx((0, 0, 1, 1))


def test_arc_constructors_agree():
    a = Arc.through((42, 24), (21, 30), (0, 24))
    b = Arc.from_center((42, 24), (0, 24), C_PLATE)
    for arc in (a, b):
        assert arc.radius == pytest.approx(R_PLATE)
        assert arc.center == pytest.approx(C_PLATE)
        np.testing.assert_allclose(arc.start, [42, 24], atol=1e-12)
        np.testing.assert_allclose(arc.end, [0, 24], atol=1e-12)
        np.testing.assert_allclose(arc.point(0.5), [21, 30], atol=1e-12)
    cw = Arc.through((0, 24), (21, 30), (42, 24))
    assert cw.sweep < 0 and cw.length == pytest.approx(a.length)
    full = Arc.from_center((1, 0), (1, 0), (0, 0))
    assert full.is_full and full.length == pytest.approx(2 * math.pi)
    big = Arc.through((1, 0), (-1, 0), (0, -1))  # 270 degrees counter-clockwise
    assert big.sweep == pytest.approx(1.5 * math.pi) and big.center == pytest.approx((0, 0))


def test_arc_end_not_on_circle():
    with pytest.raises(GeometryError) as e:
        Arc.from_center((42, 24), (0, 24.5), (21, -9.75), where="plate.toml: geometry.outer[2]")
    assert str(e.value) == ("plate.toml: geometry.outer[2]: arc end point (0, 24.5) is not on "
                            "its circle (centre (21, -9.75), radius 39.75)")


def test_arc_through_collinear_or_repeated():
    with pytest.raises(GeometryError, match="collinear"):
        Arc.through((0, 0), (1, 1), (2, 2))
    with pytest.raises(GeometryError, match="not distinct"):
        Arc.through((0, 0), (0, 0), (2, 2))


def test_arc_sampling_honours_chord_and_quarters():
    c = Arc.circle((0, 0), 1)
    assert len(c.sample_t(np.inf)) - 1 >= 4  # one interval per 90 degrees, >= 3
    tol = 1e-3
    t = c.sample_t(10.0, tol)
    p = c.point(t)
    chord = np.hypot(*np.diff(p, axis=0).T)
    assert chord.max() <= math.sqrt(8 * tol) * (1 + 1e-12)
    mid = np.hypot(*(0.5 * (p[1:] + p[:-1])).T)
    assert (1 - mid).max() <= tol * (1 + 1e-9)  # sagitta
    quarter = Arc(c.center, 1, 0, math.pi / 2)
    assert len(quarter.sample_t(np.inf)) == 2
    assert len(Arc(c.center, 1, 0, math.pi / 2 + 1e-3).sample_t(np.inf)) == 3


def test_sampling_follows_callable_size():
    def size(p):
        return 0.02 + 0.1 * p[:, 0]

    for curve in (Segment((0, 0), (3, 0)), Arc.from_center((0, 0), (3, 0), (1.5, 0))):
        t = curve.sample_t(size, 1e-2)
        assert t[0] == 0 and t[-1] == 1 and np.all(np.diff(t) > 0)
        p = curve.point(t)
        lengths = np.hypot(*np.diff(p, axis=0).T)
        h = size(0.5 * (p[1:] + p[:-1]))
        ratio = lengths / h
        assert 0.7 < ratio.min() and ratio.max() < 1.3


def test_sample_parameters_batches_many_curves():
    curves = [Segment((0, 0), (1, 0)), Arc.circle((0, 0), 1), Segment((0, 0), (0, 0.1))]
    off, t = sample_parameters(curves, lambda p: np.full(len(p), 0.1), 1e-3)
    for i, c in enumerate(curves):
        np.testing.assert_allclose(t[off[i]:off[i + 1]], c.sample_t(lambda p: np.full(len(p), 0.1),
                                                                    1e-3), atol=1e-9)
    with pytest.raises(GeometryError, match="positive"):
        sample_parameters(curves, lambda p: np.zeros(len(p)))
    with pytest.raises(GeometryError, match="positive"):
        sample_parameters(curves, -1.0)


def test_batch_distance_matches_curves():
    rng = np.random.default_rng(0)
    curves = [Segment(rng.random(2), rng.random(2)) for _ in range(40)]
    curves += [Arc.from_center((1, 0), (0, 1), (0, 0), ccw=False), Arc.circle((0.5, 0.5), 0.2)]
    p = rng.random((300, 2)) * 3 - 1
    ref = np.min([c.distance(p) for c in curves], axis=0)
    np.testing.assert_allclose(CurveBatch.from_curves(curves).distance(p), ref, atol=1e-12)


def test_batch_points_and_tangents_are_the_curves_own():
    rng = np.random.default_rng(1)
    curves = [Segment(rng.random(2), rng.random(2)) for _ in range(5)]
    curves += [Arc.from_center((1, 0), (0, 1), (0, 0), ccw=False), Arc.circle((0.5, 0.5), 0.2),
               Arc.through((0, 0), (1, 0.5), (2, 0))]
    idx = rng.integers(0, len(curves), 200)
    t = rng.random(200)
    batch = CurveBatch.from_curves(curves)
    for k, c in enumerate(curves):
        m = idx == k
        np.testing.assert_array_equal(batch.points(idx[m], t[m]), c.point(t[m]))
        np.testing.assert_array_equal(batch.tangents(idx[m], t[m]), c.tangent(t[m]))


# ----------------------------------------------------------------------------- domains
def test_power_plate_area_is_exact():
    d = power_plate()
    assert d.area == pytest.approx(power_plate_area(), rel=1e-13)
    assert d.polygon(1e-5).area == pytest.approx(d.area, rel=1e-6)
    assert d.bounds == pytest.approx((0, 0, 42, 30), abs=1e-12)
    assert d.diameter == pytest.approx(math.hypot(42, 30))
    np.testing.assert_allclose(d.corners, [[0, 0], [42, 0], [42, 24], [0, 24]])
    assert d.contains([[21, 29.9], [21, 30.1], [1, 1], [-1, 1]]).tolist() == [True, False,
                                                                              True, False]


def test_annulus_and_interface():
    d = make_domain(circle((0, 0), 38, "B"), holes=[circle((0, 0), 8, "C")],
                    interfaces=[Path((Arc.circle((0, 0), 28),), "A")])
    assert d.area == pytest.approx(math.pi * (38**2 - 8**2), rel=1e-13)
    assert [(c.kind, c.marker, c.name, c.owner) for c in d.curves] == [
        ("outer", 1, "B[0]", "B"), ("hole", 2, "C[0]", "C"), ("interface", 3, "A[0]", "A")]
    p = np.array([[0, 0], [10, 0], [30, 0], [0, -37]])
    assert d.contains(p).tolist() == [False, True, True, True]
    np.testing.assert_allclose(d.distance_to_boundary(p), [8, 2, 2, 1])
    np.testing.assert_allclose(d.distance_to_boundary(p, interfaces=False), [8, 2, 8, 1])
    # the same annulus as two half-circle arcs per loop, clockwise hole
    two = Loop((Arc.from_center((38, 0), (-38, 0), (0, 0)),
                Arc.from_center((-38, 0), (38, 0), (0, 0))))
    hole = Loop((Arc.circle((0, 0), 8, ccw=False),))
    assert make_domain(two, [hole]).area == pytest.approx(d.area, rel=1e-13)


def test_curve_names_and_markers():
    d = make_domain([Segment((0, 0), (1, 0), "bottom"), Segment((1, 0), (1, 1)),
                     Segment((1, 1), (0, 1)), Segment((0, 1), (0, 0))],
                    holes=[[Arc.circle((0.5, 0.5), 0.1)]], points={"p": (0.2, 0.2)})
    assert [c.name for c in d.curves] == ["bottom", "outer[1]", "outer[2]", "outer[3]",
                                          "hole[0][0]"]
    assert [c.marker for c in d.curves] == [1, 2, 3, 4, 5]
    assert d.corners.tolist()[-1] == [0.2, 0.2]


def test_offset_square_validates():
    d = make_domain(square(offset=(1e9, 1e9)), holes=[circle((1e9 + 0.5, 1e9 + 0.5), 0.25)],
                    interfaces=[Path.polyline([(1e9 + 0.1, 1e9 + 0.1), (1e9 + 0.2, 1e9 + 0.9)])],
                    points={"p": (1e9 + 0.9, 1e9 + 0.9)})
    assert d.area == pytest.approx(1 - math.pi / 16, rel=1e-6)
    assert make_domain(square(offset=(1e9, 1e9))).area == 1.0
    assert d.contains([[1e9 + 0.1, 1e9 + 0.5], [1e9 + 0.5, 1e9 + 0.5]]).tolist() == [True, False]
    g = build_pslg(d, 0.05, 1e-4)
    assert np.abs(d.distance_to_boundary(g.vertices[g.vertex_curve >= 0])).max() < 1e-6


def test_offset_power_plate_validates():
    d = power_plate()
    far = make_domain(d.outer.translated((1e9, -1e9)))
    assert far.area == pytest.approx(d.area, rel=1e-9)
    np.testing.assert_array_equal(far.corners, d.corners + [1e9, -1e9])
    g = build_pslg(far, 1.0, 1e-3)
    _check_pslg(far, g)


def test_translated_domain():
    d = power_plate()
    m = d.translated((100, -5))
    assert m.area == pytest.approx(d.area, rel=1e-12)
    assert m.bounds == pytest.approx((100, -5, 142, 25))
    assert m.contains([[121, 24]]).tolist() == [True]


BAD = {
    "too few vertices": (lambda: make_domain(Loop((Segment((0, 0), (1, 0)),
                                                   Segment((1, 0), (0, 0))), "outer")),
                         ["outer", "at least 3 vertices"]),
    "polygon too few": (lambda: Loop.polygon([(0, 0), (1, 0)], "plate"),
                        ["plate", "at least 3 vertices"]),
    "not closed": (lambda: make_domain(Loop((Segment((0, 0), (1, 0)), Segment((1, 0), (1, 2)),
                                             Segment((1, 2), (0, 1))), "outer")),
                   ["outer: curve 0 starts at (0, 0) but curve 2 ends at (0, 1)"]),
    "gap": (lambda: make_domain(Loop((Segment((0, 0), (1, 0)), Segment((1, 0), (1, 2.5)),
                                      Segment((1, 2), (0, 0))), "outer")),
            ["outer: curve 2 starts at (1, 2) but curve 1 ends at (1, 2.5)"]),
    "zero-length": (lambda: make_domain(Loop((Segment((0, 0), (1, 0)), Segment((1, 0), (1, 0)),
                                              Segment((1, 0), (1, 1)),
                                              Segment((1, 1), (0, 0))), "outer")),
                    ["outer: curve 1", "zero-length", "(1, 0)"]),
    "duplicate points": (lambda: Loop.polygon([(0, 0), (1, 0), (1, 0), (0, 1)], "outer"),
                         ["outer", "duplicate consecutive points (1, 0)"]),
    "nan": (lambda: make_domain(Loop.polygon([(0, 0), (1, 0), (1, 1)], "outer"),
                                points={"p": (math.nan, 0.5)}), ["point 'p'", "non-finite"]),
    "nan curve": (lambda: make_domain(Loop((Segment((0, 0), (math.inf, 0)),
                                            Segment((math.inf, 0), (0, 1)),
                                            Segment((0, 1), (0, 0))), "outer")),
                  ["outer: curve 0", "non-finite", "inf"]),
    "nan vertex": (lambda: Loop.polygon([(0, 0), (1, math.nan), (1, 1)], "outer"),
                   ["outer", "vertex 1", "non-finite"]),
    "self-intersection": (lambda: make_domain(Loop.polygon([(0, 0), (1, 0), (0, 1), (1, 1)],
                                                           "outer")),
                          ["outer", "intersects itself", "(0.5, 0.5)"]),
    "no area": (lambda: make_domain(Loop.polygon([(0, 0), (1, 0), (0.5, 1e-12)], "outer")),
                ["outer", "no area"]),
    "arcs doubled back": (lambda: make_domain(Loop((Arc.through((0, 0), (1, 1), (2, 0)),
                                                    Arc.through((2, 0), (1, 1), (0, 0))),
                                                   "outer")), ["outer", "intersects itself"]),
    "hole crosses": (lambda: make_domain(square(), [square("h", (0.5, 0.5))]),
                     ["h", "not strictly inside outer"]),
    "hole touches": (lambda: make_domain(square(), [circle((0.5, 0.25), 0.25, "h")]),
                     ["h", "not strictly inside outer", (0.5, 0)]),
    "hole outside": (lambda: make_domain(square(), [circle((3, 3), 0.25, "h")]),
                     ["h", "not strictly inside", "outside"]),
    "tangent holes": (lambda: make_domain(square(), [circle((0.3, 0.5), 0.1, "a"),
                                                     circle((0.3 + 0.2 * math.cos(1), 0.5
                                                             + 0.2 * math.sin(1)), 0.1, "b")]),
                      ["a and b overlap or touch", (0.3 + 0.1 * math.cos(1),
                                                    0.5 + 0.1 * math.sin(1))]),
    "interface tangent to hole": (lambda: make_domain(square(), [circle((0.5, 0.5), 0.2, "h")],
                                                      [Path.polyline([(0.1, 0.3), (0.9, 0.3)],
                                                                     "i")]),
                                  ["i", "h", (0.5, 0.3)]),
    "holes overlap": (lambda: make_domain(square(), [circle((0.3, 0.5), 0.15, "a"),
                                                     circle((0.5, 0.5), 0.15, "b")]),
                      ["a and b overlap"]),
    "holes touch": (lambda: make_domain(square(), [circle((0.3, 0.5), 0.1, "a"),
                                                   circle((0.5, 0.5), 0.1, "b")]),
                    ["a and b overlap or touch", (0.4, 0.5)]),
    "hole in hole": (lambda: make_domain(square(), [circle((0.5, 0.5), 0.3, "a"),
                                                    circle((0.5, 0.5), 0.1, "b")]),
                     ["a and b overlap"]),
    "interface leaves": (lambda: make_domain(square(), interfaces=[
        Path.polyline([(0.5, 0.5), (1.5, 0.5)], "i")]), ["i", "boundary outer", "(1, 0.5)"]),
    "interface touches": (lambda: make_domain(square(), interfaces=[
        Path.polyline([(0.5, 0.5), (1, 0.5)], "i")]), ["i", "touches", "(1, 0.5)"]),
    "interface outside": (lambda: make_domain(square(), interfaces=[
        Path.polyline([(1.5, 0.5), (1.5, 0.7)], "i")]), ["i", "outside the domain"]),
    "interface in hole": (lambda: make_domain(square(), [circle((0.5, 0.5), 0.2, "h")],
                                              [Path.polyline([(0.1, 0.5), (0.5, 0.5)], "i")]),
                          ["i", "h"]),
    "interface touches hole": (lambda: make_domain(square(), [circle((0.5, 0.5), 0.2, "h")],
                                                   [Path.polyline([(0.1, 0.5), (0.3, 0.5)],
                                                                  "i")]),
                               ["i", "h", "(0.3, 0.5)"]),
    "interfaces cross": (lambda: make_domain(square(), interfaces=[
        Path.polyline([(0.2, 0.2), (0.8, 0.8)], "i"),
        Path.polyline([(0.2, 0.8), (0.8, 0.2)], "j")]), ["i and j cross", "(0.5, 0.5)"]),
    "interfaces T": (lambda: make_domain(square(), interfaces=[
        Path.polyline([(0.2, 0.2), (0.8, 0.8)], "i"),
        Path.polyline([(0.5, 0.5), (0.8, 0.2)], "j")]), ["i and j", "(0.5, 0.5)"]),
    "interface self": (lambda: make_domain(square(), interfaces=[
        Path.polyline([(0.2, 0.2), (0.8, 0.8), (0.8, 0.2), (0.2, 0.8)], "i")]),
        ["i", "intersects itself", "(0.5, 0.5)"]),
    "point outside": (lambda: make_domain(square(), points={"p": (1.5, 0.5)}),
                      ["point 'p' at (1.5, 0.5)", "not inside"]),
    "point on boundary": (lambda: make_domain(square(), points={"p": (1, 0.5)}),
                          ["point 'p' at (1, 0.5)", "not inside"]),
    "point in hole": (lambda: make_domain(square(), [circle((0.5, 0.5), 0.2)],
                                          points={"p": (0.5, 0.5)}), ["point 'p'", "not inside"]),
    "point on interface": (lambda: make_domain(square(), interfaces=[
        Path.polyline([(0.2, 0.2), (0.8, 0.8)], "i")], points={"p": (0.5, 0.5)}),
        ["point 'p' at (0.5, 0.5)", "lies on i"]),
    "duplicate names": (lambda: make_domain(square("a"), [circle((0.5, 0.5), 0.2, "a")]),
                        ["'a'"]),
    "arc radius": (lambda: make_domain(Loop((Arc((0, 0), -1, 0, 2 * math.pi),), "o")),
                   ["o: curve 0", "radius"]),
    "arc sweep": (lambda: make_domain(Loop((Arc((0, 0), 1, 0, 3 * math.pi),), "o")),
                  ["o: curve 0", "540 degrees"]),
}


@pytest.mark.parametrize("case", list(BAD), ids=list(BAD))
def test_validation_errors(case):
    build, parts = BAD[case]
    with pytest.raises(GeometryError) as e:
        build()
    msg = str(e.value)
    assert "\n" not in msg
    for part in parts:
        if isinstance(part, tuple):  # an approximate location
            near = re.search(r"near \(([^,]+), ([^)]+)\)", msg)
            assert near, msg
            assert np.hypot(float(near[1]) - part[0], float(near[2]) - part[1]) < 1e-2, msg
        else:
            assert part in msg, msg


def test_where_prefixes_messages():
    with pytest.raises(GeometryError, match=r"^model\.toml: outer: curve 2 starts"):
        make_domain(Loop((Segment((0, 0), (1, 0)), Segment((1, 0), (1, 2.5)),
                          Segment((1, 2), (0, 0))), "outer"), where="model.toml")


def test_valid_special_cases():
    # one full circle, two arcs, interfaces meeting at a shared end, at an outer corner
    make_domain(circle((0, 0), 1))
    make_domain(Loop((Arc.through((0, 0), (1, 1), (2, 0)), Arc.through((2, 0), (1, -1), (0, 0)))))
    d = make_domain(square(), interfaces=[Path.polyline([(0, 0), (0.5, 0.5)], "i"),
                                          Path.polyline([(0.5, 0.5), (0.8, 0.2)], "j"),
                                          Path.polyline([(0.3, 0.6), (0.4, 0.8), (0.2, 0.8)],
                                                        "k", closed=True)],
                    points={"c": (0.5, 0.5), "q": (0.2, 0.3), "corner": (1, 1)})
    assert len(d.corners) == 4 + 2 + 3 + 1  # (0, 0), (0.5, 0.5) and (1, 1) shared
    assert d.validate() is d
    assert hash(d) == hash(pickle.loads(pickle.dumps(d))) and pickle.loads(pickle.dumps(d)) == d


# ----------------------------------------------------------------------------- PSLG
def _check_pslg(d: Domain, g: PSLG) -> None:
    tol = 1e-9 * d.diameter + 4 * np.finfo(float).eps * np.abs(d.bounds).max()  # rounding
    assert g.vertices.dtype == np.float64 and g.edges.dtype == np.int32
    assert g.edge_curve.dtype == np.int32 and g.vertex_curve.dtype == np.int32
    assert len(np.unique(g.vertices, axis=0)) == len(g.vertices)
    for i, info in enumerate(d.curves):
        e = g.edges[g.edge_curve == i]
        assert np.all(e[1:, 0] == e[:-1, 1])  # ordered chain
        v = g.vertices[g.curve_vertices(i)]
        assert info.curve.distance(v).max() < tol
    slide = g.vertex_curve >= 0
    for i, info in enumerate(d.curves):
        sel = g.vertex_curve == i
        np.testing.assert_allclose(info.curve.point(g.vertex_t[sel]), g.vertices[sel], atol=tol)
    assert np.all(np.isnan(g.vertex_t[~slide])) and np.all((g.vertex_t[slide] > 0)
                                                           & (g.vertex_t[slide] < 1))
    # loops: every vertex has degree 2 within its owner, and the chain closes
    for owner in {c.owner for c in d.curves if c.kind != "interface"}:
        ids = [i for i, c in enumerate(d.curves) if c.owner == owner]
        e = g.edges[np.isin(g.edge_curve, ids)]
        deg = np.bincount(e.ravel(), minlength=len(g.vertices))
        assert set(deg[deg > 0].tolist()) == {2}
        assert e[0, 0] == e[-1, 1]


def test_pslg_power_plate():
    d = power_plate()
    g = build_pslg(d, 1.0, 1e-3)
    _check_pslg(d, g)
    assert g.vertex_curve[:4].tolist() == [-1] * 4
    np.testing.assert_array_equal(g.vertices[:4], [[0, 0], [42, 0], [42, 24], [0, 24]])
    arc = d.curves[2].curve
    v = g.vertices[g.curve_vertices(2)]
    mid = 0.5 * (v[1:] + v[:-1])
    sagitta = arc.radius - np.hypot(*(mid - arc.center).T)
    assert sagitta.max() <= 1e-3 * (1 + 1e-9)
    lengths = np.hypot(*np.diff(g.vertices[g.edges], axis=1)[:, 0].T)
    assert lengths.max() <= 1.0 + 1e-12 and lengths.min() > 0.5


def test_pslg_follows_callable_size():
    d = make_domain(circle((0, 0), 38), [circle((0, 0), 8)],
                    [Path((Arc.circle((0, 0), 28),), "A")], {"p": (0, 20)})

    def size(p):
        return 0.2 + 0.05 * np.hypot(p[:, 0], p[:, 1]) + 0.02 * p[:, 0]

    g = build_pslg(d, size, 1.0)
    _check_pslg(d, g)
    e = g.vertices[g.edges]
    ratio = np.hypot(*(e[:, 1] - e[:, 0]).T) / size(e.mean(axis=1))
    assert 0.7 < ratio.min() and ratio.max() < 1.3
    p = np.flatnonzero((g.vertices == [0, 20]).all(axis=1))
    assert len(p) == 1 and g.vertex_curve[p[0]] == -1 and not np.isin(p[0], g.edges)
    assert np.bincount(g.edge_curve).tolist() == [len(g.curve_vertices(i)) - 1 for i in range(3)]


def test_pslg_shares_interface_junctions():
    d = make_domain(square(), interfaces=[Path.polyline([(0, 0), (0.5, 0.5)], "i"),
                                          Path.polyline([(0.5, 0.5), (0.8, 0.2)], "j")],
                    points={"c": (0.5, 0.5)})
    g = build_pslg(d, 0.1)
    _check_pslg(d, g)
    centre = np.flatnonzero((g.vertices == [0.5, 0.5]).all(axis=1))
    corner = np.flatnonzero((g.vertices == [0, 0]).all(axis=1))
    assert len(centre) == 1 and len(corner) == 1
    assert np.sum(g.edges == centre[0]) == 2 and np.sum(g.edges == corner[0]) == 3


def test_pslg_is_immutable_and_many_segments_fast_enough():
    n = 20_000
    th = np.linspace(0, 2 * np.pi, n, endpoint=False)
    r = 1 + 0.1 * np.cos(7 * th)
    d = make_domain(Loop.polygon(np.c_[r * np.cos(th), r * np.sin(th)]))
    g = build_pslg(d, lambda p: np.full(len(p), 1e-4))
    assert len(g.edges) > 3 * n
    with pytest.raises(ValueError):
        g.vertices[0, 0] = 1.0


def test_sample_parameters_nearest_rounds_the_count_to_the_nearest():
    seg = [Segment((0, 0), (1, 0))]
    assert len(sample_parameters(seg, 0.3)[1]) == 5  # ceil(3.33) = 4 intervals of 0.25
    assert len(sample_parameters(seg, 0.3, nearest=True)[1]) == 4  # 3 intervals of 0.33
    grow = lambda p: 0.3 + 0.0 * p[:, 0]  # noqa: E731
    assert len(sample_parameters(seg, grow, nearest=True)[1]) == 4
    assert len(sample_parameters(seg, 0.4, nearest=True)[1]) == 4  # 2.5 rounds up


@pytest.mark.parametrize("tol", [1e-3, 1.7e-3, 2.3e-3, 3e-3])
def test_sample_parameters_nearest_keeps_the_chord_tolerance(tol):
    # the size grows from 0.02 to 0.4 along a half circle: the chord cap (0.09 at 1e-3)
    # sets the steps on one side; rounding the count down there would stretch them beyond it
    arc = Arc.from_center((1, 0), (-1, 0), (0, 0))
    size = lambda p: 0.21 - 0.19 * p[:, 0]  # noqa: E731
    for s in (size, 0.5):
        t = sample_parameters([arc], s, tol, nearest=True)[1]
        theta = np.pi * t
        sagitta = 1.0 - np.cos(0.5 * np.diff(theta))
        assert sagitta.max() <= tol
        assert len(t) <= len(sample_parameters([arc], s, tol)[1])
