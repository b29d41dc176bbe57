"""Verification of the 3-D analysis against the exact radial references (:mod:`.radial`).

Structured tetrahedral meshes of a quarter of a thick-walled cylinder and an eighth of a
hollow sphere (mapped layers of triangular prisms, each split into three tetrahedra by the
global vertex order, which keeps neighbouring prisms conforming), the graded Al2O3/Ni
material of the validation (paper Table 6, metal fraction ``((r - a) / (b - a))^2``, linear
rule of mixtures), and the three cases of ``docs/fea.md`` ("3-D analysis"):

- ``pressure``: the cylinder, a = 10, b = 20, length 5 (mm), plane strain (``u_z = 0`` on
  both ends, symmetry planes ``x = 0``, ``y = 0``), 100 MPa on the inner face;
- ``thermal``: the same cylinder with the inner face at 1173.15 K and the outer at 273.15 K
  (stress-free at 273.15 K), no pressure;
- ``sphere``: the hollow sphere a = 10, b = 20 under 100 MPa inside.

:func:`run_case` solves one case on one mesh and compares the radial and hoop stresses (and
the temperature) at the probes with the reference; :func:`convergence` fits the rates.

>>> P, T = annulus_tets(10.0, 20.0, 5.0, nr=2, nt=3, nz=1)
>>> P.shape, T.shape
((24, 3), (36, 4))
"""

from __future__ import annotations

import math
import time
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..errors import FEAError
from .config import Properties
from .mixing import mix_linear
from .radial import RadialSolution, cylinder, sphere
from .solid import Displacement, solve_tets

__all__ = ["prisms_to_tets", "annulus_tets", "shell_octant_tets", "annulus_mesh",
           "graded_field", "case_config", "CYLINDER_FACES", "AL2O3", "NI",
           "graded_profiles", "graded_material", "CASES", "reference", "run_case",
           "convergence", "case_mesh", "RADII", "LENGTH", "PRESSURE", "T_INNER", "T_OUTER",
           "T_REF", "extrude", "plane_strain_check", "case_probes", "radial_hoop", "CaseRun"]

#: the constituents' properties (paper Table 6; SI units)
AL2O3 = Properties(conductivity=35.0, youngs_modulus=393e9, poisson_ratio=0.25,
                   expansion=7.4e-6)
NI = Properties(conductivity=90.7, youngs_modulus=199.5e9, poisson_ratio=0.3,
                expansion=15.4e-6)
RADII = (10.0, 20.0)        # mm
LENGTH = 5.0                # mm
PRESSURE = 100e6            # Pa
T_INNER, T_OUTER, T_REF = 1173.15, 273.15, 273.15
#: the validation cases
CASES = ("pressure", "thermal", "sphere")


# -------------------------------------------------------------------------------- meshes

def prisms_to_tets(bottom: np.ndarray, top: np.ndarray) -> np.ndarray:
    """Split prisms ``(bottom triangle, top triangle)`` ``(K, 3)`` each into 3 tetrahedra.

    ``top[:, i]`` is above ``bottom[:, i]`` and every top id orders like its bottom id (a
    layer offset), so sorting each triangle by vertex id makes the diagonal of every quad
    face run from its lower-id bottom vertex to its higher-id top vertex, the same from both
    prisms sharing the face: the tetrahedra are conforming.
    """
    order = np.argsort(bottom, axis=1)
    a, b, c = np.take_along_axis(bottom, order, axis=1).T
    a2, b2, c2 = np.take_along_axis(top, order, axis=1).T
    return np.vstack([np.column_stack([a, b, c, c2]), np.column_stack([a, b, b2, c2]),
                      np.column_stack([a, a2, b2, c2])])


def _orient(P: np.ndarray, T: np.ndarray) -> np.ndarray:
    """Tetrahedra with positive volume (two vertices swapped where negative)."""
    a = P[T[:, 0]]
    v = np.einsum("ij,ij->i", np.cross(P[T[:, 1]] - a, P[T[:, 2]] - a), P[T[:, 3]] - a)
    T = T.copy()
    neg = v < 0
    T[neg, 2], T[neg, 3] = T[neg, 3], T[neg, 2].copy()
    return T


def _layers(base: np.ndarray, tris: np.ndarray, layers: int) -> tuple[np.ndarray, np.ndarray]:
    """Prisms between ``layers + 1`` copies of a triangulation with ``len(base)`` vertices."""
    n = len(base)
    bottoms = [tris + k * n for k in range(layers)]
    bottom = np.vstack(bottoms)
    return bottom, bottom + n


def annulus_tets(a: float, b: float, length: float, nr: int, nt: int, nz: int,
                 angle: float = math.pi / 2) -> tuple[np.ndarray, np.ndarray]:
    """A sector ``0 <= theta <= angle`` of the tube ``a <= r <= b``, ``0 <= z <= length``:
    ``nr x nt`` quads in ``(r, theta)`` split into triangles, ``nz`` prism layers in ``z``;
    ``6 nr nt nz`` tetrahedra. Returns ``(points (N, 3), tets (M, 4))``."""
    r = np.linspace(a, b, nr + 1)
    th = np.linspace(0.0, angle, nt + 1)
    R, TH = np.meshgrid(r, th, indexing="ij")
    xy = np.column_stack([(R * np.cos(TH)).ravel(), (R * np.sin(TH)).ravel()])
    idx = np.arange((nr + 1) * (nt + 1)).reshape(nr + 1, nt + 1)
    q0, q1 = idx[:-1, :-1].ravel(), idx[1:, :-1].ravel()
    q2, q3 = idx[1:, 1:].ravel(), idx[:-1, 1:].ravel()
    tris = np.vstack([np.column_stack([q0, q1, q2]), np.column_stack([q0, q2, q3])])
    z = np.linspace(0.0, length, nz + 1)
    P = np.vstack([np.column_stack([xy, np.full(len(xy), zk)]) for zk in z])
    T = prisms_to_tets(*_layers(xy, tris, nz))
    return P, _orient(P, T)


def shell_octant_tets(a: float, b: float, nr: int, ns: int) -> tuple[np.ndarray, np.ndarray]:
    """The eighth ``x, y, z >= 0`` of the shell ``a <= |x| <= b``: the flat triangle with
    corners on the axes, split into ``ns^2`` triangles and projected onto the sphere, then
    ``nr`` radial prism layers; ``3 nr ns^2`` tetrahedra."""
    ij = [(i, j) for i in range(ns + 1) for j in range(ns + 1 - i)]
    lut = {p: k for k, p in enumerate(ij)}
    bary = np.array([(i, j, ns - i - j) for i, j in ij], dtype=np.float64) / ns
    unit = bary / np.linalg.norm(bary, axis=1, keepdims=True)
    tris = []
    for i in range(ns):
        for j in range(ns - i):
            tris.append((lut[i, j], lut[i + 1, j], lut[i, j + 1]))
            if i + j + 1 < ns:
                tris.append((lut[i + 1, j], lut[i + 1, j + 1], lut[i, j + 1]))
    tris = np.array(tris, dtype=np.int64)
    r = np.linspace(a, b, nr + 1)
    P = np.vstack([unit * rk for rk in r])
    T = prisms_to_tets(*_layers(unit, tris, nr))
    return P, _orient(P, T)


#: the named faces of :func:`annulus_mesh` (marker = index + 1)
CYLINDER_FACES = ("inner", "outer", "bottom", "top", "y0", "x0")


def annulus_mesh(a: float, b: float, length: float, nr: int, nt: int, nz: int):
    """:func:`annulus_tets` of a quarter tube as a :class:`~hetmesh.mesh.Mesh` whose boundary
    triangles are named facets: ``inner`` (r = a), ``outer`` (r = b), ``bottom`` (z = 0),
    ``top`` (z = length), ``y0`` (the plane y = 0) and ``x0`` (x = 0)."""
    from ..mesh import Mesh

    P, T = annulus_tets(a, b, length, nr, nt, nz)
    m = Mesh(P, T)
    tri = np.asarray(m.boundary_facets)
    c = P[tri]                                            # (K, 3, 3)
    tol = 1e-9 * b
    r = np.hypot(c[..., 0], c[..., 1])
    tests = [np.abs(r - a) <= tol, np.abs(r - b) <= tol, np.abs(c[..., 2]) <= tol,
             np.abs(c[..., 2] - length) <= tol, np.abs(c[..., 1]) <= tol,
             np.abs(c[..., 0]) <= tol]
    marker = np.zeros(len(tri), dtype=np.int32)
    for i, on in enumerate(tests):
        marker[(marker == 0) & on.all(axis=1)] = i + 1
    return Mesh(P, T, facets=tri, facet_markers=marker,
                marker_names={i + 1: n for i, n in enumerate(CYLINDER_FACES)})


def graded_field():
    """The cylinder's material as an :class:`~hetmesh.material.AnalyticField` in x, y, z
    (metal fraction ``((r - 10) / 10)^2``, ``r`` the distance from the z axis)."""
    from ..material.analytic import AnalyticField

    a, b = RADII
    return AnalyticField({"metal": f"((sqrt(x**2 + y**2) - {a!r}) / {b - a!r})**2"},
                         ["ceramic", "metal"], dim=3)


def case_config(case: str, order: int = 2):
    """The ``[fea]`` settings of the cylinder cases (``pressure`` or ``thermal``) on the
    faces of :func:`annulus_mesh`, as a model file would give them."""
    from .config3d import DisplacementBC3D, FEAConfig3D, PressureBC, Selection, TemperatureBC3D

    if case not in ("pressure", "thermal"):
        raise FEAError(f"unknown cylinder case {case!r} (expected pressure or thermal)")
    disp = (DisplacementBC3D(Selection(faces=("bottom", "top")), None, None, 0.0),
            DisplacementBC3D(Selection(faces=("y0",)), None, 0.0, None),
            DisplacementBC3D(Selection(faces=("x0",)), 0.0, None, None))
    temps = (TemperatureBC3D(Selection(faces=("inner",)), T_INNER),
             TemperatureBC3D(Selection(faces=("outer",)), T_OUTER)) \
        if case == "thermal" else ()
    press = (PressureBC(Selection(faces=("inner",)), PRESSURE),) if case == "pressure" else ()
    return FEAConfig3D(properties={"ceramic": AL2O3, "metal": NI}, temperature=temps,
                       displacement=disp, pressure=press, probes=case_probes(case),
                       reference_temperature=T_REF, length_scale=1e-3, order=order)


def case_mesh(case: str, n: int) -> tuple[np.ndarray, np.ndarray]:
    """The structured mesh of a case at refinement ``n`` (elements across the wall):
    the cylinder with ``nt = round(2.36 n)`` (square-ish cells at mid-radius) and
    ``nz = ceil(n / 2)`` (about 7 n^3 tetrahedra); the sphere with ``ns = round(1.6 n)``
    (about 7.7 n^3)."""
    a, b = RADII
    if case == "sphere":
        return shell_octant_tets(a, b, n, max(1, round(1.6 * n)))
    return annulus_tets(a, b, LENGTH, n, max(1, round(0.5 * math.pi * 15.0 / 10.0 * n)),
                        max(1, math.ceil(n * LENGTH / (b - a))))


# ------------------------------------------------------------------------------ material

def _fraction(r: np.ndarray) -> np.ndarray:
    a, b = RADII
    return ((np.asarray(r, dtype=np.float64) - a) / (b - a)) ** 2


def _table() -> dict[str, np.ndarray]:
    return {k: np.array([getattr(AL2O3, k), getattr(NI, k)])
            for k in ("conductivity", "youngs_modulus", "poisson_ratio", "expansion")}


def graded_profiles() -> dict[str, Any]:
    """``E, nu, alpha, k`` as functions of the radius (model units, mm)."""
    table = _table()

    def prop(name):
        def f(r):
            c = _fraction(r)
            return mix_linear(np.stack([1 - np.ravel(c), np.ravel(c)], axis=-1),
                              table)[name].reshape(np.shape(r))
        return f

    return {"E": prop("youngs_modulus"), "nu": prop("poisson_ratio"),
            "alpha": prop("expansion"), "k": prop("conductivity")}


def graded_material(case: str):
    """The material callable of :func:`~hetmesh.fea.solid.solve_tets` for a case: the
    composition at each point from its radius (cylindrical, or spherical for ``sphere``)."""
    table = _table()
    axes = slice(0, 3) if case == "sphere" else slice(0, 2)

    def material(x):
        c = np.clip(_fraction(np.linalg.norm(x[:, axes], axis=1)), 0.0, 1.0)
        return mix_linear(np.column_stack([1 - c, c]), table)

    return material


def reference(case: str) -> RadialSolution:
    """The exact radial solution of a case."""
    a, b = RADII
    f = graded_profiles()
    if case == "pressure":
        return cylinder(a, b, f["E"], f["nu"], p_inner=PRESSURE, t_ref=T_REF)
    if case == "thermal":
        return cylinder(a, b, f["E"], f["nu"], alpha=f["alpha"], k=f["k"], t_inner=T_INNER,
                        t_outer=T_OUTER, t_ref=T_REF)
    if case == "sphere":
        return sphere(a, b, f["E"], f["nu"], p_inner=PRESSURE, t_ref=T_REF)
    raise FEAError(f"unknown case {case!r} (expected one of {', '.join(CASES)})")


def case_probes(case: str) -> dict[str, tuple[float, float, float]]:
    """R1, R2, R3 at r = 12.5, 15, 17.5: on ``y = 0`` at mid-length for the cylinder, on
    the diagonal ``x = y = z`` for the sphere."""
    radii = (12.5, 15.0, 17.5)
    if case == "sphere":
        return {f"R{i + 1}": tuple(float(r / math.sqrt(3.0)) for _ in range(3))
                for i, r in enumerate(radii)}
    return {f"R{i + 1}": (r, 0.0, 0.5 * LENGTH) for i, r in enumerate(radii)}


# ---------------------------------------------------------------------------------- runs

def _tensor(p: Mapping[str, float]) -> np.ndarray:
    xx, yy, zz = p["stress_xx"], p["stress_yy"], p["stress_zz"]
    xy, yz, xz = p["stress_xy"], p["stress_yz"], p["stress_xz"]
    return np.array([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]])


def radial_hoop(case: str, probe: Mapping[str, float]) -> tuple[float, float]:
    """Radial and hoop stress at a probe from its stress tensor."""
    x = np.array([probe["x"], probe["y"], probe["z"]])
    if case == "sphere":
        n = x / np.linalg.norm(x)
        t = np.cross(n, [0.0, 0.0, 1.0])
    else:
        n = np.array([x[0], x[1], 0.0]) / math.hypot(x[0], x[1])
        t = np.array([-n[1], n[0], 0.0])
    t = t / np.linalg.norm(t)
    S = _tensor(probe)
    return float(n @ S @ n), float(t @ S @ t)


@dataclass(frozen=True)
class CaseRun:
    """One solve of a case: sizes, timings and the relative errors at the probes."""

    case: str
    order: int
    n: int
    tets: int
    unknowns: int
    seconds: float
    errors: Mapping[str, Mapping[str, float]]   # probe -> {"sigma_r", "sigma_t", ["T"]}
    values: Mapping[str, Mapping[str, float]]   # probe -> FE values
    exact: Mapping[str, Mapping[str, float]]    # probe -> reference values
    solver: Mapping[str, Any]

    @property
    def max_error(self) -> float:
        return max(max(e.values()) for e in self.errors.values())


def run_case(case: str, n: int, order: int, *, solver: str = "auto",
             ref: RadialSolution | None = None) -> CaseRun:
    """Solve ``case`` on :func:`case_mesh` ``(case, n)`` with elements of ``order`` and
    compare with the reference at the probes: relative errors of ``sigma_r``, ``sigma_t``
    (and of the temperature rise ``T - T_outer`` for ``thermal``)."""
    a, b = RADII
    P, T = case_mesh(case, n)
    ref = ref if ref is not None else reference(case)
    tol = 1e-9 * b
    rad = np.linalg.norm(P, axis=1) if case == "sphere" else np.hypot(P[:, 0], P[:, 1])
    inner, outer = np.abs(rad - a) <= tol, np.abs(rad - b) <= tol
    disp = [Displacement(np.abs(P[:, 0]) <= tol, ux=0.0, label="x = 0"),
            Displacement(np.abs(P[:, 1]) <= tol, uy=0.0, label="y = 0")]
    if case == "sphere":
        disp.append(Displacement(np.abs(P[:, 2]) <= tol, uz=0.0, label="z = 0"))
    else:
        disp.append(Displacement((np.abs(P[:, 2]) <= tol) | (np.abs(P[:, 2] - LENGTH) <= tol),
                                 uz=0.0, label="ends"))
    temps = [(inner, T_INNER), (outer, T_OUTER)] if case == "thermal" else []
    press = [(inner, PRESSURE)] if case in ("pressure", "sphere") else []
    probes = case_probes(case)
    t0 = time.perf_counter()
    res = solve_tets(P, T, graded_material(case), order=order, temperature=temps,
                     displacement=disp, pressure=press, probes=probes,
                     reference_temperature=T_REF, length_scale=1e-3, solver=solver)
    seconds = time.perf_counter() - t0
    errors, values, exact = {}, {}, {}
    for name, q in probes.items():
        r = float(np.linalg.norm(q)) if case == "sphere" else float(math.hypot(q[0], q[1]))
        sr, st = radial_hoop(case, res.probes[name])
        er, et = float(ref.sigma_r(r)), float(ref.sigma_t(r))
        values[name] = {"sigma_r": sr, "sigma_t": st}
        exact[name] = {"sigma_r": er, "sigma_t": et}
        errors[name] = {"sigma_r": abs(sr - er) / abs(er), "sigma_t": abs(st - et) / abs(et)}
        if case == "thermal":
            tf, te = res.probes[name]["temperature"], float(ref.temperature(r))
            values[name]["T"], exact[name]["T"] = tf, te
            errors[name]["T"] = abs(tf - te) / (T_INNER - T_OUTER)
    return CaseRun(case, order, n, len(T), int(res.solver["elastic"]["unknowns"]), seconds,
                   errors, values, exact, dict(res.solver))


def convergence(runs: list[CaseRun], key: str | None = None) -> float:
    """The convergence rate in the element size ``h ~ tets^(-1/3)``: the slope of
    ``np.polyfit`` of log(max error at the probes) against log(h) (``key``: one quantity,
    e.g. ``"sigma_t"``, else the largest of all)."""
    h = np.array([r.tets for r in runs], dtype=np.float64) ** (-1.0 / 3.0)
    if key is None:
        e = np.array([r.max_error for r in runs])
    else:
        e = np.array([max(v[key] for v in r.errors.values()) for r in runs])
    return float(np.polyfit(np.log(h), np.log(e), 1)[0])


# ----------------------------------------------------------------- a 2-D model extruded

def extrude(P2: np.ndarray, T2: np.ndarray, z0: float, z1: float, layers: int
            ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """A triangle mesh swept from ``z0`` to ``z1`` in ``layers`` prism layers, each prism cut
    into three tetrahedra (:func:`prisms_to_tets`). Returns ``(points (N, 3), tets (M, 4),
    node2d (N,), tri2d (M,))``: the 2-D node of every point and the 2-D triangle of every
    tetrahedron."""
    z = np.linspace(z0, z1, layers + 1)
    n = len(P2)
    P = np.vstack([np.column_stack([P2, np.full(n, zk)]) for zk in z])
    bottom, top = _layers(P2, np.asarray(T2, dtype=np.int64), layers)
    T = prisms_to_tets(bottom, top)
    tri = np.tile(np.arange(len(T2)), 3 * layers)
    keep = _orient(P, T)
    return P, keep, np.tile(np.arange(n), layers + 1), tri


def plane_strain_check(model, mesh2d, *, thickness: float = 1.0, layers: int = 1,
                       solver: str = "auto") -> dict[str, Any]:
    """A 2-D model with an ``[fea]`` table (plane strain) solved in 3-D on its mesh extruded
    by ``thickness`` (``u_z = 0`` on both end faces; the point conditions held along their
    vertical lines; the temperatures on the swept curves), against the 2-D solution on the
    same mesh. Returns ``{"2d": FEAResult, "3d": SolidResult, "probes": name -> {"vm_2d",
    "vm_3d", "difference"}}`` with ``difference`` the largest of the six stress components'
    differences relative to the 2-D von Mises stress, probes at mid-thickness."""
    from ..material.field import element_subregions, has_subregions
    from .analysis import displacement_nodes, solve, temperature_nodes
    from .mixing import mix

    cfg = model.fea
    if cfg is None or cfg.plane != "strain":
        raise FEAError("plane_strain_check needs a model with a plane-strain [fea] table")
    r2 = solve(mesh2d, model)
    P2, T2 = np.asarray(mesh2d.points), np.asarray(mesh2d.triangles)
    P, T, node2d, tri2d = extrude(P2, T2, 0.0, thickness, layers)
    field_ = model.material

    def lift(nodes2d):
        m2 = np.zeros(len(P2), dtype=bool)
        m2[nodes2d] = True
        return m2[node2d]

    temps = [(lift(nodes), v) for nodes, v in temperature_nodes(mesh2d, model.domain, cfg)]
    disp = [Displacement(lift(nodes), bc.ux, bc.uy, None, label=bc.label)
            for nodes, bc in displacement_nodes(mesh2d, model.domain, cfg)]
    ends = np.isclose(P[:, 2], 0.0) | np.isclose(P[:, 2], thickness)
    disp.append(Displacement(ends, uz=0.0, label="ends"))
    sub2 = element_subregions(field_, P2, T2) if has_subregions(field_) else None
    sub = sub2[tri2d] if sub2 is not None else None
    cons = list(field_.constituents)
    matrix = cons.index(cfg.matrix) if cfg.matrix is not None else 0
    table = cfg.table()

    def material(x):
        if sub is None:
            comp = field_.composition(x[:, :2])
        else:
            comp = field_.composition(x[:, :2], region=np.repeat(sub, len(x) // len(T)))
        return mix(np.asarray(comp, dtype=np.float64), table, cfg.mixing, matrix)

    groups = np.asarray(mesh2d.regions, dtype=np.int64)[tri2d]
    if sub is not None:
        groups = groups * (int(sub.max()) + 1) + sub
    probes = {k: (float(q[0]), float(q[1]), 0.5 * thickness) for k, q in cfg.probes.items()}
    r3 = solve_tets(P, T, material, order=cfg.order, temperature=temps, displacement=disp,
                    probes=probes, reference_temperature=cfg.reference_temperature,
                    length_scale=cfg.length_scale, groups=groups, solver=solver)
    out = {}
    for k in probes:
        a, b = r2.probes[k], r3.probes[k]
        vm = a["von_mises"]
        diff = max(abs(a[c] - b[c]) for c in ("stress_xx", "stress_yy", "stress_xy",
                                               "stress_zz")) / vm
        out[k] = {"vm_2d": vm, "vm_3d": b["von_mises"], "difference": diff,
                  "stress_xz": b["stress_xz"], "stress_yz": b["stress_yz"]}
    return {"2d": r2, "3d": r3, "probes": out}
