"""Robustness: seeded random models (hetmesh.testing) meshed and checked independently.

The generator must be deterministic and make only valid models; a handful of hard models
(steep fronts, p < 1, S-FGM plateaus, kinks, small holes, interfaces) must mesh and pass
``independent_check``. The whole suite runs in ``benchmarks/bench_robust.py``; a larger
sample is marked slow.
"""

from __future__ import annotations

import dataclasses
import math
from collections import Counter

import numpy as np
import pytest

import hetmesh
from hetmesh.density import estimate_elements
from hetmesh.testing import FAMILIES, RandomModel, independent_check, random_model, robust_suite


@pytest.fixture(scope="module")
def suite():
    return robust_suite()


def budget(model, threshold):
    """The benchmark's element budget: 20 x the a-priori estimate, at least 100,000 (a run
    needing more has diverged; it then fails in seconds, not after minutes at 5M)."""
    est = estimate_elements(model.material, model.domain, threshold, model.domain.diameter / 8)
    return max(100_000, int(20 * est)) if math.isfinite(est) else 5_000_000


def mesh_and_check(seed, threshold=None):
    rm = random_model(seed)
    model = rm.load()
    t = rm.thresholds[-1] if threshold is None else threshold
    result = hetmesh.generate(model, t, max_elements=budget(model, t))
    assert independent_check(result, model, t) == []


# ----------------------------------------------------------------------------- generator
def test_generator_is_deterministic():
    for seed in (0, 7, 23):
        a, b = random_model(seed), random_model(seed)
        assert a == b and a.toml == b.toml
    assert random_model(1).toml != random_model(8).toml  # same family, other seed


def test_suite_covers_every_family_and_feature(suite):
    assert len(suite) == 48
    assert [m.seed for m in suite] == list(range(48))
    counts = Counter(m.family for m in suite)
    assert set(counts) == set(FAMILIES) and min(counts.values()) >= 4
    tags = Counter(t for m in suite for t in m.kind)
    for tag in ("star", "arcs", "ushape", "lshape", "holes", "small-holes", "interface", "far",
                "steep", "p<1", "plateaus"):
        assert tags[tag] >= 1, tag
    assert any(t.endswith("kink") or t == "ridge" for t in tags)
    for m in suite:
        assert isinstance(m, RandomModel) and m.name == f"random-{m.seed:04d}-{m.family}"
        assert 1 <= len(m.thresholds) <= 2
        assert all(0.02 <= t <= 0.2 for t in m.thresholds)
        assert list(m.thresholds) == sorted(m.thresholds, reverse=True)


def test_every_suite_model_loads(suite):
    for m in suite:
        model = m.load()
        assert model.name == m.name
        x0, y0, x1, y1 = model.domain.bounds
        X, Y = np.meshgrid(np.linspace(x0, x1, 41), np.linspace(y0, y1, 41))
        c = model.material.composition(np.column_stack([X.ravel(), Y.ravel()]))
        # the composition stays in [0, 1] over the whole bounding box, not only the domain
        assert np.isfinite(c).all() and c.min() >= -1e-9 and c.max() <= 1 + 1e-9, m.name


def test_bad_seed():
    with pytest.raises(ValueError):
        random_model(-1)


# ----------------------------------------------------------------------------- the check
@pytest.fixture(scope="module")
def square_result():
    model = hetmesh.load_model(hetmesh.example_path("plate_with_holes"))
    return model, hetmesh.generate(model, 0.1)


def test_check_accepts_a_good_mesh(square_result):
    model, result = square_result
    assert independent_check(result, model, 0.1) == []


def test_check_finds_broken_meshes(square_result):
    model, result = square_result
    mesh = result.mesh
    # a threshold the mesh does not meet
    assert any("delta_max" in p for p in independent_check(result, model, 0.01))
    # a missing triangle: a hole in the mesh, a wrong area
    cut = dataclasses.replace(mesh, cells=mesh.cells[1:], regions=None,
                              cell_data={})
    probs = independent_check(dataclasses.replace(result, mesh=cut), model, 0.1)
    assert any("boundary" in p for p in probs) and any("area" in p for p in probs)
    # an interior node moved off its place: compositions and angles no longer match
    P = mesh.points.copy()
    inner = np.setdiff1d(np.arange(len(P)), mesh.edges.ravel())
    P[inner[0]] += 0.3 * np.ptp(P, axis=0).min() / math.sqrt(len(P))
    moved = dataclasses.replace(mesh, points=P)
    probs = independent_check(dataclasses.replace(result, mesh=moved), model, 0.1)
    assert any("point data" in p for p in probs) and any("q_min" in p for p in probs)
    # a boundary node moved off its curve
    P = mesh.points.copy()
    P[mesh.edges[0, 0]] += 1e-3 * model.domain.diameter
    probs = independent_check(dataclasses.replace(result, mesh=dataclasses.replace(mesh, points=P)),
                              model, 0.1)
    assert any("off their curve" in p for p in probs)
    # constraint edges missing: a curve not covered, boundary edges without a curve
    fewer = dataclasses.replace(mesh, facets=mesh.facets[5:], facet_markers=mesh.facet_markers[5:])
    probs = independent_check(dataclasses.replace(result, mesh=fewer), model, 0.1)
    assert any("cover" in p for p in probs) and any("not on the outer loop" in p for p in probs)


# ----------------------------------------------------------------------------- hard models
# Each runs in a few seconds; the id names the feature. 44 (an open interface inside a domain
# with slanted edges) and 3 (an S-FGM whose where() is embedded as a curve) once drove the
# quality refinement to its element budget.
HARD = [
    pytest.param(1, 0.055, id="1-tanh-steep-small-holes"),
    pytest.param(9, 0.043, id="9-power-p<1-far"),
    pytest.param(37, 0.06, id="37-power-p<1-small-holes"),
    pytest.param(17, 0.062, id="17-sfgm-p<1-plateaus-far"),
    pytest.param(3, 0.087, id="3-sfgm-plateaus"),
    pytest.param(20, 0.022, id="20-kink-corner-small-holes"),
    pytest.param(41, 0.068, id="41-kink-line-fillet"),
    pytest.param(44, 0.19, id="44-power-interface"),
]


@pytest.mark.parametrize("seed, threshold", HARD)
def test_hard_model(seed, threshold):
    assert threshold in random_model(seed).thresholds
    mesh_and_check(seed, threshold)


@pytest.mark.slow
@pytest.mark.parametrize("seed", range(16))
def test_random_models(seed):
    for t in random_model(seed).thresholds:
        mesh_and_check(seed, t)
