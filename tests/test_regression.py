"""Regression numbers with explicit tolerances (the targets live in benchmarks/)."""

from __future__ import annotations

import pytest

import hetmesh
from hetmesh.density import n_iso

#: the economy row spacing: the fewest elements, most of them just under delta_0
ECONOMY = 0.985


@pytest.mark.parametrize("threshold, elements", [(0.1, 378), (0.05, 1385), (0.03, 3719)])
def test_power_plate_counts_and_quality_economy(threshold, elements):
    model = hetmesh.load_model(hetmesh.example_path("power_plate"))
    s = hetmesh.generate(model, threshold, method="layers", row_spacing=ECONOMY).stats
    assert s.n_elements == pytest.approx(elements, rel=0.10)
    assert s.delta_max < threshold
    assert s.q_min >= 0.58
    assert s.q_avg >= 0.925
    assert s.delta_avg / threshold >= 0.85
    assert s.angle_min >= 30.0


# at 0.1 the auto comparison keeps the springs-dense start since the springs starts' curves
# follow their relaxed interior (626 elements of q_avg 0.985; before, the springs start's
# 569 of 0.980)
@pytest.mark.parametrize("threshold, elements, q_avg", [(0.1, 600, 0.965), (0.05, 1854, 0.977),
                                                        (0.03, 5049, 0.984)])
def test_power_plate_counts_and_quality_default(threshold, elements, q_avg):
    """The default row spacing (0.85 delta_0) buys element quality with elements: q_avg at
    least Gmsh's minus 0.005 on this plate (Gmsh: 0.975, 0.983, 0.985 with 628, 3,099 and
    8,924 elements; docs/reproduce.md)."""
    model = hetmesh.load_model(hetmesh.example_path("power_plate"))
    s = hetmesh.generate(model, threshold).stats
    assert s.n_elements == pytest.approx(elements, rel=0.10)
    assert s.delta_max < threshold
    assert s.q_min >= 0.65
    assert s.q_avg >= q_avg
    assert s.angle_min >= 30.0


@pytest.mark.parametrize("threshold", [0.05, 0.03])
def test_unit_square_close_to_the_limit(threshold):
    model = hetmesh.load_model(hetmesh.example_path("unit_square"))
    s = hetmesh.generate(model, threshold, method="layers", row_spacing=ECONOMY).stats
    assert s.n_elements <= 0.85 * n_iso(model.material, model.domain, threshold)
    s = hetmesh.generate(model, threshold).stats
    assert s.n_elements <= 1.15 * n_iso(model.material, model.domain, threshold)
    assert s.q_avg >= 0.975


def test_n_iso_matches_the_reference_counts():
    model = hetmesh.load_model(hetmesh.example_path("unit_square"))
    for thr, ref in [(0.05, 1232), (0.03, 3421), (0.01, 30792)]:
        assert n_iso(model.material, model.domain, thr) == pytest.approx(ref, rel=2e-3)


def test_paper_cvt_method_is_kept_and_beaten():
    model = hetmesh.load_model(hetmesh.example_path("power_plate"))
    cvt = hetmesh.generate(model, 0.05, method="cvt").stats
    layers = hetmesh.generate(model, 0.05, row_spacing=ECONOMY).stats
    default = hetmesh.generate(model, 0.05).stats
    assert cvt.delta_max < 0.05 and layers.delta_max < 0.05
    assert layers.n_elements < 0.7 * cvt.n_elements
    assert default.q_avg > cvt.q_avg + 0.01
