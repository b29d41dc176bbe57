#!/usr/bin/env python
"""Quality of swept + repaired tetrahedral meshes (compositions varying along the sweep):
measure, never assert.

    PYTHONPATH=src python benchmarks/bench_sweep_quality.py [--repeats N]

For examples/seamed_plate_z.toml at delta_0 = 0.2, 0.1, 0.05, the unit cube with metal
fraction (x + z)/2 at 0.1 and 0.05, and a quarter ring bonded at r = 25 (the ring of
tests/test_interfaces3d.py: 20 <= r <= 30, 10 high, `0.5 + 0.45 sin(6 theta)` inside,
`0.3 + 0.02 z` outside) at 0.2 and 0.1, each without the MMG pass after the repair
(hetmesh.tet.sweep_mmg; "repair") and with it ("mmg", the default): Ne, Ne / N_iso3,
delta_max, the minimum and 1st-percentile dihedral angle, the mean radius ratio
3 r_in / R_circ, the wall time (median of the repeats) and the sha1 of the mesh's points
and tetrahedra.
"""

from __future__ import annotations

import argparse
import hashlib
import logging
import statistics
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
try:
    import hetmesh
except ImportError:
    sys.path.insert(0, str(ROOT / "src"))
    import hetmesh

from hetmesh.material import AnalyticField  # noqa: E402
from hetmesh.tet import n_iso3, quality_summary  # noqa: E402

logging.getLogger("hetmesh").setLevel(logging.WARNING)


def fingerprint(points, tets) -> str:
    h = hashlib.sha1(np.ascontiguousarray(points, dtype=np.float64).tobytes())
    h.update(np.ascontiguousarray(tets, dtype=np.int64).tobytes())
    return h.hexdigest()[:12]


RING = """
[model]
name = "bonded_ring"

[solid]
type = "revolution"
angle = 90

[domain.outer]
start = [20, 0]
path = [{ to = [25, 0], name = "bottom" }, { to = [30, 0], name = "bottom" },
        { to = [30, 10], name = "outside" }, { to = [25, 10], name = "top" },
        { to = [20, 10], name = "top" }, { to = [20, 0], name = "inside" }]

[[domain.interfaces]]
name = "bond"
start = [25, 0]
path = [{ to = [25, 10] }]

[material]
constituents = ["ceramic", "metal"]

[material.composition]
metal = "where(x**2 + y**2 < 625, 0.5 + 0.45*sin(6*atan2(y, x)), 0.3 + 0.02*z)"
"""


def cases(tmp: Path):
    from hetmesh.tet.api import mesh_model

    plate = hetmesh.load_model(ROOT / "examples" / "seamed_plate_z.toml")
    for d0 in (0.2, 0.1, 0.05):
        yield "seamed_plate_z", d0, plate.solid, plate.material, \
            lambda d=d0: mesh_model(plate, d)
    f = AnalyticField({"metal": "(x + z) / 2"}, ["ceramic", "metal"], dim=3)
    cube = replace(hetmesh.load_model(ROOT / "examples" / "unit_cube.toml"), material=f)
    for d0 in (0.1, 0.05):
        yield "cube (x+z)/2", d0, cube.solid, f, lambda d=d0: mesh_model(cube, d)
    (tmp / "bonded_ring.toml").write_text(RING)
    ring = hetmesh.load_model(tmp / "bonded_ring.toml")
    for d0 in (0.2, 0.1):
        yield "bonded ring", d0, ring.solid, ring.material, lambda d=d0: mesh_model(ring, d)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=1)
    a = ap.parse_args(argv)
    from hetmesh.tet import extrude, revolve

    print(f"  {'model':<16} {'d0':>5} {'pass':<6} {'Ne':>8} {'Ne/Niso3':>8} {'dmax':>8} "
          f"{'dih_min':>7} {'dih_p1':>7} {'rr_mean':>7} {'time_s':>7}  sha1")
    with tempfile.TemporaryDirectory() as tmp:
        for name, d0, solid, field, run in cases(Path(tmp)):
            niso = n_iso3(solid, field, d0)
            for mmg in (False, True):
                extrude.MMG_PASS = revolve.MMG_PASS = mmg
                times = []
                for _ in range(a.repeats):
                    t0 = time.perf_counter()
                    res = run()
                    times.append(time.perf_counter() - t0)
                q = quality_summary(res.points, res.tets)
                kind = "mmg" if "mmg_rounds" in res.info else "repair"
                print(f"  {name:<16} {d0:>5} {kind:<6} {len(res.tets):>8,} "
                      f"{len(res.tets) / niso:>8.2f} {float(res.delta.max()):>8.5f} "
                      f"{q['dihedral_min']:>7.2f} {q['dihedral_p1']:>7.2f} "
                      f"{q['radius_ratio_mean']:>7.3f} {statistics.median(times):>7.2f}  "
                      f"{fingerprint(res.points, res.tets)}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
