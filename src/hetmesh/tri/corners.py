"""Small input angles: sharp corners, concentric-shell splits, exemptions (GOR).

Ruppert's refinement cannot reach its angle bound next to an input angle below 60 degrees (two
constraint curves meeting there, e.g. a material discontinuity reaching the boundary at 28
degrees in ``fgm_plate``): every split of one edge at the apex encroaches on the other, and
refining the wedge only shrinks it. The remedies (Ruppert 1995, Shewchuk 2002):

* :func:`sharp_corners` finds those apexes among the fixed vertices;
* :func:`shell_split` splits an edge with one end at such an apex at a power-of-two distance
  from it (concentric shells), so the pieces next to the apex have equal lengths and stop
  encroaching on each other;
* :func:`corner_exempt` leaves alone triangles whose smallest angle is at an input corner
  sharper than twice the angle bound, and triangles whose shortest edge is seditious (joins
  the two curves of a sharp corner at about the same distance from it).
"""

from __future__ import annotations

import numpy as np

from ..mesh import any_corner
from ..metrics import side_lengths, triangle_angles
from .workset import FIXED, Context, WorkSet

__all__ = ["sharp_corners", "shell_split", "corner_exempt"]


def sharp_corners(ws: WorkSet, ctx: Context, limit_deg: float = 60.0) -> np.ndarray:
    """Ids of the fixed vertices where two constraint curves meet inside the domain at less
    than ``limit_deg`` (e.g. a discontinuity reaching the boundary at a small angle)."""
    fixed = np.flatnonzero(ws.vcurve[:ws.n] == FIXED)
    out = []
    for v in fixed:
        other = np.concatenate([ws.E[ws.E[:, 0] == v, 1], ws.E[ws.E[:, 1] == v, 0]])
        if len(other) < 2:
            continue
        d = ws.P[other] - ws.P[v]
        ang = np.sort(np.arctan2(d[:, 1], d[:, 0]))
        gap = np.diff(np.r_[ang, ang[0] + 2 * np.pi])
        mid = ang + 0.5 * gap
        small = gap < np.radians(limit_deg)
        if small.any():
            r = 1e-3 * np.hypot(*d.T).min()
            probe = ws.P[v] + r * np.column_stack([np.cos(mid[small]), np.sin(mid[small])])
            if ctx.inside(probe).any():
                out.append(v)
    return np.array(out, dtype=np.int64)


def shell_split(ws: WorkSet, ctx: Context, sharp: np.ndarray):
    """Where to split constraint edges: the midpoint, except for an edge with one end at a
    sharp corner (``sharp``, from :func:`sharp_corners`), split at the power-of-two distance
    from that corner in [L/3, 2L/3] (concentric shells, Ruppert/Shewchuk): the pieces next
    to a small input angle then have equal lengths and stop encroaching on each other, so
    the splitting ends."""
    if len(sharp) == 0:
        return None

    def where(idx, et):
        tm = 0.5 * (et[:, 0] + et[:, 1])
        ends = np.isin(ws.E[idx], sharp)
        one = ends[:, 0] != ends[:, 1]
        if not one.any():
            return tm
        j = ends[one].argmax(axis=1)  # which end is the apex
        rows = np.flatnonzero(one)
        ta = et[rows, j]
        tb = et[rows, 1 - j]
        length = np.array([ctx.curves[c].length for c in ws.ecurve[idx[rows]]])
        s_far = np.abs(tb - ta) * length
        s = 2.0 ** np.floor(np.log2(2.0 * s_far / 3.0))
        tm[rows] = ta + np.sign(tb - ta) * s / length
        return tm

    return where


def corner_exempt(ws: WorkSet, tris: np.ndarray, ang_deg: float,
                   sharp: np.ndarray | None = None) -> np.ndarray:
    """Triangles whose smallest angle sits at an input corner too sharp to refine (< 2A), and
    triangles whose shortest edge is seditious (see :func:`_seditious`)."""
    out = np.zeros(len(tris), bool)
    if sharp is not None and len(sharp):
        out |= _seditious(ws, tris, sharp)
    fixed = ws.vcurve == FIXED
    touch = np.flatnonzero(any_corner(fixed, tris))
    if touch.size == 0:
        return out
    tt = tris[touch]
    ang = triangle_angles(ws.P, tt)
    total = np.bincount(tt.ravel(), ang.ravel(), minlength=ws.n)
    too_sharp = fixed & (total < 2 * ang_deg - 1e-9)
    vmin = tt[np.arange(len(tt)), ang.argmin(axis=1)]
    out[touch] |= too_sharp[vmin]
    return out


def _seditious(ws: WorkSet, tris: np.ndarray, sharp: np.ndarray) -> np.ndarray:
    """Triangles whose shortest edge joins two curve nodes around a small input angle, at
    about the same distance from its apex (Shewchuk's seditious edges): splitting them
    only shrinks the wedge, which never ends, so they are left as they are."""
    P = ws.P
    k = side_lengths(P, tris).argmin(axis=1)
    r = np.arange(len(tris))
    a, b = tris[r, (k + 1) % 3], tris[r, (k + 2) % 3]
    ca, cb = ws.vcurve[a], ws.vcurve[b]
    cand = np.flatnonzero((ca >= 0) & (cb >= 0) & (ca != cb))
    out = np.zeros(len(tris), bool)
    if len(cand) == 0:
        return out
    a, b, ca, cb = a[cand], b[cand], ca[cand], cb[cand]
    # the curves incident to every sharp corner
    incident = np.zeros((len(sharp), int(ws.ecurve.max()) + 1), bool)
    for i, v in enumerate(sharp):
        incident[i, ws.ecurve[(ws.E == v).any(axis=1)]] = True
    apex = P[sharp]
    mid = 0.5 * (P[a] + P[b])
    j = np.argmin(np.hypot(mid[:, None, 0] - apex[:, 0], mid[:, None, 1] - apex[:, 1]), axis=1)
    c = apex[j]
    da, db = P[a] - c, P[b] - c
    na, nb = np.hypot(*da.T), np.hypot(*db.T)
    with np.errstate(invalid="ignore", divide="ignore"):
        cos = np.einsum("ij,ij->i", da, db) / (na * nb)
        ratio = na / nb
    out[cand] = ((cos > 0.5) & (ratio > 0.5) & (ratio < 2.0)
                 & incident[j, ca] & incident[j, cb])
    return out
