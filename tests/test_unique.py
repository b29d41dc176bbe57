"""hetmesh.topology.unique: numpy.unique's results and shapes, by sorting (NumPy 2.4's hashing
is 20-80 x slower on integer keys)."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from hetmesh.topology import unique


def _cases():
    rng = np.random.default_rng(1)
    for trial in range(120):
        kind = trial % 5
        if kind == 0:
            yield rng.integers(0, 7, rng.integers(0, 40))
        elif kind == 1:
            yield rng.integers(-3, 4, (rng.integers(0, 6), rng.integers(1, 5)))
        elif kind == 2:
            yield rng.integers(0, 4, (rng.integers(0, 30), 2)).astype(np.int32)
        elif kind == 3:
            yield rng.integers(0, 2, rng.integers(0, 20)).astype(bool)
        else:
            yield rng.random(rng.integers(0, 10)).round(1)  # floats: numpy's own


@pytest.mark.parametrize("a", list(_cases()))
def test_same_as_numpy(a):
    for ri, rv, rc in itertools.product([False, True], repeat=3):
        for axis in ([None, 0] if a.ndim == 2 else [None]):
            want = np.unique(a, return_index=ri, return_inverse=rv, return_counts=rc, axis=axis)
            got = unique(a, return_index=ri, return_inverse=rv, return_counts=rc, axis=axis)
            want = want if isinstance(want, tuple) else (want,)
            got = got if isinstance(got, tuple) else (got,)
            assert len(got) == len(want)
            for w, g in zip(want, got):
                assert g.shape == w.shape and g.dtype == w.dtype
                np.testing.assert_array_equal(g, w)
