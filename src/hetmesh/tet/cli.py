"""``hetmesh mesh`` for 3D models: mesh, write, plot, statistics.

Called by :mod:`hetmesh.cli.mesh` once the model file turned out to describe a solid.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

from ..errors import OptionError, OutputError
from ..mesh import simplex_measures
from .api import mesh_model
from .mesher import n_iso3
from .quality import quality_summary

__all__ = ["run_tet", "run_tet_stats", "tet_statistics", "plot_tets"]

#: options of ``hetmesh mesh`` that the 2D mesher has and the 3D one does not
_2D_ONLY = {"min_angle": "--min-angle", "method": "--method", "row_spacing": "--row-spacing",
            "gradation": "--gradation"}


def check_tet_options(args: argparse.Namespace, kwargs: dict) -> dict:
    """The keyword arguments of :func:`mesh_model` from the CLI's, or :class:`OptionError`."""
    for key, flag in _2D_ONLY.items():
        if kwargs.get(key) is not None:
            raise OptionError(f"{flag} is not available for 3D models")
    from .sampling import TET_SAMPLINGS
    if kwargs.get("sampling", "vertices") not in TET_SAMPLINGS:
        raise OptionError(f"--sampling {kwargs['sampling']} is not available for 3D models "
                          f"({', '.join(TET_SAMPLINGS)})")
    from ..io.export import FILE_FORMATS, FORMATS
    name = getattr(args, "format", None)
    # the names and extensions were checked with the other outputs (check_outputs)
    fmt = FILE_FORMATS[name.lower()] if name else FORMATS[args.output.suffix.lower()]
    if 3 not in fmt.dims:
        raise OutputError(f"--output {args.output}: {fmt.name} does not take tetrahedral "
                          f"meshes")
    return {k: kwargs[k] for k in ("seed", "chord_tol", "max_elements", "max_size",
                                   "sampling") if k in kwargs}


def tet_statistics(model, res) -> dict:
    """The figures of a tetrahedral mesh (also the ``--stats`` JSON's ``stats``)."""
    q = quality_summary(res.points, res.tets)
    niso = n_iso3(model.solid, model.material, res.threshold)
    return {"n_points": int(len(res.points)), "n_elements": int(len(res.tets)),
            "delta_max": float(res.delta.max()), "delta_avg": float(res.delta.mean()),
            "volume": float(simplex_measures(res.points, res.tets).sum()),
            "n_iso3": float(niso),
            # a composition constant within every subregion needs no element: no ratio
            "ratio_n_iso3": float(len(res.tets) / niso) if niso > 0 else None,
            **q}


def _iso_ratio(stats: dict) -> str:
    """``"1.234 x N_iso3"``, or ``"N_iso3 = 0"`` for a composition constant within every
    subregion."""
    r = stats["ratio_n_iso3"]
    return "N_iso3 = 0" if r is None else f"{r:.3f} x N_iso3"


def _section(points, tets, values, axis: int, at: float):
    """Polygons where the plane ``x[axis] = at`` cuts the tetrahedra, and their values."""
    d = points[:, axis] - at
    sd = d[tets]
    cut = (sd.min(axis=1) < 0) & (sd.max(axis=1) > 0)
    t = tets[cut]
    sd = sd[cut]
    pairs = [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)]
    polys = np.full((len(t), 4, 3), np.nan)
    count = np.zeros(len(t), dtype=int)
    for i, j in pairs:
        a, b = sd[:, i], sd[:, j]
        hit = (a < 0) != (b < 0)
        w = a[hit] / (a[hit] - b[hit])
        p = points[t[hit, i]] + w[:, None] * (points[t[hit, j]] - points[t[hit, i]])
        rows = np.flatnonzero(hit)
        k = count[rows]
        ok = k < 4
        polys[rows[ok], k[ok]] = p[ok]
        count[rows] += 1
    uv = [k for k in range(3) if k != axis]
    q = polys[:, :, uv]
    c = np.nanmean(q, axis=1)
    ang = np.arctan2(q[:, :, 1] - c[:, None, 1], q[:, :, 0] - c[:, None, 0])
    ang = np.where(np.isnan(ang), np.inf, ang)
    order = np.argsort(ang, axis=1)
    q = np.take_along_axis(q, order[:, :, None], axis=1)
    polys2 = [qq[~np.isnan(qq[:, 0])] for qq in q]
    return polys2, values[t].mean(axis=1)


def plot_tets(model, res, path: Path, title: str) -> None:
    """PNG (or any matplotlib format): the boundary surface coloured by composition, and a
    section through the middle of the part."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.collections import PolyCollection
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    from ..io.atomic import atomic_path

    comp = res.info["composition"]
    rng_ = comp.max(axis=0) - comp.min(axis=0)
    j = len(rng_) - 1 - int(np.argmax(rng_[::-1]))  # ties: the last constituent
    name = model.constituents[j]
    v = comp[:, j]
    cmap = plt.get_cmap("viridis")
    fig = plt.figure(figsize=(11, 5))
    ax = fig.add_subplot(1, 2, 1, projection="3d")
    tri = res.points[res.faces]
    col = cmap(np.clip(v[res.faces].mean(axis=1), 0, 1))
    ax.add_collection3d(Poly3DCollection(tri, facecolors=col, edgecolors=(0, 0, 0, 0.25),
                                         linewidths=0.2))
    lo, hi = res.points.min(axis=0), res.points.max(axis=0)
    ax.set_xlim(lo[0], hi[0]), ax.set_ylim(lo[1], hi[1]), ax.set_zlim(lo[2], hi[2])
    ax.set_box_aspect(tuple(np.maximum(hi - lo, 1e-9 * (hi - lo).max())))
    ax.set_title("boundary surface")
    axis = int(np.argmin(hi - lo)) if model.material2d is None else 2
    axis = 1 if model.material2d is None and axis == 2 else axis
    at = 0.5 * (lo[axis] + hi[axis])
    polys, vals = _section(res.points, res.tets, v, axis, at)
    ax2 = fig.add_subplot(1, 2, 2)
    pc = PolyCollection(polys, array=vals, cmap=cmap, edgecolors="k", linewidths=0.15)
    pc.set_clim(0, 1)
    ax2.add_collection(pc)
    ax2.autoscale_view()
    ax2.set_aspect("equal")
    uv = [k for k in range(3) if k != axis]
    ax2.set_xlabel("xyz"[uv[0]]), ax2.set_ylabel("xyz"[uv[1]])
    ax2.set_title(f"section {'xyz'[axis]} = {at:g}")
    fig.colorbar(pc, ax=ax2, label=f"{name} fraction")
    fig.suptitle(title)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=120, format=path.suffix.lstrip(".") or "png")
    plt.close(fig)


def run_tet(args: argparse.Namespace, model, kwargs: dict) -> int:
    """Mesh a 3D model as ``hetmesh mesh`` asked; returns the exit status."""
    if args.command not in ("mesh", "uniform"):
        raise OptionError(f"hetmesh {args.command} is not available for 3D models yet "
                          f"(hetmesh mesh and uniform are)")
    kw = check_tet_options(args, kwargs)
    from ..options import check_sampling
    check_sampling(model.material, kw.get("sampling", "vertices"),
                   names={"sampling": "--sampling"})
    t0 = time.perf_counter()
    if args.command == "uniform":  # the uniform baseline (hetmesh.tet.uniform)
        from .uniform import uniform_model
        kw = {k: v for k, v in kw.items() if k in ("chord_tol", "max_elements")}
        res = uniform_model(model, args.threshold, **kw)
    else:
        res = mesh_model(model, args.threshold, **kw)
    seconds = time.perf_counter() - t0
    from ..io.export import write_mesh
    written = [write_mesh(res.mesh, args.output, file_format=args.format)]
    stats = tet_statistics(model, res)
    if args.plot is not None:
        plot_tets(model, res, args.plot,
                  f"{model.name}: {len(res.tets)} tetrahedra, delta_0 = {args.threshold:g}")
        written.append(args.plot)
    if args.stats is not None:
        from .. import __version__
        from ..io.atomic import atomic_write
        from ..io.jsondoc import jsonable

        doc = {"hetmesh_version": __version__, "command": args.command,
               "model": {"name": model.name, "file": str(args.model)},
               "threshold": args.threshold, "output": str(args.output), "stats": stats,
               "delta_histogram": np.histogram(res.delta, bins=20,
                                               range=(0, args.threshold))[0].tolist(),
               "timings": {"wall": seconds},
               "options": {**kw, "placement": res.info.get("placement")}}
        with atomic_write(args.stats) as fh:
            json.dump(jsonable(doc), fh, indent=2)
            fh.write("\n")
        written.append(args.stats)
    if not args.quiet:
        from ..cli.progress import result_console

        console = result_console()
        console.print(f"{model.name}, delta_0 = {args.threshold:g}")
        console.print(
            f"  {stats['n_elements']} tetrahedra, {stats['n_points']} points "
            f"({_iso_ratio(stats)}), delta_max {stats['delta_max']:.4g}, "
            f"dihedral min {stats['dihedral_min']:.1f} / 1st percentile "
            f"{stats['dihedral_p1']:.1f} deg, mean radius ratio "
            f"{stats['radius_ratio_mean']:.3f}, {seconds:.2f} s")
        for p in written:
            console.print(f"wrote {p}")
    return 0


def run_tet_stats(args: argparse.Namespace, model) -> int:
    """``hetmesh stats MESH --model MODEL3D``: the tetrahedra of ``MESH`` (any format meshio
    reads) against the model: delta recomputed from the material, quality, volume against
    the solid's, every point inside the solid."""
    import meshio

    from ..errors import MeshDataError
    from ..io.xdmf import read_xdmf
    from ..metrics import delta_vertices

    path = Path(args.mesh)
    if not path.is_file():
        raise OutputError(f"no such mesh file: {path}")
    arrays = read_xdmf(path) if path.suffix.lower() == ".xdmf" else None
    if arrays is not None:
        points, tets = np.asarray(arrays["points"]), np.asarray(arrays["cells"])
    else:
        try:
            m = meshio.read(path)
        except Exception as exc:  # meshio raises many kinds on bad files
            raise OutputError(f"cannot read {path}: {' '.join(str(exc).split())}") from None
        blocks = [c.data for c in m.cells if c.type == "tetra"]
        points, tets = np.asarray(m.points, np.float64), (np.concatenate(blocks)
                                                          if blocks else None)
    if tets is None or points.ndim != 2 or points.shape[1] != 3 or not len(tets):
        raise MeshDataError(f"{path}: no tetrahedra; {model.name} is a 3D model")
    inside = model.solid.contains(points)
    if not inside.all():
        i = int(np.flatnonzero(~inside)[0])
        x, y, z = points[i]
        raise MeshDataError(f"{path}: point {i} at ({x:.6g}, {y:.6g}, {z:.6g}) is outside "
                            f"the solid of {model.name}")
    v = simplex_measures(points, tets)
    tets = tets.copy()
    tets[v < 0] = tets[v < 0][:, [0, 1, 3, 2]]
    sampling = getattr(args, "sampling", "vertices") or "vertices"
    from .sampling import TET_SAMPLINGS
    if sampling not in TET_SAMPLINGS:
        raise OptionError(f"--sampling {sampling} is not available for 3D models "
                          f"({', '.join(TET_SAMPLINGS)})")
    comp = model.material.composition(points)
    delta = delta_vertices(comp, tets)
    if sampling != "vertices":  # dense lattice, certified bound, or every voxel centre
        from ..delta import element_delta
        from ..material.field import element_subregions, has_subregions
        from ..options import check_sampling
        check_sampling(model.material, sampling, names={"sampling": "--sampling"})
        # each tetrahedron in its own subregion (of its centroid), as the mesher samples it
        split = getattr(model.material, "field2d", model.material)
        regions = element_subregions(model.material, points, tets) \
            if has_subregions(split) and callable(getattr(model.material, "region", None)) \
            else None
        delta = element_delta(model.material, points, tets, sampling, composition=comp,
                              regions=regions)
    stats = {"n_points": int(len(points)), "n_elements": int(len(tets)),
             "delta_max": float(delta.max()), "delta_avg": float(delta.mean()),
             "volume": float(np.abs(v).sum()), "solid_volume": float(model.solid.volume),
             **quality_summary(points, tets)}
    if args.threshold is not None:
        stats["threshold"] = args.threshold
        stats["n_over_threshold"] = int((delta >= args.threshold).sum())
    if args.quiet:
        return 0
    if args.json:
        print(json.dumps({"mesh": str(path), "model": str(args.model), **stats}, indent=2))
    else:
        from ..cli.progress import result_console

        console = result_console()
        console.print(f"{path}: model {model.name}, delta from the {sampling}")
        for k, val in stats.items():
            console.print(f"  {k:<20} {val:.6g}" if isinstance(val, float)
                          else f"  {k:<20} {val}")
    return 0
