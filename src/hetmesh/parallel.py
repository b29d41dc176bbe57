"""Deterministic parallel work over fixed blocks of an index range (threads).

numpy releases the GIL in its large elementwise operations and gathers, and the constrained
Delaunay kernel releases it too, so threads over independent blocks use the cores of the
machine. The results never depend on the number of threads: the blocks are fixed by the
length of the range and :data:`BLOCK` alone, every block is computed exactly as it would be
alone, and the results are put together in block order. Only elementwise work (and unions
of masks) is split this way; sums that depend on their order stay in one piece.

``HETMESH_THREADS=1`` in the environment runs everything in the calling thread.
"""

from __future__ import annotations

import os
import threading
from concurrent.futures import ThreadPoolExecutor

import numpy as np

__all__ = ["BLOCK", "blocks", "block_map", "block_concat", "threads"]

#: items per block: large enough that numpy runs without the GIL most of the time, small
#: enough that a block's temporaries stay in the cache's reach and two blocks fit in memory
BLOCK = 1 << 18

_pool: ThreadPoolExecutor | None = None
_pool_size = 0
_pool_lock = threading.Lock()
_inside = threading.local()


def threads() -> int:
    """Worker threads: ``HETMESH_THREADS`` if set, else the CPUs this process may use (at
    most 8)."""
    env = os.environ.get("HETMESH_THREADS", "").strip()
    if env:
        try:
            return max(1, int(env))
        except ValueError:
            pass
    try:
        n = len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        n = os.cpu_count() or 1
    return max(1, min(n, 8))


def blocks(n: int, size: int = BLOCK) -> list[slice]:
    """The blocks of ``range(n)``: slices of ``size`` items (the last one shorter)."""
    return [slice(a, min(a + size, n)) for a in range(0, n, size)]


def _executor() -> ThreadPoolExecutor | None:
    global _pool, _pool_size
    k = threads()
    if k < 2:
        return None
    with _pool_lock:
        if _pool is None or _pool_size != k:
            _pool = ThreadPoolExecutor(max_workers=k, thread_name_prefix="hetmesh")
            _pool_size = k
        return _pool


def _run(fn, s):
    _inside.active = True
    try:
        return fn(s)
    finally:
        _inside.active = False


def block_map(fn, n: int, size: int = BLOCK, serial: bool = False) -> list:
    """``[fn(s) for s in blocks(n, size)]``, the blocks spread over threads when there are
    several (and this is not already a worker thread); with ``serial``, one after the other
    in the calling thread (for work that is not safe in threads, such as evaluating a
    material field that is not :func:`~hetmesh.material.field.thread_safe`: blocks still
    keep the temporaries small)."""
    parts = blocks(n, size)
    ex = (None if serial or len(parts) < 2 or getattr(_inside, "active", False)
          else _executor())
    if ex is None:
        return [fn(s) for s in parts]
    return list(ex.map(lambda s: _run(fn, s), parts))


def block_concat(fn, n: int, size: int = BLOCK, axis: int = 0, serial: bool = False):
    """:func:`block_map`, the block results (arrays, or tuples of arrays) concatenated."""
    parts = block_map(fn, n, size, serial)
    if len(parts) == 1:
        return parts[0]
    if not parts:
        return fn(slice(0, 0))
    if isinstance(parts[0], tuple):
        return tuple(np.concatenate([p[i] for p in parts], axis=axis)
                     for i in range(len(parts[0])))
    return np.concatenate(parts, axis=axis)
