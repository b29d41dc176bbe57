#!/usr/bin/env python
"""The surface-solid mesher's first volume, builtin fill against Gmsh: measure, never assert.

    PYTHONPATH=src python benchmarks/bench_surface_fill.py [--repeats 5]

For examples/l_bracket.toml at delta_0 = 0.2 and 0.1, and a torus (R = 20, r = 8 mm, 96 x 32
quadrilaterals split into 6,144 triangles, written here; metal fraction ((x + 28)/56)^2) at
0.2: the fill alone ("builtin": ``hetmesh.tet.surface_mesh.initial_volume``, the conforming
Delaunay fill of hetmesh.tet.surface_fill, Qhull; "gmsh": the peer, Gmsh's 3D Delaunay of
the input triangles, one thread, as hetmesh used before), its wall time (median of the
repeats) and point and tetrahedron counts; then the whole verified mesh from each fill
(``generate_surface(..., initial=...)``, MMG and the repair as usual): Ne, the minimum and
1st-percentile of the smallest dihedral angles, the mean radius ratio, the size rounds and
the wall time of one run.
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
from hetmesh.testing import torus_surface
from hetmesh.tet.general import orient_positive
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


def gmsh_fill(solid) -> tuple[np.ndarray, np.ndarray]:
    """The peer: Gmsh's 3D Delaunay mesh of the inside of the input triangles (a discrete
    surface per shell, a volume per outer shell with its cavities; one thread, no
    optimisation, no size from the points), hetmesh's first volume before the builtin
    fill: ``(points, tets)``, positive."""
    import gmsh
    V, F = solid.V, solid.F
    gmsh.initialize(readConfigFiles=False, interruptible=False)
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.option.setNumber("General.NumThreads", 1)
        gmsh.option.setNumber("Mesh.Algorithm3D", 1)
        gmsh.option.setNumber("Mesh.Optimize", 0)
        # no size from the surface's points: as few inside points as the recovery needs
        # (MMG sets the sizes next)
        for k in ("MeshSizeExtendFromBoundary", "MeshSizeFromPoints"):
            gmsh.option.setNumber(f"Mesh.{k}", 0)
        gmsh.model.add("hetmesh_surface")
        lab, regions = solid.shells
        tags = {}
        for k in np.unique(lab):  # one discrete surface per shell, its own points
            s = gmsh.model.addDiscreteEntity(2)
            ids = np.unique(F[lab == k])
            gmsh.model.mesh.addNodes(2, s, ids + 1, V[ids].ravel())
            tags[int(k)] = s
        for k in np.unique(lab):
            gmsh.model.mesh.addElementsByType(tags[int(k)], 2, [], (F[lab == k] + 1).ravel())
        for outer, cavities in regions:
            loops = [gmsh.model.geo.addSurfaceLoop([tags[j]]) for j in [outer, *cavities]]
            gmsh.model.geo.addVolume(loops)
        gmsh.model.geo.synchronize()
        gmsh.model.mesh.generate(3)
        tags, xyz, _ = gmsh.model.mesh.getNodes()
        _, enodes = gmsh.model.mesh.getElementsByType(4)
    except Exception as exc:  # noqa: BLE001  (Gmsh raises plain Exceptions)
        raise RuntimeError(f"Gmsh could not fill the surface {solid.source}: "
                           f"{' '.join(str(exc).split())}") from None
    finally:
        gmsh.finalize()
    if not len(enodes):
        raise RuntimeError(f"Gmsh made no tetrahedra inside the surface {solid.source}")
    tags = tags.astype(np.int64)
    index = np.full(int(tags.max()) + 1, -1, dtype=np.int64)
    index[tags] = np.arange(len(tags))
    t = index[enodes.astype(np.int64)].reshape(-1, 4)
    p = xyz.reshape(-1, 3).astype(np.float64)
    used = np.unique(t)
    remap = np.full(len(p), -1, dtype=np.int64)
    remap[used] = np.arange(len(used))
    return p[used], orient_positive(p[used], remap[t])


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=5)
    a = ap.parse_args(argv)
    tmp = Path(tempfile.mkdtemp())
    V, F = torus_surface(20.0, 8.0, 96, 32)
    meshio.write_points_cells(str(tmp / "torus.stl"), V, [("triangle", F)])
    (tmp / "torus.toml").write_text(TORUS)
    models = {"l_bracket": load_model(hetmesh.example_path("l_bracket")),
              "torus": load_model(tmp / "torus.toml")}
    runs = [("l_bracket", 0.2), ("l_bracket", 0.1), ("torus", 0.2)]
    print("| model | fill | fill time (s) | points | tets |")
    print("|---|---|---|---|---|")
    fills = {"builtin": initial_volume, "gmsh": gmsh_fill}
    for name, m in models.items():
        for fill, make in fills.items():
            times = []
            for _ in range(a.repeats):
                t0 = time.perf_counter()
                p, t = make(m.solid)
                times.append(time.perf_counter() - t0)
            print(f"| {name} ({len(m.solid.F)} triangles) | {fill} | "
                  f"{np.median(times):.3f} | {len(p):,} | {len(t):,} |")
    print("\n| model | delta_0 | fill | Ne | dihedral min | 1st pct | mean radius ratio | "
          "size rounds | time (s) |")
    print("|---|---|---|---|---|---|---|---|---|")
    for name, d0 in runs:
        m = models[name]
        for fill, make in fills.items():
            t0 = time.perf_counter()
            r = generate_surface(m.solid, m.material, d0, initial=make)
            dt = time.perf_counter() - t0
            q = quality_summary(r.points, r.tets)
            print(f"| {name} | {d0} | {fill} | {len(r.tets):,} | {q['dihedral_min']:.1f} | "
                  f"{q['dihedral_p1']:.1f} | {q['radius_ratio_mean']:.3f} | "
                  f"{r.info['size_rounds']} | {dt:.2f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
