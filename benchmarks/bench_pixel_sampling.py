#!/usr/bin/env python
"""What sampling every pixel costs: measure, never assert.

    PYTHONPATH=src python benchmarks/bench_pixel_sampling.py                 # ~1-2 min
    PYTHONPATH=src python benchmarks/bench_pixel_sampling.py --repeats 1 --threshold 0.1

Writes the image examples (hetmesh.material.image.write_examples: the graded part with and
without noise, 512 x 256 pixels, and the two-phase label image) into a temporary folder and
meshes each model with ``sampling="vertices"`` and ``sampling="pixels"``, in this process.
Per model and sampling: elements, q_avg, delta_max of the sampling, the largest delta(T) over
the pixel centres and vertices of every element (``field.pixel_delta``, whatever the
sampling) and how many elements reach delta_0 there, and the median wall time of the runs;
then the pixels / vertices ratios of elements and time, measured in the same run.
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import tempfile
import time


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--threshold", type=float, default=0.05, help="delta_0 (default 0.05)")
    ap.add_argument("--repeats", type=int, default=3, help="runs per case (default 3)")
    args = ap.parse_args(argv)

    import hetmesh
    from hetmesh.io.model import load_model
    from hetmesh.material.image import write_examples

    print(f"hetmesh {hetmesh.__version__} from {os.path.dirname(hetmesh.__file__)}; "
          f"delta_0 = {args.threshold:g}; {args.repeats} run(s) each; "
          f"load {os.getloadavg()[0]:.1f}")
    head = (f"{'model':>18} {'sampling':>9} {'Ne':>7} {'q_avg':>7} {'delta_max':>9} "
            f"{'pixels max':>10} {'>= d0':>6} {'s':>7} {'Ne x':>6} {'s x':>6}")
    print(head)
    with tempfile.TemporaryDirectory(prefix="bench-pixels-") as tmp:
        for name, path in write_examples(tmp).items():
            model = load_model(path)
            base = None
            for sampling in ("vertices", "pixels"):
                times = []
                for _ in range(args.repeats):
                    t0 = time.perf_counter()
                    r = hetmesh.generate(model, args.threshold, sampling=sampling)
                    times.append(time.perf_counter() - t0)
                mesh = r.mesh
                d = model.material.pixel_delta(mesh.points, mesh.triangles,
                                               mesh.cell_data.get("subregion"))
                s = statistics.median(times)
                ne = r.stats.n_elements
                base = base or (ne, s)
                print(f"{name:>18} {sampling:>9} {ne:>7,} {r.stats.q_avg:>7.4f} "
                      f"{r.stats.delta_max:>9.4f} {float(d.max()):>10.4f} "
                      f"{int((d >= args.threshold).sum()):>6} {s:>7.2f} "
                      f"{ne / base[0]:>6.3f} {s / base[1]:>6.2f}", flush=True)
    print(f"load at the end {os.getloadavg()[0]:.1f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
