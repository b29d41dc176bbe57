"""The cap on |grad f| from the composition's sampled variation (hetmesh.tri.sizecap): the size
it gives is the width over which f really varies by less than delta_0."""

from __future__ import annotations

import numpy as np

from hetmesh.tri.sizecap import CELLS, WIDTH, variation_cap


def _sqrt_x(p: np.ndarray) -> np.ndarray:
    """f = sqrt(x): |grad f| is infinite at x = 0, f stays bounded."""
    return np.sqrt(np.clip(p[:, 0], 0.0, None))


def test_size_is_a_width_over_which_f_varies_below_threshold():
    """At every probe the size delta_0 / cap (WIDTH x a power of two of cells) is the side of
    a square centred on the probe over which f varies by less than delta_0; sqrt(x)
    increases with x, so its range over a square is that over the square's x extent."""
    thr = 0.1
    cap = variation_cap(_sqrt_x, (0.0, 0.0, 1.0, 1.0), thr)
    x = np.linspace(0.0, 0.6, 61)
    h = thr / cap(np.column_stack([x, np.full_like(x, 0.5)]))
    cell = 1.0 / CELLS
    blocks = h / WIDTH / cell
    assert np.allclose(blocks, 2.0 ** np.round(np.log2(blocks)))  # whole power-of-two blocks
    lo, hi = np.clip(x - h / 2, 0.0, None), x + h / 2
    assert (np.sqrt(hi) - np.sqrt(lo) < thr).all()


def test_size_next_to_a_singular_edge_is_twice_the_quiet_block():
    """At x = 0 the quiet block is the largest whose three-block neighbourhood (from x = -b
    to 2 b) varies below delta_0, sqrt(2 b) < delta_0; the size is twice its side."""
    thr = 0.1
    cap = variation_cap(_sqrt_x, (-0.5, 0.0, 0.5, 1.0), thr)
    h = thr / cap(np.array([[1e-9, 0.5]]))[0]
    cell = 1.0 / CELLS
    b = cell * 2.0 ** np.floor(np.log2(thr ** 2 / 2 / cell))
    assert np.sqrt(2 * b) < thr <= np.sqrt(4 * b)
    assert h == WIDTH * b


def test_smooth_field_is_never_capped_below_its_gradient():
    """A linear field: the cap is at least 1.5 x its gradient everywhere."""
    g = 0.8
    cap = variation_cap(lambda p: g * p[:, 0], (0.0, 0.0, 1.0, 1.0), 0.05)
    pts = np.random.default_rng(0).random((200, 2))
    assert (cap(pts) >= 1.5 * g).all()
