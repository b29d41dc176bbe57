"""Steady heat conduction, then linear thermoelasticity, on a hetmesh mesh (paper Sec. 4.4).

The paper exported its meshes to a commercial package; here the analysis is built in, on
scikit-fem, with linear (P1, the default) or quadratic (P2, ``[fea] order = 2``) Lagrange
triangles:

1. **Conduction.** ``div(k grad T) = 0``; ``T`` fixed on the named curves, insulated
   elsewhere (zero normal flux is the natural condition).
2. **Thermoelasticity.** ``div sigma = 0`` with ``sigma = lambda tr(eps) I + 2 mu eps -
   beta (T - T_ref) I`` in the plane (``beta`` = ``E alpha / (1 - 2 nu)`` in plane strain,
   ``E alpha / (1 - nu)`` in plane stress, :func:`~hetmesh.fea.mixing.thermal_modulus`);
   plane strain adds ``sigma_zz = lambda tr(eps) - beta (T - T_ref)``.

The properties ``k, E, nu, alpha`` are mixed from the composition **at every quadrature
point** (3 per element for P1, 6 for P2), each element evaluated in its own feature-tree
subregion (:func:`hetmesh.material.element_subregions`), by the rule of ``[fea] mixing``
(:mod:`hetmesh.fea.mixing`). Boundary conditions are found geometrically -- the mesh nodes
within ``1e-6`` x the domain diameter of the named curves, the node at a named point -- so any
mesh file of the model works. Stresses are recovered at the nodes by an L2 projection onto
linear functions, continuous within each (region, subregion) piece and discontinuous across
material discontinuities and closed interfaces; probe values interpolate those recovered
fields in the containing element (see ``docs/fea.md``).

Singular systems are named, never solved: a mesh component without a fixed temperature, or
displacement conditions that leave a rigid-body mode free (:func:`~hetmesh.fea.config.rigid_rank`).
"""

from __future__ import annotations

import logging
import time
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components
from scipy.sparse.linalg import cg, splu

from ..errors import FEAError
from ..mesh import Mesh
from ..metrics import signed_area2
from ..topology import unique
from .config import ON_BOUNDARY, FEAConfig, rigid_rank
from .mixing import lame, mix, thermal_modulus

__all__ = ["FEAResult", "solve", "von_mises", "STRESS_NAMES"]

log = logging.getLogger(__name__)

#: the stress components, in the column order of :attr:`FEAResult.stress`
STRESS_NAMES = ("stress_xx", "stress_yy", "stress_xy", "stress_zz")


@dataclass(frozen=True, eq=False)
class FEAResult:
    """The solution of :func:`solve`.

    Attributes
    ----------
    mesh : Mesh
        The input mesh with the results as point data (``temperature`` K, ``displacement``
        ``(N, 2)`` m, ``stress_xx/yy/xy/zz`` and ``von_mises`` Pa, recovered) and cell data
        (the same stresses and temperature averaged over each element).
    temperature : (N,) nodal temperatures (K)
    displacement : (N, 2) nodal displacements (m)
    stress : (N, 4) recovered nodal stresses ``xx, yy, xy, zz`` (Pa); at a node shared by
        pieces of different material, the mean of the pieces' values
    von_mises : (N,) from ``stress``
    cell_stress : (M, 4) element means of the quadrature-point stresses
    cell_von_mises : (M,)
    probes : dict name -> dict of floats (see :meth:`report`)
    config : FEAConfig
    timings : dict phase -> seconds
    """

    mesh: Mesh
    temperature: np.ndarray
    displacement: np.ndarray
    stress: np.ndarray
    von_mises: np.ndarray
    cell_stress: np.ndarray
    cell_von_mises: np.ndarray
    probes: Mapping[str, Mapping[str, float]]
    config: FEAConfig
    model_name: str = ""
    timings: Mapping[str, float] = field(default_factory=dict)

    def report(self) -> dict[str, Any]:
        """A JSON-ready summary: settings, extremes, timings and one entry per probe with
        ``x, y, element, temperature, ux, uy, stress_xx, stress_yy, stress_xy, stress_zz,
        von_mises`` (SI units)."""
        c = self.config
        return {
            "model": self.model_name,
            "points": int(self.mesh.n_points), "elements": int(self.mesh.n_elements),
            "plane": c.plane, "mixing": c.mixing, "matrix": c.matrix,
            "reference_temperature": c.reference_temperature,
            "length_scale": c.length_scale,
            "units": {"length": "m", "temperature": "K", "stress": "Pa",
                      "probe_coordinates": "model units"},
            "temperature_range": [float(self.temperature.min()), float(self.temperature.max())],
            "von_mises_max": float(self.von_mises.max()),
            "von_mises_max_cell": float(self.cell_von_mises.max()),
            "probes": {k: dict(v) for k, v in self.probes.items()},
            "timings": dict(self.timings),
        }


# ----------------------------------------------------------------------------- geometry

def p1_basis(P: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(gradients (M, 3, 2), areas (M,))`` of the P1 basis functions of every triangle."""
    a, b, c = P[t[:, 0]], P[t[:, 1]], P[t[:, 2]]
    d = signed_area2(a, b, c)
    e = np.stack([c - b, a - c, b - a], axis=1)  # edge opposite each vertex
    g = np.stack([-e[..., 1], e[..., 0]], axis=-1) / d[:, None, None]
    return g, 0.5 * d


def _components(t: np.ndarray, n: int) -> tuple[int, np.ndarray]:
    """Connected components of the mesh (through shared nodes): ``(count, label (N,))``."""
    rows = np.concatenate([t[:, 0], t[:, 1], t[:, 2]])
    cols = np.concatenate([t[:, 1], t[:, 2], t[:, 0]])
    g = sp.coo_matrix((np.ones(len(rows)), (rows, cols)), shape=(n, n))
    return connected_components(g, directed=False)


def _curve_batch(domain, names):
    from ..tri.geometry.curves import CurveBatch

    infos = [info for info in domain.curves if info.name in names or info.owner in names]
    return CurveBatch.from_curves([i.curve for i in infos]), infos


def _curve_nodes(domain, mesh: Mesh, names, tol: float) -> np.ndarray:
    """Ids of the mesh nodes on the curves called ``names`` (curve or loop names)."""
    batch, infos = _curve_batch(domain, names)
    cand = unique(mesh.boundary_edges) if all(i.kind != "interface" for i in infos) \
        else np.arange(mesh.n_points)
    return cand[batch.distance(mesh.points[cand]) <= tol]


def curve_facets(domain, P: np.ndarray, facets: np.ndarray, nodes: np.ndarray, names,
                 tol: float) -> np.ndarray:
    """Ids of the facets (edges ``(2, F)``) discretising the named curves: both ends on them
    and the midpoint within the chord's sagitta (a quarter of the edge, or ``tol``)."""
    on = np.zeros(len(P), dtype=bool)
    on[nodes] = True
    cand = np.flatnonzero(on[facets[0]] & on[facets[1]])
    if not len(cand):
        return cand
    a, b = P[facets[0, cand]], P[facets[1, cand]]
    batch, _ = _curve_batch(domain, names)
    d = batch.distance(0.5 * (a + b))
    return cand[d <= np.maximum(tol, 0.25 * np.hypot(*(b - a).T))]


def _point_node(mesh: Mesh, p, tol: float, label: str, key: str) -> int:
    d = np.hypot(*(mesh.points - np.asarray(p, dtype=np.float64)).T)
    i = int(np.argmin(d))
    if d[i] > tol:
        raise FEAError(f"{key}: no mesh node at point {label} (the nearest is {d[i]:.3g} "
                       f"away); a point condition needs a node there: is the mesh for this "
                       f"model?")
    return i


# ---------------------------------------------------------------------- boundary conditions

def temperature_nodes(mesh: Mesh, domain, cfg: FEAConfig) -> list[tuple[np.ndarray, float]]:
    """``[(nodes, value)]`` per fixed-temperature condition, in the file's order."""
    tol = ON_BOUNDARY * domain.diameter
    out = []
    for bc in cfg.temperature:
        nodes = _curve_nodes(domain, mesh, bc.curves, tol)
        if not len(nodes):
            raise FEAError(f"{bc.key}: no mesh node lies on {', '.join(bc.curves)}: is the "
                           f"mesh for this model?")
        out.append((nodes, bc.value))
    return out


def displacement_nodes(mesh: Mesh, domain, cfg: FEAConfig) -> list[tuple[np.ndarray, Any]]:
    """``[(nodes, bc)]`` per displacement condition (``nodes`` empty-free)."""
    tol = ON_BOUNDARY * domain.diameter
    out = []
    for bc in cfg.displacement:
        if bc.point is not None:
            nodes = np.array([_point_node(mesh, bc.point, tol, bc.label, bc.key)])
        else:
            nodes = _curve_nodes(domain, mesh, bc.curves, tol)
            if not len(nodes):
                raise FEAError(f"{bc.key}: no mesh node lies on {bc.label}: is the mesh for "
                               f"this model?")
        out.append((nodes, bc))
    return out


def _fixed_components(n: int, disp) -> tuple[np.ndarray, np.ndarray]:
    """``(fixed_x, fixed_y)`` ``(N,)`` bool at the mesh nodes."""
    fixed = np.zeros((n, 2), dtype=bool)
    for nodes, bc in disp:
        fixed[nodes, 0] |= bc.ux is not None
        fixed[nodes, 1] |= bc.uy is not None
    return fixed[:, 0], fixed[:, 1]


def _condition_facets(basis, domain, P, sk_facets, nodes, names, tol) -> np.ndarray:
    """The facets along the curves ``names`` whose dofs a condition also fixes: none for a
    point condition or elements without facet dofs (P1), :func:`curve_facets` otherwise."""
    if not names or not basis.facet_dofs.size:
        return np.zeros(0, dtype=np.int64)
    return curve_facets(domain, P, sk_facets, nodes, names, tol)


def _condition_dofs(basis, nodes: np.ndarray, facets: np.ndarray, comp: int | None = None
                    ) -> np.ndarray:
    """Dofs of ``basis`` on the mesh ``nodes`` and ``facets`` (:func:`_condition_facets`);
    component ``comp`` of a vector basis."""
    rows = slice(None) if comp is None else slice(comp, comp + 1)
    return np.concatenate([basis.nodal_dofs[rows, nodes].ravel(),
                           basis.facet_dofs[rows][:, facets].ravel()])


def check_thermal(parts: tuple[int, np.ndarray], nodes: np.ndarray, P: np.ndarray) -> None:
    """Raise :class:`FEAError` if a mesh component (``parts``, :func:`_components`) has no
    fixed temperature."""
    count, label = parts
    has = np.zeros(count, dtype=bool)
    has[label[nodes]] = True
    if not has.all():
        k = int(np.flatnonzero(~has)[0])
        p = P[np.flatnonzero(label == k)[0]]
        raise FEAError(f"singular thermal system: the part of the mesh containing node "
                       f"({p[0]:.6g}, {p[1]:.6g}) has no fixed temperature (insulated all "
                       f"round, its temperature is undefined)")


def check_rigid(parts: tuple[int, np.ndarray], t: np.ndarray, P: np.ndarray, fx: np.ndarray,
                fy: np.ndarray) -> None:
    """Raise :class:`FEAError` unless the constraints of every mesh component (``parts``,
    :func:`_components`) remove its three rigid-body modes
    (:func:`~hetmesh.fea.config.rigid_rank`)."""
    count, label = parts
    used = np.zeros(len(P), dtype=bool)
    used[t.ravel()] = True
    for k in range(count):
        sel = (label == k) & used
        if not sel.any():
            continue
        c = sel & (fx | fy)
        rank = rigid_rank(P[c], fx[c], fy[c])
        if rank < 3:
            p = P[np.flatnonzero(sel)[0]]
            where = "" if count == 1 else f" of the part containing node ({p[0]:.6g}, {p[1]:.6g})"
            raise FEAError(f"singular elastic system: too few displacement constraints; they "
                           f"remove {rank} of the 3 rigid-body modes (2 translations and a "
                           f"rotation){where}")


# ------------------------------------------------------------------------------ material

def _subregions(field, P: np.ndarray, t: np.ndarray) -> np.ndarray | None:
    from ..material.field import element_subregions, has_subregions

    return element_subregions(field, P, t) if has_subregions(field) else None


def material_at(field, cfg: FEAConfig, x: np.ndarray, sub: np.ndarray | None
                ) -> dict[str, np.ndarray]:
    """Mixed properties at points ``x`` ``(M, Q, 2)`` (model coordinates), each row in
    subregion ``sub[row]``; returns ``(M, Q)`` arrays ``conductivity, youngs_modulus,
    poisson_ratio, expansion``."""
    M, Q = x.shape[:2]
    pts = x.reshape(-1, 2)
    if sub is None:
        comp = field.composition(pts)
    else:
        comp = field.composition(pts, region=np.repeat(sub, Q))
    comp = np.asarray(comp, dtype=np.float64)
    if not np.isfinite(comp).all():
        raise FEAError("the material field gave a non-finite composition at a quadrature point")
    cons = list(field.constituents)
    matrix = cons.index(cfg.matrix) if cfg.matrix is not None else 0
    props = mix(comp, cfg.table(), cfg.mixing, matrix)
    return {k: v.reshape(M, Q) for k, v in props.items()}


# ------------------------------------------------------------------------------- solving

def _solve_spd(A: sp.spmatrix, b: np.ndarray, what: str) -> np.ndarray:
    """Direct sparse solve (SuperLU, symmetric ordering), verified."""
    A = A.tocsc()
    try:
        lu = splu(A, permc_spec="MMD_AT_PLUS_A")
        x = lu.solve(b)
    except RuntimeError as exc:  # "Factor is exactly singular"
        raise FEAError(f"singular {what} system: {exc}") from None
    r = np.linalg.norm(A @ x - b)
    scale = np.linalg.norm(b) + 1e-300
    if not np.isfinite(x).all() or r > 1e-6 * scale:
        raise FEAError(f"singular {what} system: the solution is not finite or does not "
                       f"satisfy the equations (residual {r / scale:.2g})")
    return x


def _condensed(A: sp.spmatrix, b: np.ndarray, fixed: np.ndarray, x0: np.ndarray, what: str
               ) -> np.ndarray:
    """Solve ``A x = b`` with ``x[fixed] = x0[fixed]``."""
    A = A.tocsr()
    free = np.flatnonzero(~fixed)
    x = x0.copy()
    if len(free):
        rhs = b[free] - A[free][:, fixed] @ x0[fixed]
        x[free] = _solve_spd(A[free][:, free], rhs, what)
    return x


def thermal(basis, k: np.ndarray, nodes: np.ndarray, values: np.ndarray) -> np.ndarray:
    """Steady conduction ``div(k grad T) = 0``, ``T[nodes] = values`` (dofs of ``basis``);
    ``k`` at quadrature points ``(M, Q)``."""
    from skfem import BilinearForm, asm
    from skfem.helpers import dot, grad

    @BilinearForm
    def conduction(u, v, w):
        return w["k"] * dot(grad(u), grad(v))

    K = asm(conduction, basis, k=k)
    fixed = np.zeros(K.shape[0], dtype=bool)
    fixed[nodes] = True
    x0 = np.zeros(K.shape[0])
    x0[nodes] = values
    return _condensed(K, np.zeros(K.shape[0]), fixed, x0, "thermal")


def elastic(vbasis, lam, mu, beta, dT, fixed: np.ndarray, u0: np.ndarray) -> np.ndarray:
    """Linear thermoelasticity: ``int C eps(u) : eps(v) = int beta dT div v``; coefficient
    arrays at quadrature points ``(M, Q)``; ``fixed``/``u0`` per dof."""
    from skfem import BilinearForm, LinearForm, asm
    from skfem.helpers import ddot, div, sym_grad, trace

    @BilinearForm
    def stiffness(u, v, w):
        eu, ev = sym_grad(u), sym_grad(v)
        return w["lam"] * trace(eu) * trace(ev) + 2.0 * w["mu"] * ddot(eu, ev)

    @LinearForm
    def thermal_load(v, w):
        return w["beta"] * w["dT"] * div(v)

    K = asm(stiffness, vbasis, lam=lam, mu=mu)
    f = asm(thermal_load, vbasis, beta=beta, dT=dT)
    return _condensed(K, f, fixed, u0, "elastic")


def von_mises(s: np.ndarray) -> np.ndarray:
    """Von Mises stress of ``(..., 4)`` stresses ``xx, yy, xy, zz``."""
    xx, yy, xy, zz = s[..., 0], s[..., 1], s[..., 2], s[..., 3]
    return np.sqrt(0.5 * ((xx - yy) ** 2 + (yy - zz) ** 2 + (zz - xx) ** 2) + 3.0 * xy ** 2)


def p1_gradient(grads: np.ndarray, u: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Displacement gradients ``(M, 1, 2, 2)`` (``du_c/dx_d``) of P1 nodal values ``u (N, 2)``
    with basis gradients ``grads (M, 3, 2)`` (:func:`p1_basis`)."""
    return np.einsum("mic,mid->mcd", u[t], grads)[:, None]


def stresses(du: np.ndarray, lam, mu, beta, dT, plane: str) -> np.ndarray:
    """Stresses ``(M, Q, 4)`` (``xx, yy, xy, zz``) at the quadrature points from the
    displacement gradients ``du (M, Q, 2, 2)`` (``du_c/dx_d``; Q may be 1 for a constant
    strain) and ``lam, mu, beta, dT`` ``(M, Q)``."""
    exx, eyy = du[..., 0, 0], du[..., 1, 1]
    exy = 0.5 * (du[..., 0, 1] + du[..., 1, 0])
    tr = exx + eyy
    th = beta * dT
    s = np.empty(lam.shape + (4,))
    s[..., 0] = lam * tr + 2 * mu * exx - th
    s[..., 1] = lam * tr + 2 * mu * eyy - th
    s[..., 2] = 2 * mu * exy
    s[..., 3] = lam * tr - th if plane == "strain" else 0.0
    return s


# ------------------------------------------------------------------------------ recovery

def pieces(t: np.ndarray, n: int, groups: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Nodal copies per material piece: ``(element dofs (M, 3), node of each copy (D,))``.

    A node gets one copy for every piece (``groups`` id per element) of the elements around
    it, so fields recovered on the copies are continuous within a piece and may jump across
    piece boundaries (material discontinuities, closed interfaces).
    """
    _, g = unique(groups, return_inverse=True)
    key = t.astype(np.int64) * (int(g.max()) + 1) + g[:, None]
    uniq, inv = unique(key.ravel(), return_inverse=True)
    return inv.reshape(t.shape), uniq // (int(g.max()) + 1)


def recover(dofs: np.ndarray, ndof: int, areas: np.ndarray, phi: np.ndarray, w: np.ndarray,
            values: np.ndarray) -> np.ndarray:
    """L2 projection onto continuous P1 (on the copies ``dofs``) of quadrature-point values
    ``(M, Q, C)``: solves ``M s = int values phi`` (consistent mass, Jacobi-CG)."""
    M3 = (np.array([[2.0, 1, 1], [1, 2, 1], [1, 1, 2]]) / 12.0)[None] * areas[:, None, None]
    rows = np.repeat(dofs, 3, axis=1).ravel()
    cols = np.tile(dofs, (1, 3)).ravel()
    mass = sp.csr_matrix((M3.ravel(), (rows, cols)), shape=(ndof, ndof))
    # rhs_i = area * sum_q w_q phi_i(q) values_q  (w normalised to 1)
    local = np.einsum("q,iq,mqc->mic", w, phi, values) * areas[:, None, None]
    C = values.shape[-1]
    rhs = np.zeros((ndof, C))
    np.add.at(rhs, dofs.ravel(), local.reshape(-1, C))
    diag = mass.diagonal()
    pre = sp.diags(1.0 / diag)
    out = np.empty((ndof, C))
    for c in range(C):  # a few components, not a loop over elements
        x0 = rhs[:, c] / diag / 2.0  # ~ lumped
        x, info = cg(mass, rhs[:, c], x0=x0, rtol=1e-12, atol=0.0, maxiter=2000, M=pre)
        if info != 0:
            log.warning("stress recovery: CG did not converge (info %d)", info)
        out[:, c] = x
    return out


def _node_mean(copies: np.ndarray, node: np.ndarray, n: int) -> np.ndarray:
    """Mean over the copies of each node: ``(D, C) -> (N, C)``."""
    s = np.zeros((n, copies.shape[1]))
    np.add.at(s, node, copies)
    return s / np.bincount(node, minlength=n)[:, None]


# -------------------------------------------------------------------------------- probes

def _barycentric(P: np.ndarray, t: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Barycentric coordinates ``(M, 3)`` of point ``q`` in every triangle."""
    a, b, c = P[t[:, 0]], P[t[:, 1]], P[t[:, 2]]
    v0, v1, v2 = b - a, c - a, q - a
    d = v0[:, 0] * v1[:, 1] - v1[:, 0] * v0[:, 1]
    l1 = (v2[:, 0] * v1[:, 1] - v1[:, 0] * v2[:, 1]) / d
    l2 = (v0[:, 0] * v2[:, 1] - v2[:, 0] * v0[:, 1]) / d
    return np.column_stack([1 - l1 - l2, l1, l2])


def locate(P: np.ndarray, t: np.ndarray, q, prefer: np.ndarray | None = None
           ) -> tuple[int, np.ndarray]:
    """The element holding point ``q`` and its barycentric coordinates.

    Among the elements containing ``q`` (to rounding), one with ``prefer[e]`` True is taken
    when there is one (the probe's own subregion), else the lowest id. A point just outside
    the mesh (on a curved boundary between chord and arc) takes the element it is least
    outside of, and the P1 fields are extended linearly.
    """
    lam = _barycentric(P, t, np.asarray(q, dtype=np.float64))
    worst = lam.min(axis=1)
    inside = worst >= -1e-9
    if inside.any():
        if prefer is not None and (inside & prefer).any():
            inside &= prefer
        e = int(np.flatnonzero(inside)[0])
    else:
        e = int(np.argmax(worst))
        if worst[e] < -1.0:
            raise FEAError(f"point ({q[0]:.6g}, {q[1]:.6g}) is outside the mesh: is the mesh "
                           f"for this model?")
    return e, lam[e]


# --------------------------------------------------------------------------------- solve

def solve(mesh: Mesh, model, *, config: FEAConfig | None = None) -> FEAResult:
    """Steady conduction then linear thermoelasticity on ``mesh`` (paper Sec. 4.4).

    The dimension is read from the mesh: a tetrahedral mesh (``mesh.dim == 3``) of a 3-D
    model is analysed in 3-D (:mod:`hetmesh.fea.analysis3d`, with an
    :class:`~hetmesh.fea.config3d.FEAConfig3D`; returns a ``FEAResult3D``).

    Parameters
    ----------
    mesh : Mesh
        Any triangle mesh of the model's domain (from :func:`hetmesh.generate`,
        :func:`hetmesh.uniform` or :func:`hetmesh.io.read.read_mesh`), in the model's
        coordinates.
    model : Model
        With an ``[fea]`` table (``model.fea``), or pass ``config``.
    config : FEAConfig or FEAConfig3D, optional
        Overrides ``model.fea``.

    Returns
    -------
    FEAResult, or FEAResult3D for a tetrahedral mesh

    Raises
    ------
    FEAError
        No ``[fea]`` settings; a condition whose curve or point has no mesh node; a mesh
        component without a fixed temperature; too few displacement constraints; a probe
        outside the mesh.

    Examples
    --------
    >>> model = hetmesh.load_model(hetmesh.example_path("fgm_plate"))     # doctest: +SKIP
    >>> r = hetmesh.fea.solve(hetmesh.generate(model, 0.1).mesh, model)    # doctest: +SKIP
    >>> r.probes["P3"]["von_mises"]                                        # doctest: +SKIP
    """
    if getattr(mesh, "dim", 2) == 3:  # tetrahedra: the dimension is read from the mesh
        return _solve3d(mesh, model, config)
    from skfem import Basis, ElementTriP1, ElementTriP2, ElementVector, MeshTri

    cfg = config if config is not None else getattr(model, "fea", None)
    if getattr(cfg, "dim", 2) == 3:
        raise FEAError(f"model {model.name!r}: the [fea] table is for a 3-D model, the mesh "
                       f"is 2-D: is the mesh for this model?")
    if cfg is None:
        raise FEAError(f"model {model.name!r} has no [fea] table (properties, boundary "
                       f"conditions): see docs/model-format.md")
    if not cfg.has_problem:
        raise FEAError(f"model {model.name!r}: the [fea] table has no boundary conditions "
                       f"(fea.temperature, fea.displacement): see docs/model-format.md")
    field, domain = model.material, model.domain
    if len(cfg.properties) != len(field.constituents):
        raise FEAError(f"the [fea] properties are for {len(cfg.properties)} constituents, the "
                       f"material has {len(field.constituents)}")
    timings: dict[str, float] = {}
    t0 = time.perf_counter()
    P, t = np.asarray(mesh.points), np.asarray(mesh.triangles)
    n = len(P)

    # boundary conditions, checked before any assembly
    tol = ON_BOUNDARY * domain.diameter
    parts = _components(t, n)
    temps = temperature_nodes(mesh, domain, cfg)
    check_thermal(parts, np.concatenate([nd for nd, _ in temps] + [np.zeros(0, int)]), P)
    disp = displacement_nodes(mesh, domain, cfg)
    check_rigid(parts, t, P, *_fixed_components(n, disp))

    # local metres: shifted to the bounding-box centre (coordinates at 1e9 stay accurate)
    x0, y0, x1, y1 = domain.bounds
    origin = np.array([0.5 * (x0 + x1), 0.5 * (y0 + y1)])
    scale = cfg.length_scale
    Pm = (P - origin) * scale
    sk = MeshTri(np.ascontiguousarray(Pm.T), np.ascontiguousarray(t.T), validate=False,
                 sort_t=False)
    elem = ElementTriP2() if cfg.order == 2 else ElementTriP1()
    basis = Basis(sk, elem, intorder=2 * cfg.order)
    vbasis = Basis(sk, ElementVector(elem), intorder=2 * cfg.order)
    xq = np.moveaxis(basis.mapping.F(basis.X), 0, -1) / scale + origin  # (M, Q, 2) model
    sub = _subregions(field, P, t)
    props = material_at(field, cfg, xq, sub)
    lam, mu = lame(props["youngs_modulus"], props["poisson_ratio"], cfg.plane)
    beta = thermal_modulus(props["youngs_modulus"], props["poisson_ratio"],
                           props["expansion"], cfg.plane)
    timings["material"] = time.perf_counter() - t0

    t1 = time.perf_counter()
    value = np.full(basis.N, np.nan)
    for (nodes, v), bc in zip(temps, cfg.temperature):  # later conditions win where they meet
        f = _condition_facets(basis, domain, P, sk.facets, nodes, bc.curves, tol)
        value[_condition_dofs(basis, nodes, f)] = v
    tdofs = np.flatnonzero(~np.isnan(value))
    Tfull = thermal(basis, props["conductivity"], tdofs, value[tdofs])
    T = Tfull[basis.nodal_dofs[0]]
    timings["thermal"] = time.perf_counter() - t1

    t1 = time.perf_counter()
    dT = np.asarray(basis.interpolate(Tfull)) - cfg.reference_temperature  # (M, Q)
    fixed = np.zeros(vbasis.N, dtype=bool)
    ud = np.zeros(vbasis.N)
    for nodes, bc in disp:
        names = bc.curves if bc.point is None else ()
        f = _condition_facets(vbasis, domain, P, sk.facets, nodes, names, tol)
        for j, v in enumerate((bc.ux, bc.uy)):
            if v is not None:
                d = _condition_dofs(vbasis, nodes, f, comp=j)
                fixed[d] = True
                ud[d] = v * scale
    u = elastic(vbasis, lam, mu, beta, dT, fixed, ud)
    dofs = vbasis.nodal_dofs  # (2, N)
    U = np.column_stack([u[dofs[0]], u[dofs[1]]])
    timings["elastic"] = time.perf_counter() - t1

    t1 = time.perf_counter()
    du = np.moveaxis(vbasis.interpolate(u).grad, (0, 1), (2, 3))  # (M, Q, 2, 2)
    sq = stresses(du, lam, mu, beta, dT, cfg.plane)  # (M, Q, 4)
    w = basis.W / basis.W.sum()
    cell = np.einsum("q,mqc->mc", w, sq)
    groups = mesh.regions.astype(np.int64) * (int(sub.max()) + 1 if sub is not None else 1) \
        + (sub if sub is not None else 0)
    edofs, enode = pieces(t, n, groups)
    areas = 0.5 * signed_area2(Pm[t[:, 0]], Pm[t[:, 1]], Pm[t[:, 2]])
    phi = np.vstack([1 - basis.X[0] - basis.X[1], basis.X[0], basis.X[1]])  # P1 at (3, Q)
    copies = recover(edofs, len(enode), areas, phi, w, sq)
    nodal = _node_mean(copies, enode, n)
    timings["recovery"] = time.perf_counter() - t1

    vm, cvm = von_mises(nodal), von_mises(cell)
    probes = _probes(cfg, field, P, t, groups, sub, edofs, copies, T, U)
    timings["total"] = time.perf_counter() - t0
    out = mesh.with_data(
        point_data={"temperature": T, "displacement": U,
                    **{k: nodal[:, i] for i, k in enumerate(STRESS_NAMES)}, "von_mises": vm},
        cell_data={"temperature": (dT @ w) + cfg.reference_temperature,
                   **{k: cell[:, i] for i, k in enumerate(STRESS_NAMES)}, "von_mises": cvm})
    log.info("fea %s: %d elements, T in [%.6g, %.6g] K, max von Mises %.4g Pa (%.2f s)",
             model.name, len(t), T.min(), T.max(), vm.max(), timings["total"])
    return FEAResult(mesh=out, temperature=T, displacement=U, stress=nodal, von_mises=vm,
                     cell_stress=cell, cell_von_mises=cvm, probes=probes, config=cfg,
                     model_name=model.name, timings=timings)


def _solve3d(mesh: Mesh, model, config):
    """:func:`solve` on a tetrahedral mesh (:mod:`hetmesh.fea.analysis3d`)."""
    from .analysis3d import solve_mesh3d

    cfg = config if config is not None else getattr(model, "fea", None)
    name = getattr(model, "name", "")
    if cfg is None:
        raise FEAError(f"model {name!r} has no [fea] table (properties, boundary conditions): "
                       f"see docs/model-format.md")
    if getattr(cfg, "dim", 2) != 3:
        raise FEAError(f"model {name!r}: the [fea] table is for a 2-D model, the mesh is "
                       f"3-D (tetrahedra): is the mesh for this model?")
    return solve_mesh3d(mesh, model, cfg)


def _probes(cfg, field, P, t, groups, sub, edofs, copies, T, U) -> dict[str, dict]:
    """Probe values: the recovered fields interpolated in the containing element (of the
    probe's own subregion where the probe lies on a discontinuity)."""
    if not cfg.probes:
        return {}
    names = list(cfg.probes)
    q = np.array([cfg.probes[k] for k in names], dtype=np.float64)
    own = np.asarray(field.region(q)) if sub is not None else None
    out = {}
    for i, name in enumerate(names):  # a handful of named points
        prefer = (sub == own[i]) if own is not None else None
        e, lam = locate(P, t, q[i], prefer)
        s = lam @ copies[edofs[e]]
        temp = float(lam @ T[t[e]])
        u = lam @ U[t[e]]
        entry = {"x": float(q[i, 0]), "y": float(q[i, 1]), "element": e,
                 "temperature": temp, "ux": float(u[0]), "uy": float(u[1])}
        entry.update({k: float(s[j]) for j, k in enumerate(STRESS_NAMES)})
        entry["von_mises"] = float(von_mises(s))
        out[name] = entry
    return out
