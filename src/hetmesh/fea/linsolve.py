"""Symmetric positive definite solves for the FEA: sparse direct for small systems, conjugate
gradients preconditioned by smoothed-aggregation algebraic multigrid (pyamg) for large ones.

Fixed values are imposed by symmetric elimination that keeps the matrix's size and block
structure: the rows and columns of the fixed unknowns are zeroed, their diagonal entries kept,
and the right-hand side corrected, so ``x[fixed] = x0[fixed]`` exactly. A 3-D elasticity
matrix stays a block (BSR, 3 x 3) matrix, which lets pyamg aggregate whole nodes; its
near-nullspace are the six rigid-body modes (:func:`rigid_modes`).

>>> import scipy.sparse as sp
>>> A = sp.diags([-1.0, 2.0, -1.0], [-1, 0, 1], shape=(5, 5), format="csr")
>>> fixed = np.array([True, False, False, False, True])
>>> x0 = np.array([1.0, 0, 0, 0, 0])
>>> x, info = solve_spd(A, np.zeros(5), fixed, x0, what="test")
>>> np.round(x, 6).tolist()
[1.0, 0.75, 0.5, 0.25, 0.0]
"""

from __future__ import annotations

import logging
import time

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import cg, splu

from ..errors import FEAError
from .config3d import SOLVERS  # "auto": direct up to DIRECT_MAX unknowns, else "amg"

__all__ = ["solve_spd", "rigid_modes", "eliminate", "SOLVERS", "DIRECT_MAX", "blas_threads"]

log = logging.getLogger(__name__)

#: largest system ``auto`` factorises directly (3-D fill-in makes larger ones slow)
DIRECT_MAX = 10_000


def blas_threads(n: int = 1):
    """A context limiting BLAS to ``n`` threads (threadpoolctl).

    The FEA's vector operations (CG's dot products and norms, the multigrid's small dense
    products) are memory bound, and multi-threaded OpenBLAS spin-waits on them whenever the
    cores are busy: on this project's 2-core machine under load, a dot product of 500,000
    doubles took 21 ms with 2 threads and 0.13 ms with 1, and a 174k-unknown AMG-CG elastic
    solve 19.3 s against 8.3 s.
    """
    from threadpoolctl import threadpool_limits

    return threadpool_limits(limits=n, user_api="blas")


def rigid_modes(x: np.ndarray) -> np.ndarray:
    """The six rigid-body modes ``(3 N, 6)`` of nodes ``x`` ``(N, 3)``, dofs interleaved
    ``(x0, y0, z0, x1, ...)``: three translations and three rotations about the centroid."""
    q = np.asarray(x, dtype=np.float64)
    q = q - q.mean(axis=0)
    q = q / max(float(np.abs(q).max()), 1e-300)
    n = len(q)
    B = np.zeros((n, 3, 6))
    for a in range(3):
        B[:, a, a] = 1.0
    X, Y, Z = q.T
    B[:, 0, 3], B[:, 1, 3] = -Y, X          # about z
    B[:, 1, 4], B[:, 2, 4] = -Z, Y          # about x
    B[:, 0, 5], B[:, 2, 5] = Z, -X          # about y
    return B.reshape(3 * n, 6)


def eliminate(A: sp.spmatrix, b: np.ndarray, fixed: np.ndarray, x0: np.ndarray
              ) -> tuple[sp.spmatrix, np.ndarray]:
    """Symmetric elimination of ``x[fixed] = x0[fixed]`` (see the module docstring), done on
    the stored entries so that the sparsity pattern -- and a BSR matrix's blocks -- stay:
    a CSR or square-block BSR matrix comes back in its own format."""
    fixed = np.asarray(fixed, dtype=bool)
    if not (sp.issparse(A) and A.format in ("csr", "bsr")):
        A = sp.csr_matrix(A)
    A = A.copy()
    A.sum_duplicates()
    d = A.diagonal()
    d = np.where(d != 0, d, 1.0)
    xf = np.where(fixed, x0, 0.0)
    rhs = np.where(fixed, d * x0, b - A @ xf)
    bs = A.blocksize[0] if A.format == "bsr" else 1
    nb = A.shape[0] // bs
    brow = np.repeat(np.arange(nb), np.diff(A.indptr))
    bcol = A.indices
    data = A.data.reshape(len(bcol), bs, bs)
    f = fixed.reshape(nb, bs)
    data *= (~f[brow])[:, :, None]                    # rows of fixed unknowns
    data *= (~f[bcol])[:, None, :]                    # their columns
    diag = np.flatnonzero(brow == bcol)
    for a in range(bs):
        rows = f[brow[diag], a]
        data[diag[rows], a, a] = d[bs * brow[diag[rows]] + a]
    return A, rhs


def solve_spd(A: sp.spmatrix, b: np.ndarray, fixed: np.ndarray, x0: np.ndarray, *,
              what: str, method: str = "auto", blocksize: int = 1,
              near_nullspace: np.ndarray | None = None, rtol: float = 1e-8,
              maxiter: int = 2000) -> tuple[np.ndarray, dict]:
    """Solve ``A x = b`` with ``x[fixed] = x0[fixed]``; ``A`` symmetric positive definite once
    the fixed unknowns are removed.

    Parameters
    ----------
    A, b : the system
    fixed : (n,) bool; x0 : (n,) values at the fixed unknowns
    what : "thermal" or "elastic", for messages
    method : "auto", "direct" or "amg" (:data:`SOLVERS`)
    blocksize : unknowns per node (3 for 3-D elasticity, interleaved)
    near_nullspace : (n, k) for the multigrid (rigid-body modes), optional
    rtol : relative residual of the iterative solve
    maxiter : its iteration limit

    Returns
    -------
    x, info
        ``info``: ``method``, ``unknowns``, ``iterations``, ``residual`` (relative),
        ``setup_seconds``, ``solve_seconds``.

    Raises
    ------
    FEAError
        A singular system (direct), or an iterative solve that does not converge.
    """
    if method not in SOLVERS:
        raise FEAError(f"unknown linear solver {method!r} (expected one of: "
                       f"{', '.join(SOLVERS)})")
    n = A.shape[0]
    nfree = int(n - np.count_nonzero(fixed))
    if method == "auto":
        method = "direct" if nfree <= DIRECT_MAX else "amg"
    t0 = time.perf_counter()
    Ae, rhs = eliminate(A, b, fixed, x0)
    info = {"method": method, "unknowns": nfree}
    scale = float(np.linalg.norm(rhs)) or 1.0
    if method == "direct":
        try:
            lu = splu(Ae.tocsc(), permc_spec="MMD_AT_PLUS_A")
            t1 = time.perf_counter()
            x = lu.solve(rhs)
        except RuntimeError as exc:  # "Factor is exactly singular"
            raise FEAError(f"singular {what} system: {exc}") from None
        info["iterations"] = 0
    else:
        import pyamg

        M = Ae if (blocksize == 1 or Ae.format == "bsr") else \
            Ae.tobsr(blocksize=(blocksize, blocksize))
        B = None
        if near_nullspace is not None:
            B = np.where(np.asarray(fixed)[:, None], 0.0, near_nullspace)
        # no candidate improvement: the rigid-body modes are exact near-nullspace vectors,
        # and improving them costs more setup than it saves iterations (measured on the
        # graded cylinder, P1 and P2); the coarsest level factorised once (pyamg's default
        # 'pinv' recomputed a dense pseudo-inverse at every application, seconds each)
        # one forward sweep before and one backward after (a symmetric V-cycle, 20 % faster
        # than symmetric sweeps on both sides for a few more iterations)
        ml = pyamg.smoothed_aggregation_solver(
            M, B=B, symmetry="hermitian", max_coarse=500, improve_candidates=None,
            coarse_solver="splu",
            presmoother=("block_gauss_seidel", {"sweep": "forward"}),
            postsmoother=("block_gauss_seidel", {"sweep": "backward"}))
        pre = ml.aspreconditioner(cycle="V")
        t1 = time.perf_counter()
        count = [0]

        def step(_x):
            count[0] += 1

        start = np.where(fixed, x0, 0.0)
        x, flag = cg(Ae, rhs, x0=start, rtol=rtol, atol=0.0, maxiter=maxiter, M=pre,
                     callback=step)
        info["iterations"] = count[0]
        info["levels"] = len(ml.levels)
        if flag != 0:
            r = float(np.linalg.norm(rhs - Ae @ x)) / scale
            raise FEAError(f"the {what} system did not converge: conjugate gradients with "
                           f"multigrid stopped after {count[0]} iterations at relative "
                           f"residual {r:.2g} (is the system singular?)")
    info["setup_seconds"] = t1 - t0
    info["solve_seconds"] = time.perf_counter() - t1
    r = float(np.linalg.norm(rhs - Ae @ x)) / scale
    info["residual"] = r
    if not np.isfinite(x).all() or r > max(1e-6, 10 * rtol):
        raise FEAError(f"singular {what} system: the solution is not finite or does not "
                       f"satisfy the equations (residual {r:.2g})")
    x = np.where(fixed, x0, x)
    log.debug("%s solve: %s", what, info)
    return x, info
