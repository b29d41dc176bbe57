#!/usr/bin/env python
"""The surface-solid mesher's first volume, builtin fill against Gmsh: measure, never assert.

    PYTHONPATH=src python benchmarks/bench_surface_fill.py [--repeats 5]

For examples/l_bracket.toml at delta_0 = 0.2 and 0.1, and a torus (R = 20, r = 8 mm, 96 x 32
quadrilaterals split into 6,144 triangles, written here; metal fraction ((x + 28)/56)^2) at
0.2: the fill alone (``hetmesh.tet.surface_mesh.initial_volume``, "builtin": the conforming
Delaunay fill of hetmesh.tet.surface_fill, Qhull; "gmsh": Gmsh's 3D Delaunay, one thread),
its wall time (median of the repeats) and point and tetrahedron counts; then the whole
verified mesh from each fill (``generate_surface(..., fill=...)``, MMG and the repair as
usual): Ne, the minimum and 1st-percentile of the smallest dihedral angles, the mean radius
ratio, the size rounds and the wall time of one run.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import meshio
import numpy as np

import hetmesh
from hetmesh.io.model import load_model
from hetmesh.tet.quality import quality_summary
from hetmesh.tet.surface_mesh import generate_surface, initial_volume

TORUS = """
[solid]
type = "surface"
file = "torus.stl"

[material]
constituents = ["ceramic", "metal"]

[material.composition]
metal = "((x + 28)/56)**2"
"""


def torus(R=20.0, r=8.0, nu=96, nv=32):
    """The torus' points and outward triangles (each quadrilateral of the grid split in
    two)."""
    u = 2 * np.pi * np.arange(nu) / nu
    v = 2 * np.pi * np.arange(nv) / nv
    U, W = np.meshgrid(u, v, indexing="ij")
    V = np.c_[((R + r * np.cos(W)) * np.cos(U)).ravel(),
              ((R + r * np.cos(W)) * np.sin(U)).ravel(), (r * np.sin(W)).ravel()]
    i, j = np.meshgrid(np.arange(nu), np.arange(nv), indexing="ij")
    a = (i * nv + j).ravel()
    b = (((i + 1) % nu) * nv + j).ravel()
    c = (((i + 1) % nu) * nv + (j + 1) % nv).ravel()
    d = (i * nv + (j + 1) % nv).ravel()
    return V, np.r_[np.c_[a, b, c], np.c_[a, c, d]]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=5)
    a = ap.parse_args(argv)
    tmp = Path(tempfile.mkdtemp())
    V, F = torus()
    meshio.write_points_cells(str(tmp / "torus.stl"), V, [("triangle", F)])
    (tmp / "torus.toml").write_text(TORUS)
    models = {"l_bracket": load_model(hetmesh.example_path("l_bracket")),
              "torus": load_model(tmp / "torus.toml")}
    runs = [("l_bracket", 0.2), ("l_bracket", 0.1), ("torus", 0.2)]
    print("| model | fill | fill time (s) | points | tets |")
    print("|---|---|---|---|---|")
    for name, m in models.items():
        for fill in ("builtin", "gmsh"):
            times = []
            for _ in range(a.repeats):
                t0 = time.perf_counter()
                p, t = initial_volume(m.solid, fill)
                times.append(time.perf_counter() - t0)
            print(f"| {name} ({len(m.solid.F)} triangles) | {fill} | "
                  f"{np.median(times):.3f} | {len(p):,} | {len(t):,} |")
    print("\n| model | delta_0 | fill | Ne | dihedral min | 1st pct | mean radius ratio | "
          "size rounds | time (s) |")
    print("|---|---|---|---|---|---|---|---|---|")
    for name, d0 in runs:
        m = models[name]
        for fill in ("builtin", "gmsh"):
            t0 = time.perf_counter()
            r = generate_surface(m.solid, m.material, d0, fill=fill)
            dt = time.perf_counter() - t0
            q = quality_summary(r.points, r.tets)
            print(f"| {name} | {d0} | {fill} | {len(r.tets):,} | {q['dihedral_min']:.1f} | "
                  f"{q['dihedral_p1']:.1f} | {q['radius_ratio_mean']:.3f} | "
                  f"{r.info['size_rounds']} | {dt:.2f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
