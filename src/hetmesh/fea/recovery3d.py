"""After the 3D solve: stresses at the quadrature points, their recovery at the vertices (an
L2 projection onto linear functions, continuous within each piece), and the values at the
probes, interpolated in the tetrahedron that holds each (:func:`hetmesh.fea.solid.solve_tets`
calls them in that order)."""

from __future__ import annotations

import logging
from typing import TYPE_CHECKING

import numpy as np
import scipy.sparse as sp

from ..errors import FEAError
from ..topology import unique
from .blocks import CHUNK, sum_into

if TYPE_CHECKING:
    from .solid import TetSpace

__all__ = ["STRESS_NAMES_3D", "stresses_3d", "von_mises_3d", "vertex_copies", "recover_3d",
           "cg_columns", "tet_boxes", "locate_tet", "p2_values", "displacement_gradients",
           "recover_stresses", "probe_values"]

log = logging.getLogger(__name__)

#: the stress components, in the column order of :attr:`SolidResult.stress`
STRESS_NAMES_3D = ("stress_xx", "stress_yy", "stress_zz", "stress_xy", "stress_yz",
                   "stress_xz")


def stresses_3d(du: np.ndarray, lam, mu, beta, dT) -> np.ndarray:
    """Stresses ``(..., 6)`` (``xx, yy, zz, xy, yz, xz``) from displacement gradients
    ``du (..., 3, 3)`` (``du_a/dx_b``) and ``lam, mu, beta, dT`` ``(...)``."""
    tr = du[..., 0, 0] + du[..., 1, 1] + du[..., 2, 2]
    iso = lam * tr - beta * dT
    s = np.empty(np.shape(lam) + (6,))
    for c in range(3):
        s[..., c] = iso + 2 * mu * du[..., c, c]
    for c, (a, b) in zip((3, 4, 5), ((0, 1), (1, 2), (0, 2))):
        s[..., c] = mu * (du[..., a, b] + du[..., b, a])
    return s


def von_mises_3d(s: np.ndarray) -> np.ndarray:
    """Von Mises stress of ``(..., 6)`` stresses ``xx, yy, zz, xy, yz, xz``."""
    xx, yy, zz, xy, yz, xz = (s[..., i] for i in range(6))
    return np.sqrt(0.5 * ((xx - yy) ** 2 + (yy - zz) ** 2 + (zz - xx) ** 2)
                   + 3.0 * (xy ** 2 + yz ** 2 + xz ** 2))


def vertex_copies(t: np.ndarray, groups: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Vertex copies per piece: ``(element copy ids (M, 4), vertex of each copy (D,))``."""
    _, g = unique(groups, return_inverse=True)
    G = int(g.max()) + 1
    key = t.astype(np.int64) * G + g[:, None]
    uniq, inv = unique(key.ravel(), return_inverse=True)
    return inv.reshape(t.shape), uniq // G


def recover_3d(copies: np.ndarray, ncopy: int, dx: np.ndarray, phi: np.ndarray,
               values: np.ndarray, rtol: float = 1e-10, pattern=None) -> np.ndarray:
    """L2 projection of quadrature values ``(M, Q, C)`` onto continuous P1 on the vertex
    copies ``copies (M, 4)``; ``phi (4, Q)`` the P1 basis at the quadrature points, ``dx``
    ``(M, Q)``. Consistent mass; all components at once by Jacobi-preconditioned CG
    (:func:`cg_columns`). ``pattern``: :func:`node_pattern` of ``copies``, if at hand."""
    vol = dx.sum(axis=1)
    M4 = (np.ones((4, 4)) + np.eye(4)) / 20.0
    local_mass = M4[None] * vol[:, None, None]
    if pattern is not None:
        indptr, indices, slot = pattern
        mass = sp.csr_matrix((sum_into(slot, local_mass, len(indices)), indices, indptr),
                             shape=(ncopy, ncopy))
    else:
        rows = np.repeat(copies, 4, axis=1).ravel()
        cols = np.tile(copies, (1, 4)).ravel()
        mass = sp.csr_matrix((local_mass.ravel(), (rows, cols)), shape=(ncopy, ncopy))
    C = values.shape[-1]
    local = np.einsum("mq,iq,mqc->mic", dx, phi, values)
    rhs = np.column_stack([np.bincount(copies.ravel(), weights=local[..., c].ravel(),
                                       minlength=ncopy) for c in range(C)])
    return cg_columns(mass, rhs, mass.diagonal(), rtol)


def cg_columns(A: sp.spmatrix, B: np.ndarray, diag: np.ndarray, rtol: float = 1e-10,
               maxiter: int = 1000) -> np.ndarray:
    """Solve ``A X = B`` for every column of ``B`` ``(n, C)`` by Jacobi-preconditioned
    conjugate gradients run side by side (one sparse product per iteration for all
    columns); ``A`` symmetric positive definite and well conditioned (a mass matrix)."""
    X = B / diag[:, None]
    R = B - A @ X
    Z = R / diag[:, None]
    D = Z.copy()
    rz = (R * Z).sum(axis=0)
    goal = rtol * np.linalg.norm(B, axis=0)
    for _ in range(maxiter):
        if (np.linalg.norm(R, axis=0) <= goal).all():
            return X
        AD = A @ D
        dad = (D * AD).sum(axis=0)
        alpha = np.divide(rz, dad, out=np.zeros_like(rz), where=dad != 0)
        X += alpha * D
        R -= alpha * AD
        Z = R / diag[:, None]
        rz_new = (R * Z).sum(axis=0)
        beta = np.divide(rz_new, rz, out=np.zeros_like(rz), where=rz != 0)
        D = Z + beta * D
        rz = rz_new
    log.warning("stress recovery: CG did not converge in %d iterations", maxiter)
    return X


def tet_boxes(P: np.ndarray, T: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Bounding boxes ``(lo (M, 3), hi (M, 3))`` of the tetrahedra."""
    c = P[T]
    return c.min(axis=1), c.max(axis=1)


def locate_tet(P: np.ndarray, T: np.ndarray, q, boxes=None) -> tuple[int, np.ndarray]:
    """The tetrahedron holding point ``q`` and its barycentric coordinates ``(4,)``; a point
    just outside (a curved surface between its facets) takes the element it is least outside
    of. Raises :class:`FEAError` for a point far from the mesh. ``boxes``:
    :func:`tet_boxes`, when locating several points."""
    q = np.asarray(q, dtype=np.float64)
    lo, hi = boxes if boxes is not None else tet_boxes(P, T)
    span = float(np.max(P.max(axis=0) - P.min(axis=0)))
    pad = 1e-9 * span
    cand = np.flatnonzero(np.all((lo - pad <= q) & (q <= hi + pad), axis=1))
    if not len(cand):
        # nearest element centroids: the point is outside every bounding box
        c = P[T].mean(axis=1)
        cand = np.argsort(np.linalg.norm(c - q, axis=1))[:64]
    a = P[T[cand, 0]]
    J = np.stack([P[T[cand, 1]] - a, P[T[cand, 2]] - a, P[T[cand, 3]] - a], axis=-1)
    lam3 = np.linalg.solve(J, (q - a)[..., None])[..., 0]
    lam = np.column_stack([1 - lam3.sum(axis=1), lam3])
    worst = lam.min(axis=1)
    e = int(np.argmax(worst))
    if worst[e] < -1.0:
        raise FEAError(f"point ({q[0]:.6g}, {q[1]:.6g}, {q[2]:.6g}) is outside the mesh: is "
                       f"the mesh for this model?")
    inside = np.flatnonzero(worst >= -1e-9)
    if len(inside):
        e = int(inside[np.argmin(cand[inside])])
    return int(cand[e]), lam[e]


def p2_values(lam: np.ndarray) -> np.ndarray:
    """The 10 P2 basis functions at barycentric ``lam (4,)``, in scikit-fem's local order
    (vertices, then the edges 01, 12, 02, 03, 13, 23)."""
    v = lam * (2 * lam - 1)
    e = [4 * lam[i] * lam[j] for i, j in ((0, 1), (1, 2), (0, 2), (0, 3), (1, 3), (2, 3))]
    return np.concatenate([v, e])


def displacement_gradients(space: TetSpace, U: np.ndarray) -> np.ndarray:
    """``du (M, Q, 3, 3)``: the displacement gradient at every quadrature point."""
    M = len(space.dofs)
    Q = space.dx.shape[1]
    du = np.empty((M, Q, 3, 3))
    for s in range(0, M, CHUNK):
        sl = slice(s, min(s + CHUNK, M))
        g = space.weighted(sl)[0]        # P1: one point, broadcast over the element
        du[sl] = np.einsum("mia,mqib->mqab", U[space.dofs[sl]], g)
    return du


def recover_stresses(space, T, n, sq, groups, order, pattern):
    """Stresses recovered at the vertex copies of every piece (``rec``), the copies of every
    element's vertices, and their average at the vertices ``(n, 6)``."""
    M = len(T)
    groups = np.zeros(M, dtype=np.int64) if groups is None else np.asarray(groups)
    X = space.basis.X
    phi = np.vstack([1 - X.sum(axis=0), X])
    one_piece = bool((groups == groups[0]).all()) if M else True
    if one_piece and order == 1 and np.bincount(T.ravel(), minlength=n).all():
        # one piece of P1 elements: the copies are the vertices, the pattern is the matrix's
        copies, cnode = space.dofs, np.arange(n)
        rec = recover_3d(copies, n, space.dx, phi, sq, pattern=pattern)
    else:
        copies, cnode = vertex_copies(T, groups)
        rec = recover_3d(copies, len(cnode), space.dx, phi, sq)
    nodal = np.zeros((n, 6))
    np.add.at(nodal, cnode, rec)
    nodal /= np.bincount(cnode, minlength=n)[:, None]
    return rec, copies, nodal


def probe_values(P, T, space, probes, order, rec, copies, Tfull, U) -> dict:
    """Temperature, displacements, stresses and von Mises at every probe, interpolated in
    the tetrahedron that holds it."""
    out = {}
    boxes = tet_boxes(P, T) if probes else None
    for name, q in (probes or {}).items():
        e, bary = locate_tet(P, T, q, boxes)
        vals = p2_values(bary) if order == 2 else bary
        s = bary @ rec[copies[e]]
        entry = {"x": float(q[0]), "y": float(q[1]), "z": float(q[2]), "element": e,
                 "temperature": float(vals @ Tfull[space.dofs[e]])}
        ue = vals @ U[space.dofs[e]]
        entry.update({"ux": float(ue[0]), "uy": float(ue[1]), "uz": float(ue[2])})
        entry.update({k: float(s[j]) for j, k in enumerate(STRESS_NAMES_3D)})
        entry["von_mises"] = float(von_mises_3d(s))
        out[name] = entry
    return out
