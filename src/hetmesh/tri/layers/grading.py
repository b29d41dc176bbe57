"""Grading between rows: intermediate levels in bands much higher than their neighbours."""

from __future__ import annotations

import logging
from dataclasses import replace

import numpy as np

from ..workset import Context
from .levels import KEY_STRIDE, Levels
from .paths import gradient_profiles
from .pieces import Pieces

log = logging.getLogger(__name__)

GRADE = 0.35  # growth of the band height per unit length where flat zones are subdivided


MAX_RATIO = 1.5  # a piece's end band up to this many times the height wanted is left whole


def grade_levels(ctx: Context, pieces: Pieces, levels: Levels, dprime: float,
                 chord_tol: float):
    """Subdivide the bands between rows that are much higher than their neighbours.

    Where |grad f| tends to 0 (a boundary where f ~ d^2 or d^3, an extremum) consecutive
    levels lie far apart: the band between them is higher than its neighbours and than the
    maximum element size, the rows on either side of it have node steps that do not match
    it, and circumcenter filling plus repair made poor elements there. Here the band
    heights are measured along gradient paths; a band at a piece's end (between its last
    level and a border that is a level curve, or an extremum) whose height H exceeds
    ``MAX_RATIO`` times the height wanted at its ends (the neighbouring band's height, or
    the boundary's own node spacing), and any band above 1.3 x sqrt(3)/2 h_max, gets
    intermediate levels so that the band heights grow
    by ``GRADE`` per unit length from both ends, up to sqrt(3)/2 h_max. The intermediate
    levels are taken on the path of median height; each new row and each row next to a
    subdivided band gets the spacing in f (``dps``) that makes its node step 2/sqrt(3) times
    the mean height of its two bands, and so does a row next to a level that is not dprime
    away (evened out by :func:`piece_levels`); a border level curve gets the node spacing of
    its sub-band (curve spacing caps). hft_ring at 0.1: q_avg of the placement 0.91 -> 0.94,
    repair insertions 614 -> 77. Returns (keys, levs, dps, curve spacing caps)."""
    keys, levs, dps = levels.key, levels.value, levels.dprime
    ncurve = len(ctx.curves)
    spacing = np.full(ncurve, np.inf)
    prof = gradient_profiles(ctx, pieces, dprime)
    if prof is None or len(keys) == 0:
        return levels, spacing
    pid, s, f, gn = prof.path, prof.arc, prof.f, prof.grad_norm
    ppc, pcv, pdir = prof.piece, prof.curve, prof.direction
    nk = len(keys)
    piece_of = np.floor((keys + 2.0) / KEY_STRIDE).astype(np.int64)  # levels lie in (-2, 3)
    kx = np.searchsorted(keys, ppc[pid] * KEY_STRIDE + f, side="right")
    # crossings between consecutive samples of one path
    i = np.flatnonzero((pid[1:] == pid[:-1]) & (kx[1:] != kx[:-1]))
    lo = np.minimum(kx[i], kx[i + 1])
    cnt = np.abs(kx[i + 1] - kx[i])
    ii = np.repeat(i, cnt)
    kk = np.repeat(lo, cnt) + (np.arange(cnt.sum()) - np.repeat(np.cumsum(cnt) - cnt, cnt))
    u = np.clip((levs[kk] - f[ii]) / (f[ii + 1] - f[ii]), 0.0, 1.0)
    cs = s[ii] + u * (s[ii + 1] - s[ii])
    cg = gn[ii] + u * (gn[ii + 1] - gn[ii])
    cpid = pid[ii]
    # the levels a piece really holds: those its paths cross (the level list overshoots)
    if len(kk) == 0:
        return levels, spacing
    first = np.full(pieces.n, nk, np.int64)
    last = np.full(pieces.n, -1, np.int64)
    np.minimum.at(first, ppc[cpid], kk)
    np.maximum.at(last, ppc[cpid], kk)
    # events per path: start (-1), crossings (level index), end (-2); in path order
    starts = np.flatnonzero(np.r_[True, pid[1:] != pid[:-1]])
    ends = np.r_[starts[1:] - 1, len(pid) - 1]
    ep = np.concatenate([pid[starts], cpid, pid[ends]])
    es = np.concatenate([s[starts], cs, s[ends]])
    ek = np.concatenate([np.full(len(starts), -1), kk, np.full(len(ends), -2)])
    eg = np.concatenate([gn[starts], cg, gn[ends]])
    ef = np.concatenate([f[starts], levs[kk], f[ends]])
    o = np.lexsort((es, ep))
    ep, es, ek, eg, ef = ep[o], es[o], ek[o], eg[o], ef[o]
    # a path start or end is a piece end only where f is near the piece's extreme (not where
    # a path meets a boundary transverse to the rows)
    fmin = np.full(pieces.n, np.inf)
    fmax = np.full(pieces.n, -np.inf)
    np.minimum.at(fmin, ppc[pid], f)
    np.maximum.at(fmax, ppc[pid], f)
    pe = ppc[ep]
    lo_span = levs[np.minimum(first[pe], nk - 1)] - fmin[pe]
    hi_span = fmax[pe] - levs[np.maximum(last[pe], 0)]
    at_end = (ek < 0) & ((ef - fmin[pe] <= 0.15 * lo_span) | (fmax[pe] - ef <= 0.15 * hi_span))
    ek = np.where((ek < 0) & ~at_end, -3, ek)  # -3: a path end inside a band
    # consecutive events of a path: a band between levels (or a level and the path's end)
    same = ep[1:] == ep[:-1]
    a, b = ek[:-1][same], ek[1:][same]
    H = (es[1:] - es[:-1])[same]
    bp = ep[:-1][same]
    asc = pdir[bp] > 0
    pcb = ppc[bp]
    # a band id: 2 j + 1 between level j and j + 1 (j = first - 1 / last: the piece's ends)
    lvl_a = np.where(a >= 0, a, -1)
    lvl_b = np.where(b >= 0, b, -1)
    # the level index on the low side of the band (ascending: a, descending: b)
    low = np.where(asc, lvl_a, lvl_b)
    high = np.where(asc, lvl_b, lvl_a)
    low = np.where(low >= 0, low, np.where(high >= 0, high - 1, -10))
    high = np.where(high >= 0, high, low + 1)
    full = ((a >= 0) & (b >= 0)) | ((low == first[pcb] - 1) & (high >= 0)) | \
        ((high == last[pcb] + 1) & (low >= 0))
    full &= (a != -3) & (b != -3) & (high - low == 1) & (low >= first[pcb] - 1) & (high <= last[pcb] + 1)
    if not full.any():
        return levels, spacing
    band = (pcb * (nk + 2) + low + 1)[full]
    Hf, bpf = H[full], bp[full]
    ubands, inv = np.unique(band, return_inverse=True)
    nb = len(ubands)
    medH = np.array([np.median(Hf[inv == j]) for j in range(nb)])
    b_piece = ubands // (nk + 2)
    b_low = ubands % (nk + 2) - 1
    Hmap = dict(zip(ubands.tolist(), medH.tolist()))
    cap_h = np.sqrt(3.0) / 2.0 * ctx.h_max
    cstep = ctx.domain.curve_batch.max_step(chord_tol)

    def end_size(j, upper):
        """The band height wanted at one end of band j: its neighbour's, or the curve's
        spacing at a piece end (a boundary with a chord limit), or free (cap)."""
        p, lw = int(b_piece[j]), int(b_low[j])
        nbr = p * (nk + 2) + (lw + 2 if upper else lw)
        if nbr in Hmap and (lw + 1 <= last[p] if upper else lw >= first[p]):
            return Hmap[nbr]
        # a piece end: the curve the paths that start there start on
        m = np.flatnonzero(inv == j)
        m = m[(pdir[bpf[m]] < 0) if upper else (pdir[bpf[m]] > 0)]
        cur = pcv[bpf[m]]
        st = float(np.median(cstep[cur])) if len(cur) else np.inf
        return min(cap_h, np.sqrt(3.0) / 2.0 * st)

    if log.isEnabledFor(logging.DEBUG):  # (piece, low level, height, wanted at both ends)
        log.debug("bands %s", [(int(b_piece[j]), int(b_low[j]), round(float(medH[j]), 3),
                                round(end_size(j, False), 3), round(end_size(j, True), 3))
                               for j in range(nb)])
    new_l, new_d, new_k, new_p = [], [], [], []
    row_d = {}
    for j in range(nb):
        Hj = medH[j]
        ha, hb = end_size(j, False), end_size(j, True)
        p_, lw = int(b_piece[j]), int(b_low[j])
        inner = first[p_] <= lw and lw + 1 <= last[p_]
        # a band between two levels is split only above the largest element's size (on
        # fgm_plate splitting bands 2.5 x their neighbours' height cost 20 % more elements)
        if (inner or Hj <= MAX_RATIO * min(ha, hb, cap_h)) and Hj <= cap_h * 1.3:
            continue
        # sizes grow by GRADE from both ends: sigma(t) = min(ha + G t, hb + G (H - t), cap)
        t = np.linspace(0.0, Hj, 401)
        sig = np.minimum(np.minimum(ha + GRADE * t, hb + GRADE * (Hj - t)), cap_h)
        N = np.concatenate([[0.0], np.cumsum(0.5 * (1 / sig[1:] + 1 / sig[:-1]) * np.diff(t))])
        m = int(max(1, round(N[-1])))
        if m < 2:
            continue
        pos = np.interp((np.arange(1, m) / m) * N[-1], N, t)  # sub-band boundaries
        # the path of median height: f and |grad f| along it
        mm = np.flatnonzero(inv == j)
        rep = bpf[mm[np.argsort(Hf[mm])[len(mm) // 2]]]
        sel = pid == rep
        ps, pf, pg = s[sel], f[sel], gn[sel]
        # where the band starts on that path: the low level's crossing (or the path start)
        asc_r = pdir[rep] > 0
        if lw >= first[p_]:
            flo = levs[lw]
        else:
            flo = pf[0] if asc_r else pf[-1]
        if asc_r:
            sub_s = (np.interp(flo, pf, ps) if lw >= first[p_] else ps[0]) + pos
        else:  # descending path: f decreases along s
            sub_s = (np.interp(-flo, -pf, ps) if lw >= first[p_] else ps[-1]) - pos
        sub_f = np.interp(sub_s, ps, pf)
        sub_g = np.interp(sub_s, ps, pg)
        hs = np.diff(np.concatenate([[0.0], pos, [Hj]]))  # sub-band heights, low to high
        ok = (np.diff(np.concatenate([[flo], sub_f])) > 1e-12 * max(1.0, abs(flo)))
        ok &= np.isfinite(sub_g) & (sub_g > 1e-12)  # rows need a gradient to follow
        if not ok.all():
            continue
        new_l.append(sub_f)
        new_d.append(sub_g * 0.5 * (hs[:-1] + hs[1:]))
        new_k.append(p_ * KEY_STRIDE + sub_f)
        new_p.append(np.full(len(sub_f), p_, np.int64))
        # the rows bounding the band: their step follows the sub-band next to them
        for lvl, side, h_in in ((lw, 1, hs[0]), (lw + 1, 0, hs[-1])):
            if first[p_] <= lvl <= last[p_]:
                row_d.setdefault(lvl, {})[side] = h_in
        for upper in (False, True):  # a piece end: the border curve's node spacing
            if (lw + 1 > last[p_]) if upper else (lw < first[p_]):
                m_ = np.flatnonzero(inv == j)
                m_ = m_[(pdir[bpf[m_]] < 0) if upper else (pdir[bpf[m_]] > 0)]
                hend = 2.0 / np.sqrt(3.0) * (hs[-1] if upper else hs[0])
                for cur in np.unique(pcv[bpf[m_]]):
                    spacing[cur] = min(spacing[cur], hend)
    # the step of a row next to a subdivided band, or next to a level that is not dprime
    # away in f (evened out by piece_levels), from the heights of its two bands, where
    # that differs from dprime / |grad f| by more than 15 %
    dps = dps.copy()
    for lvl in np.unique(kk):
        p = int(piece_of[lvl])
        nbl = [levs[j] for j in (lvl - 1, lvl + 1) if first[p] <= j <= last[p]]
        odd = any(abs(abs(v - levs[lvl]) - dprime) > 0.01 * dprime for v in nbl)
        if lvl not in row_d and not odd:
            continue
        sides = row_d.get(lvl, {})
        hh = [sides.get(side, Hmap.get(p * (nk + 2) + lvl + side)) for side in (0, 1)]
        hh = [h for h in hh if h is not None]
        if not hh:
            continue
        d = float(np.median(eg[ek == lvl])) * float(np.mean(hh))
        if np.isfinite(d) and d > 0.05 * dps[lvl] and abs(d / dps[lvl] - 1.0) > 0.15:
            dps[lvl] = d
    if not new_l:
        return replace(levels, dprime=dps), spacing
    keys = np.concatenate([keys] + new_k)
    levs = np.concatenate([levs] + new_l)
    dps = np.concatenate([dps] + new_d)
    piece_all = np.concatenate([levels.piece] + new_p)
    o = np.argsort(keys, kind="stable")
    log.info("layers: %d intermediate levels in %d flat bands", len(o) - nk, len(new_l))
    return Levels(piece_all[o], levs[o], dps[o], keys[o]), spacing
