"""The independent check of a finished mesh (:func:`independent_check`): code that shares
nothing with the pipeline's own verification."""

from __future__ import annotations

import math

import numpy as np

__all__ = ["independent_check"]


def independent_check(result, model, threshold: float, *, min_angle: float | None = None,
                      min_quality: float | None = None) -> list[str]:
    """Problems of a meshing result, found without hetmesh's own verification.

    Parameters
    ----------
    result : hetmesh.Result
        From :func:`hetmesh.generate` (or :func:`hetmesh.uniform`).
    model : Model
        The model as given to the mesher (``result.model``, with material discontinuities
        embedded, is used for the curves when present).
    threshold : float
        delta_0.
    min_angle, min_quality : float, optional
        The angle (degrees) and quality floors; default: ``result.options``' values, else 30
        and 0.6.

    Returns
    -------
    list of str
        One line per problem; empty if the mesh is fine. Checked:

        * arrays: shapes, finite coordinates, indices in range, statistics matching the mesh;
        * every triangle counter-clockwise with positive area (not below 1e-12 of its longest
          edge squared), no repeated or unused points, every edge in one or two triangles and
          the two of an inner edge oriented oppositely (a manifold, consistently oriented);
        * every domain corner and named point a mesh node; every boundary and interface edge
          an edge of the mesh with both ends on its curve, and the edges of every curve
          covering it exactly once (their arcs add up to its length);
        * the mesh's boundary edges exactly the constraint edges of the outer loop and the
          holes; interface edges inside the mesh;
        * the area: mesh area plus the circular segments between the boundary chords and
          their arcs equals the domain's exact area, and the area of a shapely polygon of the
          domain (arcs sampled to 1e-7 of its diameter);
        * delta(T) < threshold at every element, from compositions recomputed at the vertices
          with ``model.material.composition`` (for a piecewise field every element in the
          subregion of its centroid, at all three vertices; the element's ``subregion``
          cell data is that subregion, and a vertex off every curve belongs to it); the
          reported ``delta`` cell data and ``stats.delta_max`` not below the recomputed
          values; the compositions written as point data equal to the recomputed ones;
        * every angle >= ``min_angle`` and q(T) >= ``min_quality``, except in triangles
          whose smallest angle sits at an input corner sharper than ``2 min_angle`` (the
          angle between the curves' tangents, on the domain's side) or whose shortest edge
          joins the two curves of such a corner at about equal distances from it.
    """
    out: list[str] = []
    try:
        _check(result, model, float(threshold), min_angle, min_quality, out)
    except Exception as exc:  # a malformed result must be a problem, not a crash
        out.append(f"check could not finish: {type(exc).__name__}: {exc}")
    return out


def _check(result, model, threshold, min_angle, min_quality, out):
    mesh = result.mesh
    opts = getattr(result, "options", None) or {}
    A = float(min_angle if min_angle is not None else opts.get("min_angle", 30.0))
    qfloor = float(min_quality if min_quality is not None else opts.get("min_quality", 0.6))
    meshed = getattr(result, "model", None) or model
    domain = meshed.domain
    P = np.asarray(mesh.points, float)
    T = np.asarray(mesh.triangles, np.int64)
    if not _arrays_ok(P, T, out):
        return
    st = result.stats
    if (st.n_points, st.n_elements) != (len(P), len(T)):
        out.append(f"stats say {st.n_points} points / {st.n_elements} elements, the mesh has "
                   f"{len(P)} / {len(T)}")
    diam = float(domain.diameter)
    mag = float(np.abs(P).max())
    tol = 1e-8 * diam + 256 * np.finfo(float).eps * mag
    area2, L2 = _check_triangles(P, T, out)
    _check_points(P, T, out)
    keys, boundary = _check_edges(T, len(P), out)
    E = np.asarray(mesh.edges, np.int64).reshape(-1, 2)
    markers = np.asarray(mesh.edge_markers, np.int64)
    infos = domain.curves
    if len(E) and (E.min() < 0 or E.max() >= len(P)):
        out.append("constraint edge indices out of range")
        return
    if len(markers) and (markers.min() < 1 or markers.max() > len(infos)):
        out.append(f"edge markers outside 1..{len(infos)} (the model's curves)")
        return
    on_bnd = _check_constraints(E, markers, infos, len(P), keys, boundary, out)
    _check_curves(P, E, markers, infos, mag, tol, diam, out)
    from scipy.spatial import cKDTree

    tree = cKDTree(P)
    fixed = np.asarray(domain.corners, float).reshape(-1, 2)
    if len(fixed):
        d, _ = tree.query(fixed)
        if (m := int((d > tol).sum())):
            out.append(f"{m} domain corners or named points are not mesh nodes")
    _check_area(P, T, E, markers, infos, on_bnd, area2, domain, out)
    _check_delta(mesh, model.material, P, T, domain, threshold, st, out)
    L = np.sqrt(L2)  # sides opposite vertices 0, 1, 2
    _check_angles(P, T, E, markers, infos, fixed, tree, L, A, qfloor, tol, st, out)


def _arrays_ok(P, T, out) -> bool:
    """Shapes, finite coordinates, indices in range (False: nothing else can be checked)."""
    if P.ndim != 2 or P.shape[1:] != (2,) or T.ndim != 2 or T.shape[1:] != (3,) or len(T) == 0:
        out.append(f"bad array shapes: points {P.shape}, triangles {T.shape}")
        return False
    if not np.isfinite(P).all():
        out.append("non-finite point coordinates")
        return False
    if T.min() < 0 or T.max() >= len(P):
        out.append("triangle indices out of range")
        return False
    return True


def _check_triangles(P, T, out) -> tuple[np.ndarray, np.ndarray]:
    """Orientation and degeneracy; returns twice the areas and the squared side lengths
    ``(M, 3)`` (opposite vertices 0, 1, 2)."""
    a, b, c = P[T[:, 0]], P[T[:, 1]], P[T[:, 2]]
    # relative to the first vertex: keeps precision far from the origin
    ab, ac, bc = b - a, c - a, c - b
    area2 = ab[:, 0] * ac[:, 1] - ab[:, 1] * ac[:, 0]
    L2 = np.stack([(bc ** 2).sum(1), (ac ** 2).sum(1), (ab ** 2).sum(1)], axis=1)
    if (m := int((area2 <= 0).sum())):
        out.append(f"{m} triangles are clockwise or have zero area "
                   f"(first #{int(np.argmax(area2 <= 0))})")
    if (m := int(((area2 > 0) & (area2 <= 1e-12 * L2.max(axis=1))).sum())):
        out.append(f"{m} triangles are degenerate (area below 1e-12 of the longest edge squared)")
    return area2, L2


def _check_points(P, T, out) -> None:
    """No unused and no repeated points."""
    used = np.zeros(len(P), bool)
    used[T.ravel()] = True
    if (m := int((~used).sum())):
        out.append(f"{m} points are not used by any triangle")
    order = np.lexsort((P[:, 1], P[:, 0]))
    if len(P) > 1 and (m := int(np.all(P[order][1:] == P[order][:-1], axis=1).sum())):
        out.append(f"{m} repeated points")


def _check_edges(T, n: int, out) -> tuple[np.ndarray, set]:
    """A manifold, consistently oriented; returns the edges' keys and the boundary's."""
    directed = np.concatenate([T[:, [0, 1]], T[:, [1, 2]], T[:, [2, 0]]])
    dkey = directed[:, 0] * n + directed[:, 1]
    if len(np.unique(dkey)) != len(dkey):
        out.append("a directed edge appears twice (overlapping or inconsistently oriented "
                   "triangles)")
    ukey = np.minimum(directed[:, 0], directed[:, 1]) * n + np.maximum(directed[:, 0],
                                                                         directed[:, 1])
    keys, counts = np.unique(ukey, return_counts=True)
    if (m := int((counts > 2).sum())):
        out.append(f"{m} edges are shared by more than two triangles")
    return keys, set(keys[counts == 1].tolist())


def _check_constraints(E, markers, infos, n: int, keys, boundary: set, out) -> np.ndarray:
    """Constraint edges are mesh edges, boundary ones exactly the mesh's boundary; returns
    which constraint edges lie on the outer loop or a hole."""
    ekey = np.minimum(E[:, 0], E[:, 1]) * n + np.maximum(E[:, 0], E[:, 1])
    if (m := int((~np.isin(ekey, keys)).sum())):
        out.append(f"{m} boundary or interface edges are not edges of the mesh")
    kinds = np.array([ci.kind for ci in infos])
    on_bnd = kinds[markers - 1] != "interface" if len(markers) else np.zeros(0, bool)
    want = set(ekey[on_bnd].tolist())
    if (m := len(boundary - want)):
        out.append(f"{m} mesh boundary edges are not on the outer loop or a hole")
    if (m := len(want - boundary)):
        out.append(f"{m} edges of the outer loop or holes are not on the mesh's boundary")
    iface = set(ekey[~on_bnd].tolist())
    if (m := len(iface & boundary)):
        out.append(f"{m} interface edges are on the mesh's boundary")
    return on_bnd


def _check_curves(P, E, markers, infos, mag, tol, diam, out) -> None:
    """Edge ends on their curve; every curve covered exactly once."""
    off = 0.0
    for k, ci in enumerate(infos):
        sel = np.flatnonzero(markers == k + 1)
        curve = ci.curve
        if len(sel) == 0:
            out.append(f"curve {ci.name!r} has no mesh edges")
            continue
        ends = P[E[sel]].reshape(-1, 2)
        off = max(off, float(np.asarray(curve.distance(ends)).max()))
        chord = np.hypot(*(P[E[sel, 1]] - P[E[sel, 0]]).T)
        if hasattr(curve, "radius"):
            r = curve.radius
            covered = float((2 * r * np.arcsin(np.minimum(1.0, chord / (2 * r)))).sum())
        else:
            covered = float(chord.sum())
        slack = 1e-7 * curve.length + len(sel) * 256 * np.finfo(float).eps * mag
        if abs(covered - curve.length) > slack:
            out.append(f"the edges of curve {ci.name!r} cover {covered:.12g} of its length "
                       f"{curve.length:.12g}")
    if off > tol:
        out.append(f"boundary or interface nodes are off their curve by {off:.3g} "
                   f"({off / diam:.2g} of the diameter)")


def _check_area(P, T, E, markers, infos, on_bnd, area2, domain, out) -> None:
    """Mesh area plus the arcs' caps equal to the domain's exact area and a polygon's."""
    n = len(P)
    diam = float(domain.diameter)
    seg = 0.0
    bsel = np.flatnonzero(on_bnd)
    for k in np.unique(markers[bsel]) if len(bsel) else []:
        curve = infos[k - 1].curve
        if not hasattr(curve, "radius"):
            continue
        es = E[bsel[markers[bsel] == k]]
        pa, pb = P[es[:, 0]], P[es[:, 1]]
        chord = np.hypot(*(pb - pa).T)
        th = 2 * np.arcsin(np.minimum(1.0, chord / (2 * curve.radius)))
        cap = 0.5 * curve.radius ** 2 * (th - np.sin(th))
        # the triangle on each edge: is the arc's centre on its side (the mesh misses the cap)?
        third = _third_vertex(T, es, n)
        cen = np.asarray(curve.center, float)
        side_c = _side(pa, pb, cen)
        side_t = _side(pa, pb, P[third])
        seg += float(np.where(side_c * side_t > 0, cap, -cap).sum())
    mesh_area = 0.5 * float(area2.sum())
    exact = float(domain.area)
    if abs(mesh_area + seg - exact) > 1e-9 * exact + len(E) * 1e-13 * diam * diam + \
            len(T) * 64 * np.finfo(float).eps * float(np.abs(area2).max()):
        out.append(f"mesh area {mesh_area:.12g} (+ {seg:.3g} of arc caps) differs from the "
                   f"domain's {exact:.12g}")
    poly_area, poly_tol = _polygon_area(domain)
    if abs(mesh_area + seg - poly_area) > poly_tol + 1e-9 * exact:
        out.append(f"mesh area {mesh_area:.12g} (+ {seg:.3g} of arc caps) differs from the "
                   f"shapely polygon's {poly_area:.12g}")


def _check_delta(mesh, fld, P, T, domain, threshold, st, out) -> None:
    """delta(T) below the threshold from compositions recomputed at the vertices, and the
    reported delta, statistics and point data not below / equal to them."""
    diam = float(domain.diameter)
    piecewise = hasattr(fld, "region") and int(getattr(fld, "n_regions", 1) or 1) > 1
    if piecewise:
        own = np.asarray(fld.region(P[T].mean(axis=1)))
        sub = mesh.cell_data.get("subregion")
        if sub is None:
            out.append("no 'subregion' cell data for a piecewise field")
        elif (m := int((np.asarray(sub) != own).sum())):
            out.append(f"{m} elements carry a subregion other than their centroid's")
        comp = np.stack([np.asarray(fld.composition(P[T[:, k]], region=own)) for k in range(3)],
                        axis=1)
        curves = domain.curve_batch
        free = curves.distance(P) > 1e-9 * diam
        vreg = np.asarray(fld.region(P))
        bad = ~((vreg[T] == own[:, None]) | ~free[T])
        if (m := int(bad.any(axis=1).sum())):
            out.append(f"{m} elements have a vertex off every curve in another subregion "
                       f"(they cross a material discontinuity)")
    else:
        cv = np.asarray(fld.composition(P))
        comp = cv[T]  # (M, 3, m)
        names = list(fld.constituents)
        pd = mesh.point_data
        worst = max((float(np.abs(np.asarray(pd[nm]) - cv[:, j]).max())
                     for j, nm in enumerate(names) if nm in pd), default=0.0)
        if worst > 1e-6:
            out.append(f"the compositions written as point data differ from the model's by "
                       f"up to {worst:.3g}")
    delta = (comp.max(axis=1) - comp.min(axis=1)).max(axis=1)
    if not np.isfinite(delta).all():
        out.append(f"{int((~np.isfinite(delta)).sum())} elements have a non-finite delta")
    dmax = float(np.nanmax(delta))
    if dmax >= threshold:
        out.append(f"delta_max {dmax:.6g} >= threshold {threshold:g} "
                   f"({int((delta >= threshold).sum())} elements)")
    reported = mesh.cell_data.get("delta")
    # hetmesh evaluates in coordinates relative to the domain's centre: allow that rounding
    slack = 1e-9
    if reported is not None and (m := int((np.asarray(reported) < delta - slack).sum())):
        out.append(f"{m} elements report a delta below the recomputed one")
    if st.delta_max < dmax - slack:
        out.append(f"stats.delta_max {st.delta_max:.6g} is below the recomputed {dmax:.6g}")


def _check_angles(P, T, E, markers, infos, fixed, tree, L, A, qfloor, tol, st, out) -> None:
    """Angles and quality above their floors away from sharp input corners; the statistics'
    quality equal to the mesh's."""
    with np.errstate(invalid="ignore", divide="ignore"):
        la, lb, lc = L.T
        cosv = np.stack([(lb ** 2 + lc ** 2 - la ** 2) / (2 * lb * lc),
                         (lc ** 2 + la ** 2 - lb ** 2) / (2 * lc * la),
                         (la ** 2 + lb ** 2 - lc ** 2) / (2 * la * lb)], axis=1)
        ang = np.degrees(np.arccos(np.clip(np.nan_to_num(cosv, nan=1.0), -1, 1)))
        q = (lb + lc - la) * (lc + la - lb) * (la + lb - lc) / (la * lb * lc)
    q = np.nan_to_num(q, nan=0.0)
    if abs(st.q_min - q.min()) > 1e-5 or abs(st.q_avg - q.mean()) > 1e-5:
        out.append(f"stats q_min/q_avg {st.q_min:.6g}/{st.q_avg:.6g} differ from the mesh's "
                   f"{q.min():.6g}/{q.mean():.6g}")
    amin = ang.min(axis=1)
    bad = (amin < A - 1e-6) | (q < qfloor - 1e-9)
    if bad.any():
        exempt = _corner_exempt(P, T, E, markers, infos, fixed, tree, ang, L, A, tol,
                                np.flatnonzero(bad))
        bad_a = (amin < A - 1e-6) & ~exempt
        bad_q = (q < qfloor - 1e-9) & ~exempt
        if bad_a.any():
            out.append(f"{int(bad_a.sum())} triangles below the minimum angle {A:g} away from "
                       f"sharp input corners (smallest {amin[bad_a].min():.2f} degrees)")
        if bad_q.any():
            out.append(f"{int(bad_q.sum())} triangles below the quality floor {qfloor:g} away "
                       f"from sharp input corners (q_min {q[bad_q].min():.3f})")


def _side(pa, pb, p):
    p = np.broadcast_to(np.asarray(p, float), pa.shape)
    d = pb - pa
    return np.sign(d[:, 0] * (p[:, 1] - pa[:, 1]) - d[:, 1] * (p[:, 0] - pa[:, 0]))


def _third_vertex(T: np.ndarray, edges: np.ndarray, n: int) -> np.ndarray:
    """For boundary edges, the vertex of their (one) triangle not on them."""
    keys = []
    third = []
    for i, j, k in ((0, 1, 2), (1, 2, 0), (2, 0, 1)):
        u, v = T[:, i], T[:, j]
        keys.append(np.minimum(u, v) * n + np.maximum(u, v))
        third.append(T[:, k])
    keys = np.concatenate(keys)
    third = np.concatenate(third)
    order = np.argsort(keys, kind="stable")
    ks = keys[order]
    q = np.minimum(edges[:, 0], edges[:, 1]) * n + np.maximum(edges[:, 0], edges[:, 1])
    pos = np.minimum(np.searchsorted(ks, q), len(ks) - 1)
    return third[order[pos]]


def _polygon_area(domain) -> tuple[float, float]:
    """Area of a shapely polygon of the domain (arcs sampled to 1e-7 of the diameter; the
    sampled vertices on the arcs) and the area that sampling may lose."""
    from shapely.geometry import Polygon

    chord = 1e-7 * domain.diameter
    rings = []
    loss = 0.0
    for loop in (domain.outer,) + tuple(domain.holes):
        pts = []
        for curve in loop.curves:
            if hasattr(curve, "radius"):
                r = curve.radius
                dth = 2 * math.acos(max(-1.0, 1 - chord / r)) if chord < r else math.pi / 2
                k = max(2, int(math.ceil(abs(curve.sweep) / dth)) + 1)
                k = min(k, 200_000)
                th = abs(curve.sweep) / (k - 1)
                loss += (k - 1) * 0.5 * r * r * (th - math.sin(th))
            else:
                k = 2
            pts.append(np.asarray(curve.point(np.linspace(0.0, 1.0, k)))[:-1])
        rings.append(np.vstack(pts))
    origin = rings[0][0]
    poly = Polygon(rings[0] - origin, [r - origin for r in rings[1:]])
    return float(poly.area), 1.01 * loss + 1e-12 * domain.diameter ** 2


def _corner_exempt(P, T, E, markers, infos, fixed, tree, ang, L, A, tol, cand) -> np.ndarray:
    """Triangles (among ``cand``) exempt from the angle and quality floors: the smallest
    angle at an input corner whose wedge is below 2A, or the shortest edge joining the two
    curves of such a corner at about the same distance from it."""
    out = np.zeros(len(T), bool)
    if len(fixed) == 0 or len(E) == 0:
        return out
    d, node = tree.query(fixed)
    apexes = np.unique(node[d <= tol])
    # wedges at every apex: sorted tangent directions of the incident curves
    wedges = {}
    for v in apexes:
        rows = np.flatnonzero((E[:, 0] == v) | (E[:, 1] == v))
        dirs, curves = [], []
        for r in rows:
            w = E[r, 1] if E[r, 0] == v else E[r, 0]
            curve = infos[markers[r] - 1].curve
            tv, tw = (float(np.asarray(curve.project(P[[x]]))[0]) for x in (v, w))
            step = tw - tv
            closed = float(np.hypot(*(np.asarray(curve.start) - np.asarray(curve.end)))) <= tol
            if closed and abs(step) > 0.5:
                step = -step
            tg = np.asarray(curve.tangent(np.array([tv])))[0] * (1.0 if step > 0 else -1.0)
            dirs.append(math.atan2(tg[1], tg[0]))
            curves.append(int(markers[r]))
        if len(dirs) < 2:
            continue
        order = np.argsort(dirs)
        th = np.asarray(dirs)[order]
        gaps = np.degrees(np.diff(np.r_[th, th[0] + 2 * math.pi]))
        wedges[int(v)] = (th, gaps, [curves[i] for i in order])
    if not wedges:
        return out
    on_curves: dict[int, set] = {}
    for (u, w), mk in zip(E.tolist(), markers.tolist()):
        on_curves.setdefault(u, set()).add(mk)
        on_curves.setdefault(w, set()).add(mk)
    for i in cand:
        t = T[i]
        k = int(np.argmin(ang[i]))
        v = int(t[k])
        if v in wedges:
            th, gaps, _ = wedges[v]
            other = P[t[(k + 1) % 3]] + P[t[(k + 2) % 3]] - 2 * P[v]
            bis = math.atan2(other[1], other[0])
            j = _gap_of(th, bis)
            if gaps[j] < 2 * A + 1e-9:
                out[i] = True
                continue
        # the shortest edge joins the two curves of a sharp wedge (a seditious edge)
        s = int(np.argmin(L[i]))
        a, b = int(t[(s + 1) % 3]), int(t[(s + 2) % 3])
        ca, cb = on_curves.get(a, set()), on_curves.get(b, set())
        if not ca or not cb:
            continue
        mid = 0.5 * (P[a] + P[b])
        for v, (th, gaps, curves) in wedges.items():
            da, db = P[a] - P[v], P[b] - P[v]
            na, nb = math.hypot(*da), math.hypot(*db)
            if na == 0 or nb == 0 or not (0.5 < na / nb < 2.0):
                continue
            if math.degrees(math.acos(max(-1.0, min(1.0, (da @ db) / (na * nb))))) >= 2 * A:
                continue
            j = _gap_of(th, math.atan2(*(mid - P[v])[::-1]))
            if gaps[j] >= 2 * A + 1e-9:
                continue
            c1, c2 = curves[j], curves[(j + 1) % len(curves)]
            if (c1 in ca and c2 in cb) or (c2 in ca and c1 in cb):
                out[i] = True
                break
    return out


def _gap_of(th: np.ndarray, angle: float) -> int:
    """Index j of the gap (th[j], th[j+1]) (cyclically) containing ``angle``."""
    rel = (angle - th[0]) % (2 * math.pi)
    return int(np.searchsorted(th - th[0], rel, side="right") - 1) % len(th)
