"""hetmesh.tet.sweep_mmg: the interface triangles follow the bisection repair; the MMG pass
keeps a smooth z-dependent composition's cube verified and better shaped."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from scipy.spatial import Delaunay

import hetmesh
from hetmesh.material import AnalyticField
from hetmesh.tet.api import mesh_model
from hetmesh.tet.columns import column_counts, column_tets, vertex_size
from hetmesh.tet.refine import repair
from hetmesh.tet.sweep_mmg import split_faces
from tet_checks import tet_quality


def _faces(t):
    f = np.concatenate([t[:, [1, 2, 3]], t[:, [0, 2, 3]], t[:, [0, 1, 3]], t[:, [0, 1, 2]]])
    return np.unique(np.sort(f, axis=1), axis=0, return_counts=True)


def test_split_faces_follow_the_repair():
    """The boundary triangles and an inner plane's, split as the repair split their edges,
    are exactly the repaired tetrahedra's faces there (several passes: edges split twice)."""
    field = AnalyticField({"metal": "(x + z) ** 2 / 4"}, ["ceramic", "metal"], dim=3)
    g = np.linspace(0, 1, 6)
    p2 = np.stack(np.meshgrid(g, g), -1).reshape(-1, 2)
    t2 = Delaunay(p2).simplices.astype(np.int64)
    pts, tets, _ = column_tets(p2, t2, column_counts(1.0, vertex_size(p2, t2), ratio=1.25),
                               0.0, 1.0)
    f0, held0 = _faces(tets)
    mid = (np.abs(pts[f0][..., 0] - 0.4) < 1e-12).all(axis=1)  # the plane x = 0.4
    keep = (held0 == 1) | mid
    p, t, _, _, passes, tr = repair(pts, tets, field, 0.05, trace=True)
    assert passes > 1 and len(t) > 2 * len(tets)
    f, m = split_faces(f0[keep], np.arange(keep.sum()), tr.ends, len(pts))
    f1, held1 = _faces(t)
    on = (held1 == 1) | (np.abs(p[f1][..., 0] - 0.4) < 1e-12).all(axis=1)
    assert {tuple(x) for x in np.sort(f, axis=1).tolist()} == \
        {tuple(x) for x in f1[on].tolist()}
    assert len(f) == on.sum()


def test_the_mmg_pass_meets_the_targets_on_the_cube():
    """(x + z)/2 on the unit cube at 0.1: swept, repaired, remeshed by MMG; verified here
    again: positive volumes, delta over the vertices, the cube's faces exact, the targets."""
    f = AnalyticField({"metal": "(x + z) / 2"}, ["ceramic", "metal"], dim=3)
    model = replace(hetmesh.load_model(hetmesh.example_path("unit_cube")), material=f)
    res = mesh_model(model, 0.1)
    assert res.info["placement"] == "swept+repair" and res.info["mmg_rounds"] >= 1
    p, t = np.asarray(res.points), np.asarray(res.tets, np.int64)
    a, b, c, d = (p[t[:, k]] for k in range(4))
    assert (np.linalg.det(np.stack([b - a, c - a, d - a], axis=1)) > 0).all()
    v = (p[:, 0] + p[:, 2]) / 2
    assert (v[t].max(axis=1) - v[t].min(axis=1)).max() < 0.1
    faces, held = _faces(t)
    bnd = p[np.unique(faces[held == 1])]
    assert ((bnd == 0) | (bnd == 1)).any(axis=1).all()
    assert abs(np.abs(np.linalg.det(np.stack([b - a, c - a, d - a], axis=1))).sum() / 6
               - 1.0) < 1e-12
    ang, rr = tet_quality(p, t)
    assert ang.min() >= 10 and np.percentile(ang, 1) >= 20 and rr.mean() >= 0.75
