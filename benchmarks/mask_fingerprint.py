"""Fingerprint of the adaptive mesh of an image model: one Markdown row per model file and
threshold with the tetrahedra, the sha1 of the points (float64) followed by the tetrahedra
(int64), first 12 hex digits, the quality (smallest dihedral angle, its 1st percentile,
mean radius ratio), delta_max, the a-priori estimate and the time of ``mesh_model``.

    python examples/images/make_images.py --out /tmp/img
    PYTHONPATH=src python benchmarks/mask_fingerprint.py /tmp/img/masked_part.toml \\
        /tmp/img/phase_volume.toml --thresholds 0.3 0.1

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


def fingerprint(points: np.ndarray, tets: np.ndarray) -> str:
    """The first 12 hex digits of the sha1 of the points (float64) and the tetrahedra
    (int64)."""
    h = hashlib.sha1(np.ascontiguousarray(points, np.float64).tobytes()
                     + np.ascontiguousarray(tets, np.int64).tobytes())
    return h.hexdigest()[:12]


def row(path: str, threshold: float) -> str:
    model = hetmesh.load_model(path)
    t0 = time.perf_counter()
    r = mesh_model(model, threshold)
    seconds = time.perf_counter() - t0
    angle = dihedral_angles(r.points, r.tets).min(axis=1)
    ratio = tet_quality(r.points, r.tets)
    return (f"| {model.name} | {threshold:g} | {len(r.tets):,} | {fingerprint(r.points, r.tets)} "
            f"| {angle.min():.2f} / {np.percentile(angle, 1):.2f} / {ratio.mean():.3f} "
            f"| {float(r.delta.max()):.4f} | {r.info.get('estimate', float('nan')):,.0f} "
            f"| {seconds:.1f} |")


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("models", nargs="+", help="model files (.toml)")
    ap.add_argument("--thresholds", nargs="+", type=float, default=[0.3])
    args = ap.parse_args(argv)
    print("| model | delta_0 | tetrahedra | sha1 | quality | delta_max | estimate | time (s) |")
    print("|---|---|---|---|---|---|---|---|")
    for path in args.models:
        for threshold in args.thresholds:
            print(row(path, threshold), flush=True)


if __name__ == "__main__":
    main()
