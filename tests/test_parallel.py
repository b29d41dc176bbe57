"""Threaded evaluation of material fields: the same numbers as one block after another."""

from pathlib import Path

import numpy as np
import pytest

import hetmesh
from hetmesh import parallel
from hetmesh.material import AnalyticField, CallableField
from hetmesh.material.field import thread_safe
from hetmesh.metrics import delta_dense
from hetmesh.refinement import composition_at
from hetmesh.tri.frame import local_field, local_frame

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


class _Serial:
    """The same field without the thread-safe flag: evaluated block after block."""

    def __init__(self, base):
        self.base, self.constituents = base, base.constituents

    def composition(self, points, **kw):
        return self.base.composition(points, **kw)

    def gradient(self, points, **kw):
        return self.base.gradient(points, **kw)


@pytest.fixture
def field():
    return AnalyticField({"metal": "0.5 * (1 + tanh((x - 0.3) / 0.05)) * exp(-y**2)"},
                         ["ceramic", "metal"])


def test_which_fields_are_thread_safe(field):
    assert thread_safe(field)
    assert thread_safe(local_field(field, local_frame((0.0, 0.0, 1.0, 1.0))))
    assert not thread_safe(CallableField(lambda x, y: x, ["a", "b"]))
    assert not thread_safe(local_field(CallableField(lambda x, y: x, ["a", "b"]),
                                       local_frame((0.0, 0.0, 1.0, 1.0))))
    assert not thread_safe(_Serial(field))


def test_threaded_compositions_are_the_serial_ones(field, monkeypatch):
    monkeypatch.setenv("HETMESH_THREADS", "2")
    assert parallel.threads() == 2
    pts = np.random.default_rng(3).random((2 * parallel.BLOCK + 1000, 2))
    threaded = composition_at(field, pts)        # three blocks, in two threads
    serial = composition_at(_Serial(field), pts)  # the same blocks, one after the other
    assert threaded.shape == (len(pts), 2)
    assert np.array_equal(threaded, serial)


def test_threaded_dense_delta_is_the_serial_one(field, monkeypatch):
    monkeypatch.setenv("HETMESH_THREADS", "2")
    rng = np.random.default_rng(5)
    P = rng.random((400, 2))
    T = np.sort(rng.integers(0, len(P), (3000, 3)), axis=1)
    T = T[(T[:, 0] != T[:, 1]) & (T[:, 1] != T[:, 2])]
    threaded = delta_dense(field, P, T, chunk=256)
    serial = delta_dense(_Serial(field), P, T, chunk=256)
    whole = delta_dense(field, P, T)              # one chunk
    assert (threaded > 0).all()
    assert np.array_equal(threaded, serial)
    assert np.array_equal(threaded, whole)


def test_feature_tree_fields_evaluate_alike_in_threads(monkeypatch):
    """The feature tree's one-entry cache is per thread: blocks evaluated at once neither
    evict each other's entries nor read them."""
    monkeypatch.setenv("HETMESH_THREADS", "2")
    model = hetmesh.load_model(EXAMPLES / "fgm_plate.toml")
    field = model.material
    assert thread_safe(field)
    x0, y0, x1, y1 = model.domain.bounds
    u = np.random.default_rng(7).random((parallel.BLOCK + 5000, 2))
    pts = np.column_stack([x0 + (x1 - x0) * u[:, 0], y0 + (y1 - y0) * u[:, 1]])
    threaded = composition_at(field, pts)
    serial = composition_at(_Serial(field), pts)
    assert np.array_equal(threaded, serial)
    assert np.array_equal(field.gradient(pts[:100]), _Serial(field).gradient(pts[:100]))
