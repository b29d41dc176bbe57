"""Edge collapses that keep a tetrahedral mesh's boundary on its faces.

The remeshed solids (carved sweeps, solids of primitives whose curved faces meet) end with
a few thin tetrahedra at their boundary, where a projection onto the exact surfaces could
not move a vertex all the way. :func:`collapse_edges` removes them by collapsing short
boundary edges: an end ``v`` goes onto the other end ``w`` only where ``w`` lies on every
face ``v`` lies on (:func:`face_incidence`), so the boundary triangles moved stay on their
faces, and only where the boundary afterwards is exactly the faces' triangles less the two
collapsed (:func:`same_boundary`). The points never move; the caller's tests (delta, the
verification's face checks) decide the rest.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from ..mesh import simplex_measures
from .faces import boundary_faces, same_triangles

__all__ = ["face_incidence", "same_boundary", "collapse_edges"]


def face_incidence(n: int, faces: np.ndarray, markers: np.ndarray) -> list[set]:
    """For each of ``n`` points, the set of face markers of the boundary triangles at it
    (empty for an inner point)."""
    inc: list[set] = [set() for _ in range(n)]
    for (a, b, c), m in zip(faces.tolist(), markers.tolist()):
        inc[a].add(m)
        inc[b].add(m)
        inc[c].add(m)
    return inc


def same_boundary(tets: np.ndarray, faces: np.ndarray) -> bool:
    """Whether the boundary triangles of ``tets`` are exactly ``faces`` (as vertex sets)."""
    return same_triangles(boundary_faces(tets)[0], faces)


def collapse_edges(p: np.ndarray, t: np.ndarray, faces: np.ndarray, markers: np.ndarray, *,
                   angle: Callable, bad: Callable, ok: Callable | None = None,
                   keeps: Callable | None = None, passes: int = 64,
                   phase: np.ndarray | None = None, same: Callable | None = None):
    """Boundary edges of the tetrahedra that ``bad(angle(p, t))`` marks collapsed, the
    shortest first, one per pass (at most ``passes``): an end ``v`` onto the other ``w``
    where ``w`` lies on every face ``v`` lies on, and only if the tetrahedra changed have
    positive volumes and a larger smallest ``angle`` than the tetrahedra around ``v`` had,
    pass ``ok(tets)`` (an array of bools, e.g. delta < delta_0), the boundary triangles
    at ``w`` pass ``keeps(faces, markers)`` (the verification's checks of their faces),
    and the boundary is the faces' triangles less the two collapsed.
    ``(tets, faces, markers)``; the points do not move.

    With ``phase`` (a value per tetrahedron, carried to the tetrahedra kept, and returned
    last), ``ok(tets, phase)`` takes the phases too, and ``same(tets, faces, markers,
    phase)`` replaces the check that the boundary is the faces' triangles (``faces`` may
    then hold the interfaces between phases as well, each with a marker of its own, so
    that a vertex collapses only onto one on every interface it is on)."""
    inc = face_incidence(len(p), faces, markers)
    tried: set = set()
    for _ in range(passes):
        ang = angle(p, t)
        worst = np.flatnonzero(bad(ang))
        if not len(worst):
            break
        pairs = {(int(min(a, b)), int(max(a, b))) for tt in t[worst].tolist()
                 for i, a in enumerate(tt) for b in tt[i + 1:] if inc[a] and inc[b]}
        pairs = sorted(pairs - tried,
                       key=lambda e: (float(np.linalg.norm(p[e[0]] - p[e[1]])), e))
        done = False
        for a, b in pairs:
            tried.add((a, b))
            for v, w in ((a, b), (b, a)):
                if not inc[v] <= inc[w]:
                    continue
                star = (t == v).any(axis=1)
                gone = star & (t == w).any(axis=1)
                nt = np.where(t == v, w, t)[~gone]
                ch = np.flatnonzero(star[~gone])
                if not len(ch) or (simplex_measures(p, nt[ch]) <= 0).any():
                    continue
                new = angle(p, nt[ch])
                if (new <= 0).any() or new.min() <= ang[star].min():
                    continue
                nph = None if phase is None else phase[~gone]
                if ok is not None and not (ok(nt[ch]) if phase is None
                                           else ok(nt[ch], nph[ch])).all():
                    continue
                fgone = (faces == v).any(axis=1) & (faces == w).any(axis=1)
                nf = np.where(faces == v, w, faces)[~fgone]
                nm = markers[~fgone]
                at = (nf == w).any(axis=1)
                if keeps is not None and not keeps(nf[at], nm[at]):
                    continue
                if not (same_boundary(nt, nf) if same is None else same(nt, nf, nm, nph)):
                    continue
                t, faces, markers, phase = nt, nf, nm, nph
                inc[w] |= inc[v]
                inc[v] = set()
                done = True
                break
            if done:
                break
        if not done:
            break
    return (t, faces, markers) if phase is None else (t, faces, markers, phase)
