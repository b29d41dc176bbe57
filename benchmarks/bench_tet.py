#!/usr/bin/env python
"""hetmesh tetrahedral benchmarks: measure, never assert.

    PYTHONPATH=src python benchmarks/bench_tet.py              # unit_cube at 0.1 and 0.05
    PYTHONPATH=src python benchmarks/bench_tet.py --quick      # 0.1 only, 1 repeat
    PYTHONPATH=src python benchmarks/bench_tet.py --big        # also a ~1M-tetrahedron run
                                                               # (delta_0 = 0.021, no peers)

For each threshold delta_0, on unit_cube (the cube [0, 1]^3, metal fraction (1 - z)^2):

* hetmesh: Ne, Ne / N_iso3 (N_iso3 = 6 sqrt(2) * integral |grad f|^3 dV / delta_0^3, the
  number of regular tetrahedra of edge delta_0 / |grad f|), delta_max, the minimum and
  1st-percentile (per-element minimum) dihedral angle, the mean radius ratio 3 r_in / R_circ,
  wall time (median of the repeats);
* Gmsh 3D (peer, GPL, optional): size field s delta_0 / |grad f| (capped at the cube's
  side), s lowered by 0.85 from 1 until its delta_max < delta_0; the same figures for the
  first valid s, and the s-search trace;
* MMG 3D through mmgpy (peer): remeshing a coarse cube to the size s delta_0 / |grad f| (two
  passes, the size re-evaluated at the new vertices), s lowered likewise.

With ``--sphere`` (or ``--sphere-only``), also examples/graded_sphere.toml (an eighth of the
hollow sphere 10 <= r <= 20, metal fraction ((r - 10)/10)^2) at delta_0 = 0.2 and 0.1,
meshed by the general-solid mesher (hetmesh.tet.general), and Gmsh's OpenCASCADE model of
the same octant with the size field s delta_0 / |grad f| (capped at 5, the sphere's
curvature on: Mesh.MeshSizeFromCurvature = 12 elements per 2 pi) at delta_0 = 0.2 only.

With ``--surface`` (or ``--surface-only``), also examples/l_bracket.toml (an L bracket given
by its STL surface, 412 triangles, metal fraction ((x + z)/50)^2) at delta_0 = 0.2, 0.1 and
0.05, meshed by the surface mesher (hetmesh.tet.surface_mesh: the builtin fill of
hetmesh.tet.surface_fill, then MMG remeshes), and Gmsh alone on the same STL (its
surfaces classified at 40 degrees and reparametrised, the size field s delta_0 / |grad f|
capped at 10, s lowered likewise) at 0.2 and 0.1.

Targets (PASS/FAIL columns): Ne <= 2.0 x N_iso3, min dihedral >= 10, 1st percentile >= 20,
mean radius ratio >= 0.75. Every ratio is taken against peers measured in the same run.

    PYTHONPATH=src python benchmarks/bench_tet.py --examples   # only the table below

Then every 3D example (``hetmesh.tet.api.mesh_model``, verified) at the tests' threshold 0.3
and at 0.1: the placement, Ne, Ne / N_iso3, delta_max, the quality figures, wall time (median
of the repeats), the quality targets' PASS/FAIL and the sha1 of the mesh's points and
tetrahedra (a change of mesh shows as a change of fingerprint).
"""

from __future__ import annotations

import argparse
import logging
import os
import statistics
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
try:
    import hetmesh  # noqa: F401
except ImportError:
    sys.path.insert(0, str(ROOT / "src"))

from hetmesh.material import AnalyticField  # noqa: E402
from hetmesh.mesh import simplex_measures  # noqa: E402
from hetmesh.metrics import delta_vertices  # noqa: E402
from hetmesh.tet import box, generate_tets, n_iso3, quality_summary  # noqa: E402

logging.getLogger("hetmesh").setLevel(logging.WARNING)

FORMULA = "(1 - z)**2"


def unit_cube():
    field = AnalyticField({"metal": FORMULA}, ["ceramic", "metal"], dim=3)
    return box((0, 0, 0), (1, 1, 1)), field


def figures(points, tets, field, d0, niso, wall):
    q = quality_summary(points, tets)
    delta = delta_vertices(field.composition(points), tets)
    return {"Ne": len(tets), "ratio": len(tets) / niso, "delta_max": float(delta.max()),
            "n_bad": int((delta >= d0).sum()),
            "vol_min": float(simplex_measures(points, tets).min()),
            **q, "time": wall}


#: the thresholds of the examples' table
EXAMPLE_THRESHOLDS = (0.3, 0.1)


def fingerprint(points, tets) -> str:
    import hashlib
    h = hashlib.sha1(np.ascontiguousarray(points, dtype=np.float64).tobytes())
    h.update(np.ascontiguousarray(tets, dtype=np.int64).tobytes())
    return h.hexdigest()[:12]


def examples_table(repeats: int) -> None:
    """Every 3D example at :data:`EXAMPLE_THRESHOLDS`: figures, targets, fingerprint."""
    from hetmesh.tet.api import mesh_model

    paths = sorted(p for p in (ROOT / "examples").glob("*.toml")
                   if getattr(hetmesh.load_model(p), "dim", 2) == 3)
    print("\n3D examples (mesh_model, verified); targets: dihedral min >= 10, p1 >= 20, "
          "mean radius ratio >= 0.75")
    print(f"  {'example':<16} {'d0':>4} {'placement':<13} {'Ne':>9} {'Ne/Niso3':>8} "
          f"{'dmax':>8} {'dih_min':>7} {'dih_p1':>7} {'rr_mean':>7} {'time_s':>7}   "
          f"min/p1/rr  sha1")
    for path in paths:
        model = hetmesh.load_model(path)
        for d0 in EXAMPLE_THRESHOLDS:
            times = []
            for _ in range(repeats):
                t0 = time.perf_counter()
                res = mesh_model(model, d0)
                times.append(time.perf_counter() - t0)
            q = quality_summary(res.points, res.tets)
            niso = n_iso3(model.solid, model.material, d0)
            ok = lambda b: "PASS" if b else "FAIL"  # noqa: E731
            print(f"  {path.stem:<16} {d0:>4} {res.info['placement']:<13} {len(res.tets):>9,} "
                  f"{len(res.tets) / niso:>8.2f} {float(res.delta.max()):>8.5f} "
                  f"{q['dihedral_min']:>7.2f} {q['dihedral_p1']:>7.2f} "
                  f"{q['radius_ratio_mean']:>7.3f} {statistics.median(times):>7.2f}   "
                  f"{ok(q['dihedral_min'] >= 10)} {ok(q['dihedral_p1'] >= 20)} "
                  f"{ok(q['radius_ratio_mean'] >= 0.75)}  {fingerprint(res.points, res.tets)}",
                  flush=True)


def run_hetmesh(solid, field, d0, niso, repeats):
    times, res = [], None
    for _ in range(repeats):
        t0 = time.perf_counter()
        res = generate_tets(solid, field, d0)
        times.append(time.perf_counter() - t0)
    return figures(res.points, res.tets, field, d0, niso, statistics.median(times))


def _size(field, s, d0, cap):
    def h(p):
        g = np.linalg.norm(field.gradient(p), axis=2).max(axis=1)
        with np.errstate(divide="ignore"):
            return np.minimum(s * d0 / g, cap)
    return h


def gmsh_cube(field, s, d0, cap=1.0, threads=1):
    import gmsh
    h = _size(field, s, d0, cap)
    gmsh.initialize(readConfigFiles=False)
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.option.setNumber("General.NumThreads", threads)
        gmsh.model.add("cube")
        gmsh.model.occ.addBox(0, 0, 0, 1, 1, 1)
        gmsh.model.occ.synchronize()
        for k in ("MeshSizeExtendFromBoundary", "MeshSizeFromPoints", "MeshSizeFromCurvature"):
            gmsh.option.setNumber(f"Mesh.{k}", 0)
        gmsh.option.setNumber("Mesh.MeshSizeMax", cap)
        gmsh.model.mesh.setSizeCallback(
            lambda dim, tag, x, y, z, lc: float(h(np.array([[x, y, z]]))[0]))
        t0 = time.perf_counter()
        gmsh.model.mesh.generate(3)
        wall = time.perf_counter() - t0
        tags, xyz, _ = gmsh.model.mesh.getNodes()
        _, en = gmsh.model.mesh.getElementsByType(4)
        pts = xyz.reshape(-1, 3)
        index = np.zeros(int(tags.max()) + 1, dtype=np.int64)
        index[tags.astype(np.int64)] = np.arange(len(tags))
        tets = index[en.astype(np.int64)].reshape(-1, 4)
    finally:
        gmsh.finalize()
    v = simplex_measures(pts, tets)
    tets[v < 0] = tets[v < 0][:, [0, 1, 3, 2]]
    return pts, tets, wall


def sphere_model():
    from hetmesh.io.model import load_model
    m = load_model(hetmesh.example_path("graded_sphere"))
    return m


def run_sphere(m, d0, niso, repeats):
    from hetmesh.tet.api import mesh_model
    times, res = [], None
    for _ in range(repeats):
        t0 = time.perf_counter()
        res = mesh_model(m, d0)
        times.append(time.perf_counter() - t0)
    out = figures(res.points, res.tets, m.material, d0, niso, statistics.median(times))
    out["rounds"] = res.info.get("size_rounds")
    return out


def gmsh_sphere(field, s, d0, cap=5.0, threads=1):
    import gmsh
    h = _size(field, s, d0, cap)
    gmsh.initialize(readConfigFiles=False)
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.option.setNumber("General.NumThreads", threads)
        gmsh.model.add("sphere")
        occ = gmsh.model.occ
        outer, inner = occ.addSphere(0, 0, 0, 20), occ.addSphere(0, 0, 0, 10)
        shell, _ = occ.cut([(3, outer)], [(3, inner)])
        octant = occ.addBox(0, 0, 0, 20, 20, 20)
        occ.intersect(shell, [(3, octant)])
        occ.synchronize()
        for k in ("MeshSizeExtendFromBoundary", "MeshSizeFromPoints"):
            gmsh.option.setNumber(f"Mesh.{k}", 0)
        gmsh.option.setNumber("Mesh.MeshSizeFromCurvature", 12)
        gmsh.option.setNumber("Mesh.MeshSizeMax", cap)
        gmsh.model.mesh.setSizeCallback(
            lambda dim, tag, x, y, z, lc: min(lc, float(h(np.array([[x, y, z]]))[0])))
        t0 = time.perf_counter()
        gmsh.model.mesh.generate(3)
        wall = time.perf_counter() - t0
        tags, xyz, _ = gmsh.model.mesh.getNodes()
        _, en = gmsh.model.mesh.getElementsByType(4)
        pts = xyz.reshape(-1, 3)
        index = np.zeros(int(tags.max()) + 1, dtype=np.int64)
        index[tags.astype(np.int64)] = np.arange(len(tags))
        tets = index[en.astype(np.int64)].reshape(-1, 4)
    finally:
        gmsh.finalize()
    v = simplex_measures(pts, tets)
    tets[v < 0] = tets[v < 0][:, [0, 1, 3, 2]]
    return pts, tets, wall


def sphere_section(a, head):
    m = sphere_model()
    print("\ngraded_sphere (octant of the hollow sphere a = 10, b = 20), general-solid mesher")
    for d0 in (0.2, 0.1):
        niso = n_iso3(m.solid, m.material, d0, n=96)
        print(f"\ndelta_0 = {d0}: N_iso3 = {niso:,.0f}")
        print(head)
        ours = run_sphere(m, d0, niso, 1 if a.quick else a.repeats)
        print(row("hetmesh", ours) + f"   size rounds {ours['rounds']}")
        if a.no_peers or d0 < 0.2:
            continue
        fig, trace = search(gmsh_sphere, m.material, d0, niso)
        print(row("gmsh", fig))
        print(f"  {'':<10} s-search (s, Ne, violators): "
              + ", ".join(str(tuple(round(x, 3) if isinstance(x, float) else x
                                    for x in tr)) for tr in trace))
        if fig is not None:
            print(f"  {'':<10} hetmesh / gmsh: elements {ours['Ne'] / fig['Ne']:.3f}, "
                  f"time {ours['time'] / fig['time']:.3f}")


def _kuhn_cube(n=4):
    g = np.linspace(0, 1, n + 1)
    p = np.stack(np.meshgrid(g, g, g, indexing="ij"), axis=-1).reshape(-1, 3)

    def vid(i, j, k):
        return (i * (n + 1) + j) * (n + 1) + k
    i, j, k = [a.ravel() for a in np.meshgrid(*(np.arange(n),) * 3, indexing="ij")]
    c = np.stack([vid(i + a, j + b, k + cc) for a in (0, 1) for b in (0, 1) for cc in (0, 1)],
                 axis=1)  # corner (a, b, c) -> column 4a + 2b + c
    paths = [(0, 4, 6, 7), (0, 4, 5, 7), (0, 2, 6, 7), (0, 2, 3, 7), (0, 1, 5, 7), (0, 1, 3, 7)]
    t = np.concatenate([c[:, list(pp)] for pp in paths])
    v = simplex_measures(p, t)
    t[v < 0] = t[v < 0][:, [0, 1, 3, 2]]
    return p, t


def mmg_cube(field, s, d0, cap=1.0):
    import mmgpy
    h = _size(field, s, d0, cap)
    p, t = _kuhn_cube()
    t0 = time.perf_counter()
    for _ in range(2):
        m = mmgpy.MmgMesh3D(np.ascontiguousarray(p), np.ascontiguousarray(t, dtype=np.int32))
        m.set_field("metric", h(p).reshape(-1, 1))
        m.remesh(verbose=-1, hausd=0.01, hgrad=1.3)
        p, t = m.get_vertices(), m.get_tetrahedra().astype(np.int64)
    wall = time.perf_counter() - t0
    v = simplex_measures(p, t)
    t[v < 0] = t[v < 0][:, [0, 1, 3, 2]]
    return p, t, wall


def gmsh_surface(field, s, d0, cap=10.0, threads=1):
    """Gmsh alone on examples/l_bracket.stl: surfaces classified (40 degrees), reparametrised
    and remeshed with the volume to the size field."""
    import gmsh
    h = _size(field, s, d0, cap)
    gmsh.initialize(readConfigFiles=False)
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.option.setNumber("General.NumThreads", threads)
        gmsh.model.add("surface")
        gmsh.merge(str(hetmesh.example_path("l_bracket").with_suffix(".stl")))
        gmsh.model.mesh.classifySurfaces(40 * np.pi / 180, True, True, np.pi)
        gmsh.model.mesh.createGeometry()
        loop = gmsh.model.geo.addSurfaceLoop([e[1] for e in gmsh.model.getEntities(2)])
        gmsh.model.geo.addVolume([loop])
        gmsh.model.geo.synchronize()
        for k in ("MeshSizeExtendFromBoundary", "MeshSizeFromPoints"):
            gmsh.option.setNumber(f"Mesh.{k}", 0)
        gmsh.option.setNumber("Mesh.MeshSizeMax", cap)
        gmsh.model.mesh.setSizeCallback(
            lambda dim, tag, x, y, z, lc: min(lc, float(h(np.array([[x, y, z]]))[0])))
        t0 = time.perf_counter()
        gmsh.model.mesh.generate(3)
        wall = time.perf_counter() - t0
        tags, xyz, _ = gmsh.model.mesh.getNodes()
        _, en = gmsh.model.mesh.getElementsByType(4)
        pts = xyz.reshape(-1, 3)
        index = np.zeros(int(tags.max()) + 1, dtype=np.int64)
        index[tags.astype(np.int64)] = np.arange(len(tags))
        tets = index[en.astype(np.int64)].reshape(-1, 4)
    finally:
        gmsh.finalize()
    used = np.unique(tets)
    remap = np.zeros(len(pts), dtype=np.int64)
    remap[used] = np.arange(len(used))
    pts, tets = pts[used], remap[tets]
    v = simplex_measures(pts, tets)
    tets[v < 0] = tets[v < 0][:, [0, 1, 3, 2]]
    return pts, tets, wall


def surface_section(a, head):
    from hetmesh.io.model import load_model
    m = load_model(hetmesh.example_path("l_bracket"))
    print("\nl_bracket (an L bracket from its STL surface, 412 triangles), surface mesher")
    for d0 in (0.2, 0.1, 0.05):
        niso = n_iso3(m.solid, m.material, d0, n=96)
        print(f"\ndelta_0 = {d0}: N_iso3 = {niso:,.0f}")
        print(head)
        ours = run_sphere(m, d0, niso, 1 if a.quick else a.repeats)
        print(row("hetmesh", ours) + f"   size rounds {ours['rounds']}")
        if a.no_peers or d0 < 0.1:
            continue
        fig, trace = search(gmsh_surface, m.material, d0, niso)
        print(row("gmsh", fig))
        print(f"  {'':<10} s-search (s, Ne, violators): "
              + ", ".join(str(tuple(round(x, 3) if isinstance(x, float) else x
                                    for x in tr)) for tr in trace))
        if fig is not None:
            print(f"  {'':<10} hetmesh / gmsh: elements {ours['Ne'] / fig['Ne']:.3f}, "
                  f"time {ours['time'] / fig['time']:.3f}")


def search(peer, field, d0, niso, steps=14):
    trace, s = [], 1.0
    for _ in range(steps):
        try:
            p, t, wall = peer(field, s, d0)
        except Exception as exc:  # a peer failing is a row, not a crash
            trace.append((s, f"ERROR {type(exc).__name__}: {exc}".splitlines()[0]))
            return None, trace
        fig = figures(p, t, field, d0, niso, wall)
        trace.append((s, fig["Ne"], fig["n_bad"]))
        if fig["delta_max"] < d0:
            fig["s"] = s
            return fig, trace
        s *= 0.85
    return None, trace


def row(name, f):
    if f is None:
        return f"  {name:<10} no delta-valid mesh found"
    ok = lambda b: "PASS" if b else "FAIL"  # noqa: E731
    return (f"  {name:<10} {f['Ne']:>9,} {f['ratio']:>7.3f} {f['delta_max']:>9.5f} "
            f"{f['dihedral_min']:>7.2f} {f['dihedral_p1']:>7.2f} {f['radius_ratio_mean']:>7.3f} "
            f"{f['time']:>8.2f}   {ok(f['ratio'] <= 2.0)} {ok(f['dihedral_min'] >= 10)} "
            f"{ok(f['dihedral_p1'] >= 20)} {ok(f['radius_ratio_mean'] >= 0.75)}"
            + (f"   s={f['s']:.3f}" if "s" in f else ""))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--big", action="store_true", help="also a ~1M-tetrahedron hetmesh run")
    ap.add_argument("--no-peers", action="store_true")
    ap.add_argument("--examples", action="store_true",
                    help="only the table of the 3D examples")
    ap.add_argument("--no-examples", action="store_true",
                    help="without the table of the 3D examples")
    ap.add_argument("--sphere", action="store_true", help="also examples/graded_sphere.toml")
    ap.add_argument("--sphere-only", action="store_true", help="graded_sphere.toml only")
    ap.add_argument("--surface", action="store_true", help="also examples/l_bracket.toml")
    ap.add_argument("--surface-only", action="store_true", help="l_bracket.toml only")
    a = ap.parse_args(argv)
    if a.examples:
        print(f"hetmesh from {Path(hetmesh.__file__).parent}; load average "
              f"{os.getloadavg()[0]:.2f}")
        examples_table(1 if a.quick else a.repeats)
        print(f"\nload average at the end {os.getloadavg()[0]:.2f}")
        return 0
    thresholds = [0.1] if a.quick else [0.1, 0.05]
    repeats = 1 if a.quick else a.repeats
    solid, field = unit_cube()
    print(f"hetmesh {getattr(hetmesh, '__version__', '?')} from {Path(hetmesh.__file__).parent}; "
          f"load average {os.getloadavg()[0]:.2f}")
    only = a.sphere_only or a.surface_only
    print(("" if only else "unit_cube, f = (1 - z)^2; ")
          + "targets: Ne/N_iso3 <= 2.0, dihedral min >= 10, p1 >= 20, mean radius ratio "
          ">= 0.75")
    head = (f"  {'mesher':<10} {'Ne':>9} {'Ne/Niso3':>7} {'dmax':>9} {'dih_min':>7} "
            f"{'dih_p1':>7} {'rr_mean':>7} {'time_s':>8}   economy/min/p1/rr")
    if only:
        thresholds = []
    for d0 in thresholds:
        niso = n_iso3(solid, field, d0, n=96)
        print(f"\ndelta_0 = {d0}: N_iso3 = {niso:,.0f}")
        print(head)
        ours = run_hetmesh(solid, field, d0, niso, repeats)
        print(row("hetmesh", ours))
        if a.no_peers:
            continue
        for name, peer in (("gmsh", gmsh_cube), ("mmg", mmg_cube)):
            fig, trace = search(peer, field, d0, niso)
            print(row(name, fig))
            print(f"  {'':<10} s-search (s, Ne, violators): "
                  + ", ".join(str(tuple(round(x, 3) if isinstance(x, float) else x
                                        for x in tr)) for tr in trace))
            if fig is not None:
                print(f"  {'':<10} hetmesh / {name}: elements {ours['Ne'] / fig['Ne']:.3f}, "
                      f"time {ours['time'] / fig['time']:.3f}")
    if a.sphere or a.sphere_only:
        sphere_section(a, head)
    if a.surface or a.surface_only:
        surface_section(a, head)
    if a.big:
        d0 = 0.021  # about 1,000,000 tetrahedra
        niso = n_iso3(solid, field, d0, n=96)
        t0 = time.perf_counter()
        res = generate_tets(solid, field, d0)
        wall = time.perf_counter() - t0
        print(f"\nbig run, delta_0 = {d0}: N_iso3 = {niso:,.0f}")
        print(head)
        print(row("hetmesh", figures(res.points, res.tets, field, d0, niso, wall)))
        import resource
        rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1e6  # kB -> GB
        print(f"  peak memory (max RSS) {rss:.2f} GB")
    if not (a.no_examples or only):
        examples_table(repeats)
    print(f"\nload average at the end {os.getloadavg()[0]:.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
