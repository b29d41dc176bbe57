"""Solids of primitives on the plain path whose boundary vertices MMG left where the
projection could not move them in full (next to a tetrahedron the move would flatten): the
mesh still verifies, its planar faces exact. Both models failed verification before the
plane-only moves and the collapses of such vertices between the size rounds."""

from __future__ import annotations

import numpy as np
import pytest

from hetmesh.io.model import load_model
from hetmesh.tet.api import mesh_model
from hetmesh.tet.quality import min_dihedral

#: a cylinder with a spherical cavity inside, graded along its axis
CAVITY = """
[solid]
type = "cylinder"
center = [0, 0]
radius = 1
from = 0
to = 2

[[solid.subtract]]
type = "sphere"
center = [0, 0, 1]
radius = 0.8
name = "cavity"

[material]
constituents = ["ceramic", "metal"]

[material.composition]
metal = "0.2 + 0.2*z"
"""

#: a box with a spherical pocket at a corner
CORNER = """
[solid]
type = "box"
min = [0, 0, 0]
max = [2, 1, 1]

[[solid.subtract]]
type = "sphere"
center = [2, 1, 1]
radius = 0.4
name = "pocket"

[material]
constituents = ["ceramic", "metal"]

[material.composition]
metal = "0.3*x"
"""


@pytest.mark.parametrize("text, planes", [
    pytest.param(CAVITY, {"bottom": (2, 0.0), "top": (2, 2.0)}, marks=pytest.mark.slow),
    (CORNER, {"xmin": (0, 0.0), "zmax": (2, 1.0), "ymax": (1, 1.0)}),
], ids=["cavity", "corner"])
def test_plane_faces_stay_exact(tmp_path, text, planes):
    path = tmp_path / "m.toml"
    path.write_text(text, encoding="utf-8")
    res = mesh_model(load_model(path), 0.2)
    p, t = res.points, res.tets.astype(np.int64)
    a, b, c, d = (p[t[:, k]] for k in range(4))
    assert (np.linalg.det(np.stack([b - a, c - a, d - a], axis=1)) > 0).all()
    names = dict(enumerate(res.face_names, start=1))
    for name, (axis, value) in planes.items():
        tri = res.faces[np.array([names[k] == name for k in res.face_markers])]
        assert len(tri) and (p[tri][..., axis] == value).all(), name
    assert min_dihedral(p, t).min() >= 10.0
