"""Checks of the final verification that compare the mesh with the domain's curves.

:func:`hetmesh.tri.finish.finish` re-checks every claim before a mesh is returned; the checks
here concern the curves and are pure functions of arrays:

* **chords** (:func:`chord_sagitta`, :func:`chord_problems`): every boundary and interface
  edge on a curved curve is a chord of it, and the curve may not stray from that chord by
  more than the chord tolerance (1e-3 x the domain's diameter by default). The deviation is
  computed exactly from the two nodes' parameters on the curve: for a circular arc of radius
  r whose chord spans the angle a it is the sagitta r (1 - cos(a / 2)); a segment is its own
  chord.
* **coverage** (:func:`coverage_problems`, :func:`chord_areas`): the mesh's boundary edges
  are exactly the domain's outer-loop and hole edges (no hole in the mesh, no triangle
  outside), and its area is the domain's up to the circular segments its boundary chords cut
  off or add, each computed exactly.

Examples
--------
>>> from hetmesh.tri.geometry import Arc, CurveBatch, Segment
>>> b = CurveBatch.from_curves([Arc.circle((0, 0), 2.0), Segment((0, 0), (1, 0))])
>>> s = chord_sagitta(b, np.array([0, 1]), np.array([[0.0, 1 / 17], [0.0, 1.0]]))
>>> s.round(4).tolist()
[0.0341, 0.0]
>>> chord_problems(b, np.array([0]), np.array([[0.0, 1 / 17]]), 0.02, names=["hole"])
['hole: 1 of 1 chords stray up to 0.0341 from the curve (chord tolerance 0.02)']
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..mesh import edge_keys
from ..topology import unique
from .geometry.curves import CurveBatch

__all__ = ["chord_sagitta", "chord_problems", "chord_areas", "coverage_problems",
           "mesh_model_problems", "CHORD_SLACK", "AREA_SLACK", "ON_BOUNDARY_TOL"]

#: relative allowance on the chord tolerance, for rounding (the placements step by
#: 2 arccos(1 - tol/r), which loses digits for a small tol/r)
CHORD_SLACK = 1e-6
#: relative allowance on the area, for the rounding of the triangles' areas
AREA_SLACK = 1e-9
#: :func:`mesh_model_problems`: how far (x the domain's diameter) a mesh's boundary node may
#: be from the domain's boundary (files keep coordinates to about 1e-16 relative; .inp and
#: .mesh files write fewer digits)
ON_BOUNDARY_TOL = 1e-6


def _angles(batch: CurveBatch, curve: np.ndarray, t: np.ndarray) -> np.ndarray:
    """The angle each chord spans on its arc (0 on segments), ``(K,)``."""
    curve = np.asarray(curve, np.intp)
    t = np.asarray(t, np.float64).reshape(-1, 2)
    return np.where(batch.is_arc[curve],
                    np.abs(t[:, 1] - t[:, 0]) * np.abs(batch.sweep[curve]), 0.0)


def chord_sagitta(batch: CurveBatch, curve: np.ndarray, t: np.ndarray) -> np.ndarray:
    """The largest distance between a curve and each of its chords, exactly.

    Parameters
    ----------
    batch : CurveBatch
        The domain's curves (``Domain.curve_batch``).
    curve : (K,) int
        The curve of every chord (index into ``batch``).
    t : (K, 2) float
        The parameters (in [0, 1], arclength) of the chord's two ends on its curve.

    Returns
    -------
    (K,) float
        ``r (1 - cos(a / 2)) = 2 r sin(a / 4)**2`` on an arc of radius ``r``, ``a`` the angle
        the chord spans (any ``a`` up to a full turn); 0 on a segment.
    """
    a = _angles(batch, curve, t)
    r = np.where(batch.is_arc[np.asarray(curve, np.intp)], batch.radius[curve], 0.0)
    return 2.0 * r * np.sin(0.25 * a) ** 2


def chord_problems(batch: CurveBatch, curve: np.ndarray, t: np.ndarray, tol: float, *,
                   names: Sequence[str] | None = None, scale: float = 1.0) -> list[str]:
    """One message per curve some chord of which strays more than ``tol`` from it.

    ``curve`` and ``t`` as for :func:`chord_sagitta` (every boundary and interface edge of
    the mesh); ``names`` the curves' names for the messages (else ``curve i``); lengths in
    the messages are multiplied by ``scale`` (to the user's units). Allows
    :data:`CHORD_SLACK` (relative) for rounding.
    """
    curve = np.asarray(curve, np.intp)
    sag = chord_sagitta(batch, curve, t)
    bad = ~(sag <= tol * (1.0 + CHORD_SLACK))  # nan parameters fail too
    out = []
    for c in unique(curve[bad]):
        on = curve == c
        worst = float(np.nanmax(sag[on & bad])) if np.any(on & bad & ~np.isnan(sag)) else np.nan
        name = names[c] if names is not None else f"curve {c}"
        out.append(f"{name}: {int((on & bad).sum())} of {int(on.sum())} chords stray up to "
                   f"{worst * scale:.3g} from the curve (chord tolerance {tol * scale:.3g})")
    return out


def chord_areas(batch: CurveBatch, curve: np.ndarray, t: np.ndarray) -> np.ndarray:
    """The area between each chord and its curve, exactly: ``r**2 (a - sin a) / 2`` on an
    arc (``a`` the angle spanned), 0 on a segment, ``(K,)``."""
    a = _angles(batch, curve, t)
    r = np.where(batch.is_arc[np.asarray(curve, np.intp)], batch.radius[curve], 0.0)
    return 0.5 * r * r * (a - np.sin(a))


def coverage_problems(mesh_boundary: np.ndarray, domain_boundary: np.ndarray, area: float,
                      domain_area: float, chord_area: float, *, node_area: float = 0.0,
                      scale: float = 1.0) -> list[str]:
    """The mesh covers the domain, nothing more.

    Parameters
    ----------
    mesh_boundary : (B, 2) int
        The mesh's boundary edges (held by one triangle).
    domain_boundary : (D, 2) int
        The constraint edges of the domain's outer loop and holes.
    area, domain_area : float
        The mesh's area and the domain's exact area.
    chord_area : float
        The total area between the boundary chords and their curves
        (:func:`chord_areas` summed): the mesh's area may differ from the domain's by at
        most that, plus ``node_area``, plus :data:`AREA_SLACK` (relative) for rounding.
    node_area : float
        What boundary nodes off their curve by the tolerance they are verified to may add or
        take: that tolerance times the boundary's length.
    scale : float
        Lengths in the messages are multiplied by it (areas by its square).

    Returns
    -------
    list of str
        Empty if the boundary edges are exactly the domain's and the area matches.
    """
    want = unique(edge_keys(domain_boundary[:, 0], domain_boundary[:, 1]))
    have = unique(edge_keys(mesh_boundary[:, 0], mesh_boundary[:, 1]))
    out = []
    if (n := int((~np.isin(have, want)).sum())):
        out.append(f"{n} mesh boundary edges are not on the domain's boundary (a hole in "
                   f"the mesh)")
    if (n := int((~np.isin(want, have)).sum())):
        out.append(f"{n} boundary edges of the domain are inside the mesh (triangles "
                   f"outside the domain)")
    if not abs(area - domain_area) <= chord_area + node_area + AREA_SLACK * abs(domain_area):
        a2 = scale * scale
        out.append(f"mesh area {area * a2:.9g} differs from the domain's {domain_area * a2:.9g}"
                   f" by more than its boundary chords allow ({chord_area * a2:.3g})")
    return out


def mesh_model_problems(points: np.ndarray, triangles: np.ndarray, domain, *,
                        max_chord_tol: float = 0.05, geometry: bool = True) -> list[str]:
    """Whether a mesh read from a file can belong to a model's domain, cheapest first.

    For ``hetmesh stats`` and ``hetmesh fea``, which evaluate a model's material on a mesh
    they did not make: every node the triangles use has finite coordinates; every node of
    the mesh's boundary lies on the domain's boundary (outer loop or holes, within
    :data:`ON_BOUNDARY_TOL` x its diameter); every triangle's centroid lies in the domain
    (or on its boundary); the mesh's area is the domain's up to what chords of its curves,
    at most ``max_chord_tol`` x the diameter from them, can cut off or add.

    ``geometry=False`` checks only that the nodes are finite.

    Returns
    -------
    list of str
        Empty if the mesh passes; else one message (the first check that fails), naming
        a node or coordinate.

    Examples
    --------
    >>> from hetmesh.tri.geometry import Loop, Segment, make_domain
    >>> sq = make_domain(Loop(tuple(Segment(a, b) for a, b in [((0, 0), (1, 0)),
    ...     ((1, 0), (1, 1)), ((1, 1), (0, 1)), ((0, 1), (0, 0))]), "outer"))
    >>> P = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    >>> mesh_model_problems(P, np.array([[0, 1, 2], [0, 2, 3]]), sq)
    []
    >>> mesh_model_problems(P * 2, np.array([[0, 1, 2], [0, 2, 3]]), sq)
    ["boundary node 2 at (2, 2) is 1.41 from the domain's boundary (the mesh is not of this model)"]
    """
    points = np.asarray(points, dtype=float)
    triangles = np.asarray(triangles, dtype=np.int64)
    used = unique(triangles)
    bad = used[~np.isfinite(points[used]).all(axis=1)]
    if len(bad):
        return [f"{len(bad)} node{'s' if len(bad) > 1 else ''} with non-finite coordinates "
                f"(node {int(bad[0])}: {tuple(float(v) for v in points[bad[0]])})"]
    if not geometry:
        return []
    diam = float(domain.diameter)
    a, b = triangles[:, [0, 1, 2]].ravel(), triangles[:, [1, 2, 0]].ravel()
    keys, counts = unique(edge_keys(a, b), return_counts=True)
    once = np.isin(edge_keys(a, b), keys[counts == 1])
    nodes = unique(np.concatenate([a[once], b[once]]))
    if len(nodes):
        dist = np.asarray(domain.distance_to_boundary(points[nodes], interfaces=False))
        i = int(np.argmax(dist))
        if dist[i] > ON_BOUNDARY_TOL * diam:
            x, y = points[nodes[i]]
            return [f"boundary node {int(nodes[i])} at ({x:.6g}, {y:.6g}) is {dist[i]:.3g} "
                    f"from the domain's boundary (the mesh is not of this model)"]
    cent = points[triangles].mean(axis=1)
    inside = np.asarray(domain.contains(cent), dtype=bool)
    if not inside.all():
        out = np.flatnonzero(~inside)
        near = np.asarray(domain.distance_to_boundary(cent[out], interfaces=False)) <= \
            max_chord_tol * diam
        out = out[~near]
        if len(out):
            x, y = cent[out[0]]
            return [f"{len(out)} triangles lie outside the domain (the first centred at "
                    f"({x:.6g}, {y:.6g}); the mesh is not of this model)"]
    p0, p1, p2 = points[triangles[:, 0]], points[triangles[:, 1]], points[triangles[:, 2]]
    area = 0.5 * float(np.abs((p1[:, 0] - p0[:, 0]) * (p2[:, 1] - p0[:, 1])
                              - (p1[:, 1] - p0[:, 1]) * (p2[:, 0] - p0[:, 0])).sum())
    length = sum(float(info.curve.length) for info in domain.curves if info.kind != "interface")
    allow = max_chord_tol * diam * length + AREA_SLACK * float(domain.area)
    if not abs(area - float(domain.area)) <= allow:
        return [f"the mesh's area {area:.6g} differs from the domain's {float(domain.area):.6g}"
                f" (the mesh does not cover this model's domain)"]
    return []
