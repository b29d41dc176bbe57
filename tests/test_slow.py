"""Longer invariant checks, run by CI's second step (``python -m pytest -m slow``)."""

from __future__ import annotations

import numpy as np
import pytest

import hetmesh
from conftest import EXAMPLES, check_invariants, square_domain
from hetmesh.material import CallableField

pytestmark = pytest.mark.slow


@pytest.mark.parametrize("path", EXAMPLES, ids=lambda p: p.stem)
@pytest.mark.parametrize("threshold", [0.05, 0.03])
def test_examples_finer(path, threshold):
    model = hetmesh.load_model(path)
    r = hetmesh.generate(model, threshold)
    check_invariants(r, model, threshold)


@pytest.mark.parametrize("path", EXAMPLES, ids=lambda p: p.stem)
def test_examples_dense_sampling(path):
    from hetmesh.metrics import delta_dense

    model = hetmesh.load_model(path)
    r = hetmesh.generate(model, 0.05, sampling="dense")
    check_invariants(r, model, 0.05)
    # a feature-tree element is sampled in its own subregion (the sliver between a curved
    # discontinuity and the chord that is the element's edge belongs to the neighbour)
    regions = r.mesh.cell_data.get("subregion")
    assert delta_dense(model.material, r.mesh.points, r.mesh.triangles,
                       regions=regions).max() < 0.05


@pytest.mark.parametrize("seed", range(4, 16))
def test_more_random_fields(seed):
    rng = np.random.default_rng(seed)
    kx, ky = rng.uniform(-3, 3, size=2)
    ph = rng.uniform(0, 2 * np.pi)

    def f(x, y):
        return 0.5 + 0.45 * np.sin(kx * x + ky * y + ph) * np.exp(-x)

    model = hetmesh.Model(name="random", domain=square_domain(0, 0, 2, 1),
                          material=CallableField(f, ["a", "b"]))
    thr = float(rng.uniform(0.03, 0.1))
    method = "layers" if seed % 2 else "cvt"
    r = hetmesh.generate(model, thr, method=method, seed=seed)
    check_invariants(r, model, thr)


def test_power_plate_thresholds_of_the_paper():
    model = hetmesh.load_model(hetmesh.example_path("power_plate"))
    for thr in (0.1, 0.08, 0.05, 0.03):
        r = hetmesh.generate(model, thr)
        check_invariants(r, model, thr)
        assert r.stats.q_min >= 0.5
