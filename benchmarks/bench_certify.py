"""Certified against vertex and dense sampling: elements, time, and the true variation.

Meshes narrow Gaussian bumps ``f = exp(-((x - a)**2 + (y - b)**2)/w)`` on the unit square
at 20 seeded random centres (plus (0.55, 0.91), the centre tests/test_certify.py uses)
and three widths ``w``, at delta_0 = 0.1, with each sampling, and checks every mesh
independently of hetmesh's field code: the true variation of a radial bump over a triangle
is ``f(the triangle's point nearest the centre) - f(its farthest corner)``, computed here in
closed form; a fine lattice (order 48) of every element is reported too. Then the shipped
examples at delta_0 = 0.1 (elements and time of each sampling; for the feature-tree
examples also certified with the sampled Lipschitz estimate, ``cert-lip``, the bound the
interval enclosure through the tree replaced).

Prints, per width and sampling: meshes, failures (an error), median elements, median time,
meshes with an element above delta_0 (exact check), largest exact variation found.

    python benchmarks/bench_certify.py            # all (about 2-4 minutes on 2 cores)
    python benchmarks/bench_certify.py --quick    # 5 centres, one width
    python benchmarks/bench_certify.py --skip-bumps --hft-only   # feature trees: certified
                                                  # by interval enclosure and by Lipschitz
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

import numpy as np

from hetmesh import generate
from hetmesh.errors import HetmeshError
from hetmesh.io.model import load_model
from hetmesh.testing import bump_toml

WIDTHS = (4e-4, 1e-4, 2.5e-5)
SAMPLINGS = ("vertices", "dense", "certified")
EXTRA = [(0.55, 0.91)]


def centres(n: int, seed: int = 17) -> list[tuple[float, float]]:
    rng = np.random.default_rng(seed)
    return [tuple(map(float, c)) for c in rng.uniform(0.0, 1.0, (n, 2)).round(4)] + EXTRA


def nearest_on_triangles(P: np.ndarray, T: np.ndarray, c: np.ndarray) -> np.ndarray:
    """The point of every triangle nearest ``c`` ``(M, 2)`` (closed form, per region)."""
    a, b, d = P[T[:, 0]], P[T[:, 1]], P[T[:, 2]]
    best = None
    dist = None
    for p, q in ((a, b), (b, d), (d, a)):  # nearest points on the three edges
        e = q - p
        t = np.clip(((c - p) * e).sum(1) / np.maximum((e * e).sum(1), 1e-300), 0.0, 1.0)
        x = p + t[:, None] * e
        dd = ((x - c) ** 2).sum(1)
        if best is None:
            best, dist = x, dd
        else:
            better = dd < dist
            best[better], dist[better] = x[better], dd[better]
    # c itself where it lies inside the triangle
    def cross(u, v):
        return u[:, 0] * v[:, 1] - u[:, 1] * v[:, 0]
    s1, s2, s3 = cross(b - a, c - a), cross(d - b, c - b), cross(a - d, c - d)
    inside = ((s1 >= 0) & (s2 >= 0) & (s3 >= 0)) | ((s1 <= 0) & (s2 <= 0) & (s3 <= 0))
    best[inside] = c
    return best


def exact_delta(P, T, centre, w) -> np.ndarray:
    """The true variation of the bump over every triangle."""
    c = np.asarray(centre, float)
    f = lambda q: np.exp(-((q - c) ** 2).sum(-1) / w)  # noqa: E731
    top = f(nearest_on_triangles(P, T, c))
    low = f(P[T]).min(axis=1)  # the farthest point of a triangle from c is a corner
    return top - low


def lattice_delta(P, T, centre, w, order: int = 48) -> np.ndarray:
    i, j = np.meshgrid(np.arange(order + 1), np.arange(order + 1), indexing="ij")
    keep = i + j <= order
    lam = np.stack([order - i[keep] - j[keep], i[keep], j[keep]], 1) / order
    out = np.empty(len(T))
    c = np.asarray(centre, float)
    for s in range(0, len(T), 2000):
        X = np.einsum("kv,mvd->mkd", lam, P[T[s:s + 2000]])
        v = np.exp(-((X - c) ** 2).sum(-1) / w)
        out[s:s + 2000] = v.max(1) - v.min(1)
    return out


def run_bumps(cs, widths, threshold: float, tmp: Path) -> None:
    print(f"bump f = exp(-r^2/w) on the unit square, delta_0 = {threshold}, "
          f"{len(cs)} centres (seeded, plus {EXTRA})")
    print(f"{'w':>8} {'sampling':>10} {'meshes':>6} {'errors':>6} {'median Ne':>9} "
          f"{'median s':>8} {'above d0':>8} {'max true':>9} {'max lattice':>11}")
    for w in widths:
        for sampling in SAMPLINGS:
            n_el, times, above, worst, worst_lat, errors = [], [], 0, 0.0, 0.0, 0
            for a, b in cs:
                path = tmp / "bump.toml"
                path.write_text(bump_toml(a, b, w))
                model = load_model(path)
                t0 = time.perf_counter()
                try:
                    res = generate(model, threshold, sampling=sampling)
                except HetmeshError as exc:
                    errors += 1
                    print(f"   ({a}, {b}) w={w} {sampling}: {type(exc).__name__}: {exc}",
                          file=sys.stderr)
                    continue
                times.append(time.perf_counter() - t0)
                P, T = res.mesh.points, res.mesh.triangles
                ex = exact_delta(P, T, (a, b), w)
                lat = lattice_delta(P, T, (a, b), w)
                n_el.append(len(T))
                above += int((ex >= threshold).any())
                worst, worst_lat = max(worst, float(ex.max())), max(worst_lat, float(lat.max()))
            med_n = statistics.median(n_el) if n_el else float("nan")
            med_t = statistics.median(times) if times else float("nan")
            print(f"{w:>8.2g} {sampling:>10} {len(n_el):>6} {errors:>6} {med_n:>9.0f} "
                  f"{med_t:>8.2f} {above:>8} {worst:>9.4f} {worst_lat:>11.4f}")


def _timed(model, threshold, sampling, repeats, tree_bound="interval"):
    """``(elements, median seconds)`` of meshing ``model`` with ``sampling``; feature trees
    bounded by ``tree_bound`` (``certify.TREE_BOUND``: the interval enclosure or the sampled
    Lipschitz estimate it replaced)."""
    from hetmesh import certify
    saved = certify.TREE_BOUND
    certify.TREE_BOUND = tree_bound
    try:
        times = []
        for _ in range(repeats):
            t0 = time.perf_counter()
            res = generate(model, threshold, sampling=sampling)
            times.append(time.perf_counter() - t0)
    finally:
        certify.TREE_BOUND = saved
    return res.stats.n_elements, statistics.median(times)


def run_examples(threshold: float, repeats: int, hft_only: bool = False,
                 only: list[str] | None = None) -> None:
    """Every shipped example with each sampling; feature-tree examples also with the
    Lipschitz estimate (``cert-lip``), the bound used before the interval enclosure."""
    from hetmesh.material.hft import HFTField
    root = Path(__file__).resolve().parents[1] / "src" / "hetmesh" / "examples"
    cols = SAMPLINGS + ("cert-lip",)
    print(f"\nexamples at delta_0 = {threshold} (median of {repeats} runs; cert-lip: certified "
          f"with the sampled Lipschitz estimate for feature trees)")
    print(f"{'model':>18} " + " ".join(f"{s + ' Ne':>13} {s + ' s':>10}" for s in cols)
          + f" {'cert/vert Ne':>12} {'cert/vert s':>11} {'lip/vert s':>10}")
    for path in sorted(root.glob("*.toml")):
        model = load_model(path)
        tree = isinstance(model.material, HFTField)
        if (hft_only and not tree) or (only and path.stem not in only):
            continue
        row, ne, tt = [], {}, {}
        for col in cols:
            if col == "cert-lip" and not tree:
                row.append(f"{'-':>13} {'':>10}")
                continue
            sampling, bound = ("certified", "lipschitz") if col == "cert-lip" else (col, "interval")
            try:
                ne[col], tt[col] = _timed(model, threshold, sampling, repeats, bound)
            except HetmeshError as exc:
                row.append(f"{'error':>13} {'':>10}")
                print(f"   {path.stem} {col}: {exc}", file=sys.stderr)
                continue
            row.append(f"{ne[col]:>13} {tt[col]:>10.2f}")
        ratio = ""
        if "certified" in ne and "vertices" in ne:
            ratio = (f"{ne['certified'] / ne['vertices']:>12.2f} "
                     f"{tt['certified'] / tt['vertices']:>11.2f}")
            if "cert-lip" in tt:
                ratio += f" {tt['cert-lip'] / tt['vertices']:>10.2f}"
        print(f"{path.stem:>18} " + " ".join(row) + " " + ratio, flush=True)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--threshold", type=float, default=0.1)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--skip-examples", action="store_true")
    ap.add_argument("--skip-bumps", action="store_true")
    ap.add_argument("--hft-only", action="store_true",
                    help="examples: only the feature-tree models")
    ap.add_argument("--only", nargs="+", metavar="MODEL", help="examples: only these")
    args = ap.parse_args(argv)
    import tempfile
    if not args.skip_bumps:
        with tempfile.TemporaryDirectory() as d:
            cs = centres(4 if args.quick else 20)
            run_bumps(cs, WIDTHS[:1] if args.quick else WIDTHS, args.threshold, Path(d))
    if not args.skip_examples:
        run_examples(args.threshold, 1 if args.quick else args.repeats, args.hft_only,
                     args.only)
    return 0


if __name__ == "__main__":
    sys.exit(main())
