"""Solution-adaptive refinement of a tetrahedral mesh on top of the material-adaptive one.

A mesh made for the material (delta(T) < delta_0) is fine where the composition changes fast,
which need not be where the stresses do: a graded tube under internal pressure has its
largest stresses and stress gradients at the inner face, where a grading flat there asks for
no elements. :func:`adapt` closes the loop the way Abaqus, COMSOL and scikit-fem users know:

1. **solve** (:func:`hetmesh.fea.solve`);
2. **estimate** the error of every element by Zienkiewicz-Zhu stress recovery
   (:func:`zz_indicator`; Zienkiewicz and Zhu 1987, "A simple error estimator and adaptive
   procedure for practical engineering analysis"): the recovered stress ``sigma*`` -- the
   L2 projection of the element stresses onto continuous linear functions within each piece
   that :func:`hetmesh.fea.solid.solve_tets` already computes for the nodal results -- against
   the element stress ``sigma_h``, in the energy-like norm
   ``eta_T^2 = int_T (sigma* - sigma_h) : C^-1 (sigma* - sigma_h)``, ``C^-1`` the compliance
   of the mixed material at every quadrature point; the global relative estimate is ZZ's
   ``eta / sqrt(||sigma_h||^2 + eta^2)`` (``||s||^2 = int s : C^-1 s``);
   or, with ``indicator="goal"``, the probes' dual-weighted indicator
   ``eta_T(u) eta_T(z)`` (:mod:`hetmesh.fea.goal`: ``z`` solves the dual problem of the
   probes' relative von Mises functional), whose sum estimates the relative probe error;
3. **mark** by Doerfler's bulk criterion (:func:`doerfler_mark`; Doerfler 1996, "A convergent
   adaptive algorithm for Poisson's equation"): the fewest elements whose ``eta_T^2`` add up
   to ``fraction`` of the total;
4. **refine** the marked tetrahedra by longest-edge bisection (:func:`refine_marked`; with
   ``edges="stress"`` the edge longest once the directions along which the recovered stress
   hardly varies are shrunk, :func:`stress_metric`): the bisection of
   :mod:`hetmesh.tet.refine` (every tetrahedron around a split edge is split,
   so the mesh stays conforming with no closure step), the boundary triangles split with
   their edges and keep their face names (:func:`hetmesh.tet.sampling.bisect_faces`), new
   vertices on curved faces moved onto the exact surface (:func:`snap_to_surface`), then
   the tetrahedra whose vertex delta a new vertex pushed to delta_0 bisected again
   (:func:`hetmesh.tet.sampling.repair_sampled`) and the whole mesh verified (positive
   volumes, conformity, faces on the solid, volume, delta_max < delta_0) before it is used;
5. **repeat** until the estimate is below the tolerance, the step budget is spent or the next
   mesh would pass the element budget.

Only 3-D (tetrahedral) meshes; the stress recovery is that of the nodal results, so the
indicator of quadratic elements compares their linear element stresses with a continuous
linear recovery.
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..errors import FEAError, OptionError, VerificationError
from ..topology import unique
from .estimate import compliance_energy, relative_estimate, zz_indicator
from .goal import (
    DEFAULT_ELEMENT_FACTOR,
    DEFAULT_RADIUS,
    dual_indicator,
    dual_solution,
    goal_estimate,
    goal_indicator,
)

__all__ = ["zz_indicator", "compliance_energy", "doerfler_mark", "snap_to_surface",
           "refine_marked", "mesh_faces", "adapt", "Adapted", "check_adapt_options",
           "DEFAULT_FRACTION", "DEFAULT_STEPS", "refinement_study", "STUDY_REFINEMENT",
           "relative_estimate", "Refined", "refined_mesh", "stress_metric", "stress_edge_key",
           "FLAT", "STRETCH", "EDGES"]

log = logging.getLogger(__name__)

#: Doerfler's bulk fraction theta: the marked elements carry this share of eta^2
DEFAULT_FRACTION = 0.5
#: refinement steps (solves after the first) unless told
DEFAULT_STEPS = 8
#: a direction along which the recovered stress varies by less than this times along the
#: steepest one is flat (:func:`stress_metric`)
FLAT = 0.1
#: with ``edges="stress"``, an edge along a flat direction counts this many times shorter:
#: it is bisected once the others are this much shorter than it
STRETCH = 4.0
#: how :func:`refine_marked` picks the edge of a marked tetrahedron: the longest, or the
#: longest once the directions along which the stress hardly varies are shrunk
EDGES = ("longest", "stress")
#: what the marks follow: ZZ's energy-norm indicator, or the probes' dual-weighted one
#: (:mod:`hetmesh.fea.goal`)
INDICATORS = ("energy", "goal")


# ---------------------------------------------------------------------------- mark

def doerfler_mark(eta: np.ndarray, fraction: float) -> np.ndarray:
    """Doerfler's bulk marking: the fewest elements (largest ``eta`` first, ties by index)
    whose ``eta^2`` sum to at least ``fraction`` of the total; a boolean mask.

    >>> doerfler_mark(np.array([1.0, 3.0, 2.0, 0.5]), 0.6).tolist()
    [False, True, False, False]
    """
    e2 = np.asarray(eta, dtype=np.float64) ** 2
    out = np.zeros(len(e2), dtype=bool)
    total = float(e2.sum())
    if total <= 0.0 or not len(e2):
        return out
    order = np.argsort(-e2, kind="stable")
    cum = np.cumsum(e2[order])
    k = int(np.searchsorted(cum, fraction * total * (1 - 1e-12))) + 1
    out[order[:min(k, len(e2))]] = True
    return out


def stress_metric(points: np.ndarray, tets: np.ndarray, stress: np.ndarray,
                  flat: float | None = None, stretch: float | None = None) -> np.ndarray:
    """``A (3, 3)``: coordinates ``x @ A`` in which the directions along which the stress
    hardly varies are shrunk by ``1 / stretch`` (default :data:`STRETCH`).

    ``M = sum_T |T| G_T G_T^T`` (``G_T (3, 6)`` the gradient of the vertex stresses
    ``stress (n, 6)``, linear on tetrahedron ``T``); an eigenvector of ``M`` is *flat* when
    the stress varies along it by less than ``flat`` (default :data:`FLAT`) times along the
    steepest one (``sqrt(lambda / lambda_max) < flat``). ``A`` is the eigenvectors, the flat
    ones scaled by ``1 / stretch``: the others keep their lengths, so where nothing is flat
    (or the stress is constant) ``x @ A`` is a rotation of ``x`` and :func:`refine_marked`
    bisects the longest edges.

    >>> x = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1.0]])
    >>> s = np.zeros((4, 6)); s[:, 0], s[:, 1] = x[:, 0], 2 * x[:, 1]   # none along z
    >>> np.abs(stress_metric(x, np.array([[0, 1, 2, 3]]), s)).max(axis=1).round(3).tolist()
    [1.0, 1.0, 0.25]
    """
    flat = FLAT if flat is None else float(flat)
    stretch = STRETCH if stretch is None else float(stretch)
    P = np.asarray(points, dtype=np.float64)
    T = np.asarray(tets, dtype=np.int64)
    S = np.asarray(stress, dtype=np.float64)
    D = P[T[:, 1:]] - P[T[:, :1]]                                   # (M, 3, 3)
    vol = np.abs(np.linalg.det(D)) / 6.0
    ok = vol > 0
    dS = S[T[ok, 1:]] - S[T[ok, :1]]                                # (m, 3, 6)
    G = np.linalg.solve(D[ok], dS)                                  # (m, 3, 6): d S / d x
    M = np.einsum("m,mic,mjc->ij", vol[ok], G, G)
    w, V = np.linalg.eigh(0.5 * (M + M.T))
    top = float(w.max())
    if not top > 0:
        return np.eye(3)
    rel = np.sqrt(np.maximum(w, 0.0) / top)
    scale = np.where(rel < flat, 1.0 / stretch, 1.0)
    return V * scale


def stress_edge_key(result, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(key (n, 3), A (3, 3))``: ``points @ A`` with ``A`` the :func:`stress_metric` of
    the recovered vertex stresses of ``result`` (an :class:`FEAResult3D` whose mesh has the
    vertices ``points``), the edge key of :func:`refine_marked` with ``edges="stress"``."""
    pd = result.mesh.point_data
    S = np.stack([np.asarray(pd[f"stress_{k}"], dtype=np.float64)
                  for k in ("xx", "yy", "zz", "xy", "yz", "xz")], axis=1)
    A = stress_metric(result.mesh.points, result.mesh.cells, S)
    return np.asarray(points, dtype=np.float64) @ A, A


# ---------------------------------------------------------------------------- refine

def mesh_faces(mesh, solid) -> tuple[np.ndarray, np.ndarray]:
    """The boundary triangles of a tetrahedral mesh (outward) and their face markers
    (``1 +`` the index in ``solid.face_names``), classified geometrically by the solid;
    :class:`FEAError` if a boundary triangle lies on no face (not a mesh of this solid)."""
    tri = np.asarray(mesh.boundary_facets, dtype=np.int64)
    label = np.asarray(solid.classify_faces(np.asarray(mesh.points)[tri]), dtype=np.int64)
    if (label < 0).any():
        c = np.asarray(mesh.points)[tri[label < 0][0]].mean(axis=0)
        raise FEAError(f"{int((label < 0).sum())} boundary triangles of the mesh lie on no "
                       f"face of the model's solid (e.g. at ({c[0]:.6g}, {c[1]:.6g}, "
                       f"{c[2]:.6g})): is the mesh for this model?")
    return tri, label + 1


def _section_curves(solid):
    """The curves whose swept surfaces are the solid's faces 3, 4, ... (markers), for a
    prism (its section's curves) or a revolution (its profile's); None otherwise."""
    from ..tet.revolve import Revolution
    from ..tet.solid import Prism

    if isinstance(solid, Prism):
        return [c.curve for c in solid.section.curves]
    if isinstance(solid, Revolution):
        return [c.curve for c in solid.profile.curves]
    return None


def snap_to_surface(solid, points: np.ndarray, ids: np.ndarray, faces: np.ndarray,
                    markers: np.ndarray, rounds: int = 8) -> np.ndarray:
    """``points`` with the boundary vertices ``ids`` moved onto the exact surfaces of their
    faces (``faces``/``markers`` as :func:`mesh_faces`).

    Prisms and revolutions: a side face is a curve of the section (profile) swept along the
    axis (about it), so the vertex's section coordinates are projected onto the curve
    (``curve.point(curve.project(q))``) and its axial coordinate (angle) kept -- on a cap
    it stays on the cap; a vertex on two curved faces is projected onto each in turn.
    Solids of primitives: Gauss-Newton onto the faces' surfaces
    (:func:`hetmesh.tet.general.project`).
    """
    ids = unique(np.asarray(ids, dtype=np.int64))
    p = np.array(points, dtype=np.float64, copy=True)
    if not len(ids):
        return p
    on = np.isin(faces, ids).any(axis=1)
    f, m = faces[on], markers[on]
    curves = _section_curves(solid)
    if curves is None:
        from ..tet.implicit import CSGSolid

        if isinstance(solid, CSGSolid):
            from ..tet.general import project

            q = project(solid, p, f, m - 1)
            p[ids] = q[ids]
        return p
    # the curved faces of every vertex (markers >= 3; the caps are planes)
    inc = {}
    for k in range(3):
        for v, mk in zip(f[:, k], m):
            if mk >= 3:
                inc.setdefault(int(v), set()).add(int(mk) - 3)
    verts = np.array(sorted(v for v in inc if v in set(ids.tolist())), dtype=np.int64)
    if not len(verts):
        return p
    q, s = solid.to2d(p[verts])
    q = np.array(q, dtype=np.float64)
    sets = [sorted(inc[int(v)]) for v in verts]
    many = max(len(c) for c in sets) > 1
    for _ in range(rounds if many else 1):
        for ci, curve in enumerate(curves):
            sel = np.array([ci in c for c in sets])
            if sel.any():
                q[sel] = curve.point(curve.project(q[sel]))
    p[verts] = solid.to3d(q, s)
    return p


@dataclass(frozen=True)
class Refined:
    """A refined, verified mesh: points, tetrahedra, compositions at the points, vertex
    delta, subregions (or None), boundary triangles and markers, and counts."""

    points: np.ndarray
    tets: np.ndarray
    comp: np.ndarray
    delta: np.ndarray
    regions: np.ndarray | None
    faces: np.ndarray
    markers: np.ndarray
    bisection_passes: int
    repair_passes: int
    snapped: int


def refine_marked(points: np.ndarray, tets: np.ndarray, faces: np.ndarray,
                  markers: np.ndarray, marked: np.ndarray, *, solid, field,
                  threshold: float, regions: np.ndarray | None = None,
                  comp: np.ndarray | None = None, chord_tol: float | None = None,
                  max_elements: int | None = None,
                  edge_key: np.ndarray | None = None) -> Refined:
    """Bisect every ``marked`` tetrahedron once along its longest edge, keep the mesh
    conforming, put the new boundary vertices on the exact surface, restore delta < delta_0
    and verify (see the module docstring).

    Each pass splits the longest edge (max norm) of the marked tetrahedra not split yet, at
    most one edge per tetrahedron (:func:`hetmesh.tet.refine.select_edges`) -- longest in
    ``edge_key (n, k)`` if given (one row per point; a new point gets the mean of its
    edge's rows), e.g. the coordinates of :func:`stress_edge_key`; every
    tetrahedron around a split edge splits with it (:func:`hetmesh.tet.refine.bisect_edges`),
    children inheriting their parent's subregion, the boundary triangles along it too
    (:func:`hetmesh.tet.sampling.bisect_faces`).

    Raises
    ------
    VerificationError
        If the refined mesh fails the tetrahedral mesher's verification (it is never
        returned then).
    BudgetError
        Past ``max_elements`` in the delta repair.
    """
    from ..tet.general import keep_positive
    from ..tet.mesher import CHORD, TetResult
    from ..tet.refine import MAX_PASSES, bisect_edges, select_edges
    from ..tet.sampling import bisect_faces, repair_sampled, result_problems, sampled_delta

    P = np.asarray(points, dtype=np.float64)
    T = np.asarray(tets, dtype=np.int64)
    F = np.asarray(faces, dtype=np.int64)
    Mk = np.asarray(markers, dtype=np.int64)
    reg = None if regions is None else np.asarray(regions, dtype=np.int64)
    pending = np.asarray(marked, dtype=bool).copy()
    n_start = len(P)
    key = None if edge_key is None else np.asarray(edge_key, dtype=np.float64)
    if key is not None and len(key) != len(P):
        raise FEAError(f"edge_key has {len(key)} rows for {len(P)} points")
    passes = 0
    while pending.any():
        if passes >= MAX_PASSES:
            raise FEAError(f"marked refinement did not finish in {MAX_PASSES} passes")
        split = select_edges(T, P if key is None else key, pending)
        if key is not None:
            key = np.concatenate([key, 0.5 * (key[split[:, 0]] + key[split[:, 1]])])
        n0 = len(P)
        F, Mk = bisect_faces(F, Mk, split, n0)
        P, T2, parent = bisect_edges(P, T, split, with_parents=True)
        was_split = np.bincount(parent, minlength=len(T)) > 1
        pending = pending[parent] & ~was_split[parent]
        if reg is not None:
            reg = reg[parent]
        T = T2
        passes += 1
    new = np.arange(n_start, len(P))
    on_boundary = new[np.isin(new, F)]
    snapped = snap_to_surface(solid, P, on_boundary, F, Mk)
    moved = np.zeros(len(P), dtype=bool)
    moved[on_boundary] = (snapped[on_boundary] != P[on_boundary]).any(axis=1)
    before = P
    P = keep_positive(P, snapped, T, moved)
    n_snapped = int((P[on_boundary] != before[on_boundary]).any(axis=1).sum())
    C = (field.composition(P) if comp is None else
         np.concatenate([np.asarray(comp, dtype=np.float64), field.composition(P[n_start:])]))
    delta_of = sampled_delta(field, "vertices", threshold)
    rep = repair_sampled(P, T, C, field, threshold, delta_of, max_elements=max_elements,
                         regions=reg, faces=F, markers=Mk)
    names = tuple(solid.face_names)
    res = TetResult(rep.points, rep.tets.astype(np.int32), rep.faces.astype(np.int32),
                    rep.markers.astype(np.int32), names, rep.delta, float(threshold), {})
    chord = CHORD * solid.diameter if chord_tol is None else float(chord_tol)
    probs = result_problems(res, solid, chord)
    if probs:
        raise VerificationError(f"refined tetrahedral mesh failed verification: {probs[0]}"
                                + (f" (and {len(probs) - 1} more)" if len(probs) > 1 else ""))
    return Refined(rep.points, rep.tets, rep.comp, rep.delta, rep.regions, rep.faces,
                   rep.markers, passes, rep.passes, n_snapped)


# ---------------------------------------------------------------------------- the loop

@dataclass(frozen=True, eq=False)
class Adapted:
    """What :func:`adapt` returns.

    Attributes
    ----------
    result : FEAResult3D
        The solution on the last mesh (its ``mesh`` carries the results and the cell data
        ``error_indicator``).
    mesh : Mesh
        The last mesh, without results (compositions, delta, quality, face names, as
        :func:`hetmesh.generate` writes them).
    steps : list of dict
        Per solve: ``step`` (0 the given mesh), ``elements``, ``points``, ``estimate`` (ZZ's
        relative error, or with the goal-oriented indicator its probe estimate; then also
        ``energy_estimate`` and ``dual_seconds``), ``estimate_of`` (``"energy"`` or
        ``"probes"``), ``marked``, ``delta_max``, ``von_mises`` (probe -> Pa),
        ``solve_seconds``, ``refine_seconds``; with ``edges="stress"`` and a refinement
        after it, ``edge_metric`` (the :func:`stress_metric` used, 3 x 3).
    reason : str
        Why it stopped: ``"tolerance"``, ``"steps"`` or ``"max_elements"``.
    threshold, tolerance, fraction : float
    indicator : str
        ``"energy"`` or ``"goal"``.
    edges : str
        ``"longest"`` or ``"stress"``: the edge rule of the bisections.
    """

    result: Any
    mesh: Any
    steps: list
    reason: str
    threshold: float
    tolerance: float
    fraction: float
    seconds: float = math.nan
    indicator: str = "energy"
    info: Mapping[str, Any] = field(default_factory=dict)
    edges: str = "longest"

    def report(self) -> dict[str, Any]:
        """JSON-ready: the settings, why it stopped and the steps."""
        return {"tolerance": self.tolerance, "fraction": self.fraction,
                "indicator": self.indicator, "edges": self.edges,
                "threshold": self.threshold, "reason": self.reason,
                "steps": [dict(s) for s in self.steps], "seconds": self.seconds}


def check_adapt_options(tolerance: float, steps: int, fraction: float,
                        max_elements: int | None, threshold: float) -> None:
    """:class:`OptionError` naming the first bad option."""
    if not (isinstance(tolerance, (int, float)) and math.isfinite(tolerance)
            and 0 < tolerance < 1):
        raise OptionError(f"--adapt: expected a relative error in (0, 1), got {tolerance!r}")
    if isinstance(steps, bool) or not isinstance(steps, (int, np.integer)) or steps < 0:
        raise OptionError(f"--adapt-steps: expected a whole number >= 0, got {steps!r}")
    if not (isinstance(fraction, (int, float)) and 0 < fraction <= 1):
        raise OptionError(f"--adapt-fraction: expected a fraction in (0, 1], got "
                          f"{fraction!r}")
    if max_elements is not None and (isinstance(max_elements, bool) or max_elements < 1):
        raise OptionError(f"--max-elements: expected a count >= 1, got {max_elements!r}")
    if not (isinstance(threshold, (int, float)) and 0 < threshold < 1):
        raise OptionError(f"--threshold: expected delta_0 in (0, 1), got {threshold!r}")


def refined_mesh(ref: Refined, constituents, names) -> Any:
    """The :class:`~hetmesh.mesh.Mesh` of a :class:`Refined`, as :func:`hetmesh.generate`
    writes one: compositions as point data, ``delta`` and ``quality`` (and ``subregion``)
    as cell data, the boundary triangles as facets named by ``names``."""
    from ..mesh import Mesh
    from ..metrics import tet_quality

    pd = {c: ref.comp[:, j] for j, c in enumerate(constituents)}
    cd = {"delta": ref.delta, "quality": tet_quality(ref.points, ref.tets)}
    if ref.regions is not None:
        cd["subregion"] = ref.regions.astype(np.int32)
    return Mesh(ref.points, ref.tets.astype(np.int32),
                regions=None if ref.regions is None else ref.regions.astype(np.int32),
                facets=ref.faces.astype(np.int32), facet_markers=ref.markers.astype(np.int32),
                point_data=pd, cell_data=cd,
                marker_names={m: n for m, n in enumerate(names, start=1)})


def adapt(mesh, model, threshold: float, *, tolerance: float, steps: int = DEFAULT_STEPS,
          fraction: float = DEFAULT_FRACTION, max_elements: int | None = None,
          chord_tol: float | None = None, indicator: str = "energy",
          goal_probes: Sequence[str] | None = None, goal_radius: float | None = None,
          goal_element_factor: float | None = None, edges: str = "longest", config=None,
          progress: Callable[[dict], None] | None = None) -> Adapted:
    """Solve, estimate, mark, refine, repeat (see the module docstring) on a tetrahedral
    mesh of ``model`` that meets ``delta_0 = threshold`` at its vertices.

    Parameters
    ----------
    mesh : Mesh
        A tetrahedral mesh of the model (e.g. ``hetmesh.generate(model, threshold).mesh``
        or a file of one).
    model : a 3-D model with a solid and an ``[fea]`` table (or pass ``config``)
    threshold : float
        delta_0, which every refined mesh keeps (delta_max < delta_0 at the vertices).
    tolerance : float
        Stop when ZZ's relative error estimate is at most this.
    steps : int
        At most this many refinements (``steps + 1`` solves).
    fraction : float
        Doerfler's bulk fraction (0, 1].
    max_elements : int, optional
        Stop before a refinement whose mesh would have more tetrahedra (the count is known
        only after refining: that mesh is not solved).
    chord_tol : float, optional
        The verification's chord tolerance, relative to the solid's diameter (default the
        mesher's, 0.002).
    indicator : "energy" or "goal"
        What the marks and the stop follow: ZZ's energy-norm indicator and relative
        estimate, or the probes' dual-weighted indicator and its estimate of the relative
        von Mises error at the probes (:mod:`hetmesh.fea.goal`; one more solve per step).
    edges : "longest" or "stress"
        Which edge of a marked tetrahedron is bisected: the longest, or the longest once
        the directions along which the recovered stress hardly varies are shrunk
        (:func:`stress_metric`: on a plate in plane strain the axis, along which nothing
        varies; elsewhere, where every direction varies, the longest as well).
    goal_probes : names of the ``[fea]`` probes the goal-oriented indicator aims at (default
        all); goal_radius : the probe functional's mollifier radius, x the diameter
        (default :data:`hetmesh.fea.goal.DEFAULT_RADIUS`); goal_element_factor : the radius
        is at least this times the longest edge of the probe's element (default
        :data:`hetmesh.fea.goal.DEFAULT_ELEMENT_FACTOR`)
    progress : callable, optional
        Called with every step's record.

    Raises
    ------
    MeshDataError
        The mesh is not tetrahedral, or its vertex delta reaches ``threshold``.
    FEAError, VerificationError
        From the solver; a refined mesh that fails verification (never used).
    """
    from ..delta import element_delta
    from ..errors import MeshDataError
    from .analysis import solve

    check_adapt_options(tolerance, steps, fraction, max_elements, threshold)
    if indicator not in INDICATORS:
        raise OptionError(f"indicator: expected one of {', '.join(INDICATORS)}, got "
                          f"{indicator!r}")
    if edges not in EDGES:
        raise OptionError(f"edges: expected one of {', '.join(EDGES)}, got {edges!r}")
    if goal_element_factor is not None and not (
            isinstance(goal_element_factor, (int, float)) and math.isfinite(goal_element_factor)
            and goal_element_factor > 0):
        raise OptionError(f"goal_element_factor: expected a number > 0, got "
                          f"{goal_element_factor!r}")
    cfg = config if config is not None else getattr(model, "fea", None)
    if indicator == "goal" and (cfg is None or not getattr(cfg, "probes", None)):
        raise FEAError(f"model {getattr(model, 'name', '')!r}: the goal-oriented indicator "
                       f"needs probes in the [fea] table")
    if indicator == "goal" and goal_probes is not None:  # named before any solve
        known = list(cfg.probes)
        unknown = [n for n in goal_probes if n not in known]
        if unknown:
            raise OptionError(f"goal probes: model {getattr(model, 'name', '')!r} has no probe "
                              f"named {unknown[0]!r} (its probes: {', '.join(known)})")
    if getattr(mesh, "dim", None) != 3:
        raise MeshDataError("solution-adaptive refinement needs a tetrahedral (3-D) mesh")
    solid, field_ = getattr(model, "solid", None), model.material
    if solid is None or not callable(getattr(solid, "classify_faces", None)):
        raise FEAError(f"model {getattr(model, 'name', '')!r}: refinement needs the model's "
                       f"solid (to name the faces and put new vertices on them)")
    t_start = time.perf_counter()
    faces, markers = mesh_faces(mesh, solid)
    P = np.asarray(mesh.points, dtype=np.float64)
    T = np.asarray(mesh.cells, dtype=np.int64)
    comp = np.asarray(field_.composition(P), dtype=np.float64)
    regions = None
    if mesh.cell_data.get("subregion") is not None:
        regions = np.asarray(mesh.cell_data["subregion"], dtype=np.int64)
    # every element in its own subregion (a vertex on a discontinuity has two compositions)
    delta = element_delta(field_, P, T, "vertices", composition=comp, regions=regions)
    if not float(delta.max()) < threshold:
        i = int(np.argmax(delta))
        c = P[T[i]].mean(axis=0)
        raise MeshDataError(f"the mesh's delta_max {float(delta.max()):.6g} is not below "
                            f"delta_0 = {threshold:g} (tetrahedron {i} at ({c[0]:.6g}, "
                            f"{c[1]:.6g}, {c[2]:.6g})): refinement keeps delta_0, so the "
                            f"mesh must meet it")
    names = tuple(solid.face_names)
    cons = list(getattr(model, "constituents", None) or field_.constituents)
    current = Refined(P, T, comp, delta, regions, faces, markers, 0, 0, 0)
    cur_mesh = refined_mesh(current, cons, names)
    records: list[dict] = []
    reason = "steps"
    refine_seconds = 0.0
    for step in range(steps + 1):
        t0 = time.perf_counter()
        r = solve(cur_mesh, model, config=config)
        solve_s = time.perf_counter() - t0
        eta = np.asarray(r.error_indicator)
        est = relative_estimate(eta, r.energy)
        rec = {"step": step, "elements": int(cur_mesh.n_elements),
               "points": int(cur_mesh.n_points), "estimate": est,
               "estimate_of": "energy",
               "delta_max": float(current.delta.max()),
               "von_mises": {k: float(v["von_mises"]) for k, v in r.probes.items()},
               "solve_seconds": solve_s, "refine_seconds": refine_seconds, "marked": 0}
        records.append(rec)
        mark_eta = eta
        if indicator == "goal":
            t0 = time.perf_counter()
            kw = {"radius": DEFAULT_RADIUS if goal_radius is None else goal_radius,
                  "element_factor": DEFAULT_ELEMENT_FACTOR if goal_element_factor is None
                  else goal_element_factor}
            eta_z, _ = dual_indicator(dual_solution(cur_mesh, model, cfg, r.probes,
                                                    names=goal_probes, **kw))
            mark_eta = goal_indicator(eta, eta_z)
            rec["energy_estimate"] = est
            est = rec["estimate"] = goal_estimate(eta, eta_z)
            rec["estimate_of"] = "probes"
            rec["dual_seconds"] = time.perf_counter() - t0
        log.info("adapt step %d: %d tetrahedra, estimate %.4g", step, rec["elements"], est)
        result = r
        if est <= tolerance:
            reason = "tolerance"
            if progress is not None:
                progress(rec)
            break
        if step == steps:
            if progress is not None:
                progress(rec)
            break
        marked = doerfler_mark(mark_eta, fraction)
        rec["marked"] = int(marked.sum())
        key = None
        if edges == "stress":
            key, A = stress_edge_key(r, current.points)
            rec["edge_metric"] = A.tolist()
        if progress is not None:
            progress(rec)
        t0 = time.perf_counter()
        nxt = refine_marked(current.points, current.tets, current.faces, current.markers,
                            marked, solid=solid, field=field_, threshold=threshold,
                            regions=current.regions, comp=current.comp,
                            chord_tol=None if chord_tol is None else chord_tol * solid.diameter,
                            edge_key=key)
        refine_seconds = time.perf_counter() - t0
        if max_elements is not None and len(nxt.tets) > max_elements:
            reason = "max_elements"
            break
        current = nxt
        cur_mesh = refined_mesh(current, cons, names)
    out_mesh = result.mesh.with_data(cell_data={"error_indicator":
                                                np.asarray(result.error_indicator)})
    from dataclasses import replace

    result = replace(result, mesh=out_mesh)
    return Adapted(result=result, mesh=cur_mesh, steps=records, reason=reason,
                   threshold=float(threshold), tolerance=float(tolerance),
                   fraction=float(fraction), seconds=time.perf_counter() - t_start,
                   indicator=indicator, edges=edges)


# ---------------------------------------------------------------------------- the study

#: the refinement family of the 3-D study: Doerfler fraction, refinements, tetrahedra budget,
#: the indicator the marks follow (the probes' dual-weighted one: the study asks for the
#: stress at the probes, not for the energy norm), its mollifier's element factor and the
#: edges bisected (along the directions in which the stress varies, :func:`stress_metric`)
STUDY_REFINEMENT = {"full": {"fraction": 0.5, "steps": 8, "max_elements": 60_000,
                             "indicator": "goal",
                             "goal_element_factor": DEFAULT_ELEMENT_FACTOR,
                             "edges": "stress"},
                    "quick": {"fraction": 0.5, "steps": 5, "max_elements": 20_000,
                              "indicator": "goal",
                              "goal_element_factor": DEFAULT_ELEMENT_FACTOR,
                              "edges": "stress"}}


def refinement_study(model, reference: dict, study, *, threshold: float, quick: bool = False,
                     chord_tol: float | None = None, start_chord_tol: float | None = None,
                     fraction: float | None = None, steps: int | None = None,
                     max_elements: int | None = None, indicator: str | None = None,
                     goal_element_factor: float | None = None, edges: str | None = None,
                     uniform_elements: Sequence[int] | None = None) -> dict:
    """The third family of the 3-D study: the material-adaptive mesh at ``threshold``
    (:func:`hetmesh.generate` with the chord tolerance ``start_chord_tol``, default
    ``chord_tol``, both relative) refined by :func:`adapt` step by step (marks by
    ``indicator``, default the plan's; with the goal-oriented one, the mollifier's floor
    ``goal_element_factor`` x the probe element's longest edge, default the plan's), every
    step's mesh one member, with the probe errors
    against ``reference`` (as :func:`hetmesh.fea.probe_study.study3d`'s ``study``, whose
    uniform counts give the ratios). A coarser start is refined towards the exact surface:
    every new boundary vertex is put on it (:func:`snap_to_surface`); the refined meshes are
    verified with the start's chord tolerance. With ``uniform_elements`` and a start chord
    tolerance of its own, the uniform family is measured again at that chord tolerance
    (:func:`hetmesh.fea.probe_study.study3d` with these counts), for a like-for-like ratio:
    the chord tolerance also sets how many tetrahedra a uniform mesh has along the curved
    faces.

    ``edges`` (default the plan's, ``"stress"``) picks the edges bisected (:func:`adapt`).

    Returns ``{"threshold", "fraction", "steps", "max_elements", "indicator",
    "goal_element_factor", "edges", "start_chord_tol", "reason", "seconds", "meshes": [{"family":
    "refined", "param": step,
    "elements", "von_mises", "estimate", "estimate_of", "errors", "max_error",
    "solve_seconds"}], "needed": {set: {"refined", "refined_exact", "uniform",
    "uniform_exact", "adaptive", "ratio", and with the like-for-like uniform family
    "uniform_start_chord", "uniform_start_chord_exact", "ratio_start_chord"}}}``, and then
    ``"uniform_start_chord": [{"elements", "errors"}]``; ``ratio`` is refined / uniform where
    the uniform count is a crossing (else None).
    """
    from ..meshing import generate
    from .probe_study import TOLERANCE, elements_needed, probe_sets, study3d

    plan = dict(STUDY_REFINEMENT["quick" if quick else "full"])
    for k, v in (("fraction", fraction), ("steps", steps), ("max_elements", max_elements),
                 ("indicator", indicator), ("goal_element_factor", goal_element_factor),
                 ("edges", edges)):
        if v is not None:
            plan[k] = v
    t0 = time.perf_counter()
    ref = reference["von_mises"]
    names = list(model.fea.probes)
    sets = probe_sets(names)
    primary = study.primary if study is not None else ("P" if "P" in sets else next(iter(sets)))
    start_tol = chord_tol if start_chord_tol is None else start_chord_tol
    verify_tol = None if start_tol is None else max(start_tol, chord_tol or 0.0)
    start = generate(model, threshold, chord_tol=start_tol).mesh
    a = adapt(start, model, threshold, tolerance=1e-9, steps=plan["steps"],
              fraction=plan["fraction"], max_elements=plan["max_elements"],
              chord_tol=verify_tol, indicator=plan["indicator"],
              goal_element_factor=plan["goal_element_factor"], edges=plan["edges"])
    tol = TOLERANCE if study is None else study.tolerance
    meshes = []
    for st in a.steps:
        errs = {s: max(abs(st["von_mises"][k] - ref[k]) / abs(ref[k]) for k in ns)
                for s, ns in sets.items()}
        meshes.append({"family": "refined", "param": st["step"], "elements": st["elements"],
                       "von_mises": st["von_mises"], "estimate": st["estimate"],
                       "estimate_of": st["estimate_of"], "errors": errs,
                       "max_error": errs[primary], "solve_seconds": st["solve_seconds"]})
    needed = {}
    for s in sets:
        n, exact = elements_needed([m["elements"] for m in meshes],
                                   [m["errors"][s] for m in meshes], tol)
        nd = {"refined": n, "refined_exact": exact, "uniform": None, "uniform_exact": False,
              "adaptive": None, "ratio": None}
        if study is not None and s in study.needed_by_set:
            u = study.needed_by_set[s]
            nd.update(uniform=u["uniform"], uniform_exact=u["uniform_exact"],
                      adaptive=u["adaptive"])
            if n is not None and u["uniform"] and u["uniform_exact"]:
                nd["ratio"] = n / u["uniform"]
        needed[s] = nd
    out = {"threshold": float(threshold), **plan,
           "start_chord_tol": None if start_tol is None else float(start_tol),
           "reason": a.reason, "meshes": meshes, "needed": needed, "primary": primary}
    if uniform_elements and start_tol != chord_tol:
        same = study3d(model, reference, uniform_elements=list(uniform_elements),
                       thresholds=(), tolerance=tol, chord_tol=start_tol)
        out["uniform_start_chord"] = [{"elements": m["elements"], "errors": m["errors"]}
                                      for m in same.meshes if "error" not in m]
        for s, nd in needed.items():
            u = same.needed_by_set[s]
            nd.update(uniform_start_chord=u["uniform"],
                      uniform_start_chord_exact=u["uniform_exact"], ratio_start_chord=None)
            if nd["refined"] is not None and u["uniform"] and u["uniform_exact"]:
                nd["ratio_start_chord"] = nd["refined"] / u["uniform"]
    out["seconds"] = time.perf_counter() - t0
    return out
