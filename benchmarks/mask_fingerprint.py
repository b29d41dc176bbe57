"""Fingerprint of the adaptive mesh of an image model: one Markdown row per model file and
threshold with the tetrahedra, the sha1 of the points (float64) followed by the tetrahedra
(int64), first 12 hex digits, the quality (smallest dihedral angle, its 1st percentile,
mean radius ratio), delta_max, the a-priori estimate and the time of ``mesh_model``, the
tetrahedra after each step of the mask mesher (``info["stages"]``: the size rounds, the
optimisation pass, the repair, the reconnection of a label volume's phases); with
``--uniform``, the uniform baseline's mesh (``uniform_model``) in the same run: its
tetrahedra, the ratio adaptive / uniform, its quality and time.

    python examples/images/make_images.py --out /tmp/img
    PYTHONPATH=src python benchmarks/mask_fingerprint.py /tmp/img/masked_part.toml \\
        /tmp/img/phase_volume.toml --thresholds 0.3 0.1 [--uniform]

One run each: the times are not a comparison.
"""

from __future__ import annotations

import argparse
import hashlib
import time

import numpy as np

import hetmesh
from hetmesh.metrics import dihedral_angles, tet_quality
from hetmesh.tet.api import mesh_model
from hetmesh.tet.uniform import uniform_model


def fingerprint(points: np.ndarray, tets: np.ndarray) -> str:
    """The first 12 hex digits of the sha1 of the points (float64) and the tetrahedra
    (int64)."""
    h = hashlib.sha1(np.ascontiguousarray(points, np.float64).tobytes()
                     + np.ascontiguousarray(tets, np.int64).tobytes())
    return h.hexdigest()[:12]


def quality(r) -> str:
    """Smallest dihedral angle / its 1st percentile / mean radius ratio."""
    angle = dihedral_angles(r.points, r.tets).min(axis=1)
    ratio = tet_quality(r.points, r.tets)
    return f"{angle.min():.2f} / {np.percentile(angle, 1):.2f} / {ratio.mean():.3f}"


def row(path: str, threshold: float, uniform: bool = False) -> str:
    model = hetmesh.load_model(path)
    t0 = time.perf_counter()
    r = mesh_model(model, threshold)
    seconds = time.perf_counter() - t0
    stages = ", ".join(f"{k} {v:,}" for k, v in r.info.get("stages", {}).items())
    out = (f"| {model.name} | {threshold:g} | {len(r.tets):,} | {fingerprint(r.points, r.tets)} "
           f"| {quality(r)} | {float(r.delta.max()):.4f} "
           f"| {r.info.get('estimate', float('nan')):,.0f} | {seconds:.1f} | {stages} |")
    if uniform:
        t0 = time.perf_counter()
        u = uniform_model(model, threshold)
        seconds = time.perf_counter() - t0
        out += (f" {len(u.tets):,} | {len(r.tets) / len(u.tets):.2f} | {quality(u)} "
                f"| {seconds:.1f} |")
    return out


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("models", nargs="+", help="model files (.toml)")
    ap.add_argument("--thresholds", nargs="+", type=float, default=[0.3])
    ap.add_argument("--uniform", action="store_true",
                    help="also the uniform baseline (uniform_model), same run")
    args = ap.parse_args(argv)
    head = ("| model | delta_0 | tetrahedra | sha1 | quality | delta_max | estimate | time (s) "
            "| stages |")
    if args.uniform:
        head += " uniform | adaptive / uniform | uniform quality | uniform time (s) |"
    print(head)
    print("|---" * (head.count("|") - 1) + "|")
    for path in args.models:
        for threshold in args.thresholds:
            print(row(path, threshold, args.uniform), flush=True)


if __name__ == "__main__":
    main()
