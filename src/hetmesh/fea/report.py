"""FEA outputs: the JSON report and the von Mises plot (paper Sec. 4.4, Table 7, Fig. 14).

Both are written atomically (:mod:`hetmesh.io.atomic`); the figure is built on an Agg canvas
like every hetmesh figure (:mod:`hetmesh.plot`), never through ``pyplot``.
"""

from __future__ import annotations

import json
import logging
from pathlib import Path
from typing import Any

import numpy as np

from ..io.jsondoc import jsonable
from ..topology import unique

__all__ = ["report_document", "write_report", "von_mises_figure", "plot_von_mises",
           "tet_section", "section_figure"]

log = logging.getLogger(__name__)


def report_document(result, **extra) -> dict[str, Any]:
    """:meth:`FEAResult.report` plus ``extra`` keys (file names, version), JSON-ready."""
    from ..version import __version__

    return jsonable({"hetmesh_version": __version__, **extra, **result.report()},
                    infinity_as_string=False)


def write_report(result, path: str | Path, **extra) -> Path:
    """Write :func:`report_document` as indented JSON, atomically; returns ``path``.

    >>> write_report(result, "fea.json", mesh="plate.vtu")   # doctest: +SKIP
    """
    from ..io.atomic import atomic_write

    with atomic_write(path) as fh:
        json.dump(report_document(result, **extra), fh, indent=2)
        fh.write("\n")
    log.info("wrote %s", path)
    return Path(path)


def von_mises_figure(result, *, title: str | None = None, show_probes: bool = True,
                     units: str = ""):
    """The recovered von Mises stress (MPa, Gouraud shading) with the probes marked;
    ``units`` the model's length unit for the axes.

    Returns a :class:`matplotlib.figure.Figure`.
    """
    from matplotlib.tri import Triangulation

    from ..plot import axis_labels, figure_size, label_points, new_figure

    mesh = result.mesh
    if getattr(mesh, "dim", 2) == 3:
        return section_figure(result, title=title, show_probes=show_probes, units=units)
    fig = new_figure(*figure_size(mesh))
    ax = fig.add_subplot()
    tri = Triangulation(mesh.points[:, 0], mesh.points[:, 1], mesh.triangles)
    art = ax.tripcolor(tri, result.von_mises / 1e6, shading="gouraud", cmap="inferno")
    fig.colorbar(art, ax=ax, label="von Mises stress (MPa)", shrink=0.9)
    if mesh.n_elements <= 20_000:
        ax.triplot(tri, color="0.6", lw=0.15, alpha=0.6)
    if show_probes and result.probes:
        xy = np.array([[p["x"], p["y"]] for p in result.probes.values()])
        ax.plot(xy[:, 0], xy[:, 1], "o", ms=4, mfc="cyan", mec="k", mew=0.5)
        label_points(ax, xy, list(result.probes))
    ax.set_aspect("equal")
    axis_labels(ax, units)
    ax.set_title(title or f"{result.model_name}: von Mises stress, {mesh.n_elements} elements, "
                          f"plane {result.config.plane}")
    return fig


def plot_von_mises(result, path: str | Path, *, title: str | None = None,
                   dpi: int = 150, units: str = "") -> Path:
    """Save :func:`von_mises_figure` to ``path`` (format from the extension, atomically)."""
    from ..plot import save_figure

    return save_figure(von_mises_figure(result, title=title, units=units), path, dpi)


# ------------------------------------------------------------------------------ 3-D section

def tet_section(P: np.ndarray, T: np.ndarray, values: np.ndarray, axis: int, level: float
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The cut of a tetrahedral mesh by the plane ``x[axis] = level``: ``(points (K, 2),
    triangles (L, 3), values (K,))``, the in-plane coordinates in cyclic order after
    ``axis`` (z: ``(x, y)``; x: ``(y, z)``; y: ``(z, x)``) and the vertex ``values``
    interpolated linearly along the cut edges. Every tetrahedron the plane crosses gives a
    triangle or a quadrilateral (two triangles). Vertices exactly on the plane count as
    above it.

    >>> P = np.array([[0., 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]])
    >>> q, t, v = tet_section(P, np.array([[0, 1, 2, 3]]), P[:, 2], 2, 0.5)
    >>> len(t), np.round(v, 6).tolist()
    (1, [0.5, 0.5, 0.5])
    """
    d = P[:, axis] - level
    above = d >= 0
    na = above[T].sum(axis=1)
    cut = (na > 0) & (na < 4)
    Tc = T[cut]
    uv = [(axis + 1) % 3, (axis + 2) % 3]
    pairs = [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)]
    pts, vals, ok = [], [], []
    for i, j in pairs:
        a, b = Tc[:, i], Tc[:, j]
        crosses = above[a] != above[b]
        with np.errstate(divide="ignore", invalid="ignore"):
            s = np.where(crosses, d[a] / (d[a] - d[b]), 0.0)
        pts.append(P[a][:, uv] + s[:, None] * (P[b][:, uv] - P[a][:, uv]))
        vals.append(values[a] + s * (values[b] - values[a]))
        ok.append(crosses)
    pts = np.stack(pts, axis=1)          # (C, 6, 2)
    vals = np.stack(vals, axis=1)        # (C, 6)
    ok = np.stack(ok, axis=1)            # (C, 6): 3 or 4 crossing edges
    # order each polygon's crossing points by angle about their mean
    cnt = ok.sum(axis=1)
    centre = (pts * ok[..., None]).sum(axis=1) / cnt[:, None]
    ang = np.arctan2(pts[..., 1] - centre[:, None, 1], pts[..., 0] - centre[:, None, 0])
    ang = np.where(ok, ang, np.inf)
    order = np.argsort(ang, axis=1)[:, :4]
    base = np.arange(len(Tc))[:, None] * 6
    ids = base + order                   # global ids into the flattened (C * 6) arrays
    tris = [ids[:, [0, 1, 2]], ids[cnt == 4][:, [0, 2, 3]]]
    tri = np.vstack(tris)
    used, inv = unique(tri.ravel(), return_inverse=True)
    return (pts.reshape(-1, 2)[used], inv.reshape(-1, 3), vals.ravel()[used])


def section_figure(result, *, title: str | None = None, show_probes: bool = True,
                   units: str = "", axis: int | None = None, level: float | None = None):
    """Von Mises stress (MPa) on a plane section of a tetrahedral result.

    The plane is normal to ``axis`` (default: z, or the axis along which the probes all
    share one coordinate) at ``level`` (default: that coordinate, else the middle of the
    mesh). Returns a :class:`matplotlib.figure.Figure`.
    """
    from matplotlib.tri import Triangulation

    from ..plot import label_points, new_figure

    mesh = result.mesh
    P, T = np.asarray(mesh.points), np.asarray(mesh.cells)
    probes = list(result.probes.values()) if show_probes else []
    xyz = np.array([[p["x"], p["y"], p["z"]] for p in result.probes.values()]) \
        if result.probes else np.zeros((0, 3))
    if axis is None:
        axis = 2
        if len(xyz):
            same = [k for k in (2, 0, 1) if np.ptp(xyz[:, k]) == 0]
            axis = same[0] if same else 2
    if level is None:
        if len(xyz) and np.ptp(xyz[:, axis]) == 0:
            level = float(xyz[0, axis])
        else:
            level = float(0.5 * (P[:, axis].min() + P[:, axis].max()))
    q, tri, v = tet_section(P, T, np.asarray(result.von_mises), axis, level)
    uv = [(axis + 1) % 3, (axis + 2) % 3]
    span = np.ptp(q, axis=0) if len(q) else np.ones(2)
    aspect = float(span[1] / span[0]) if span[0] > 0 else 1.0
    fig = new_figure(7.0, float(np.clip(7.0 * aspect * 0.85 + 0.6, 2.5, 10.0)))
    ax = fig.add_subplot()
    if len(tri):
        art = ax.tripcolor(Triangulation(q[:, 0], q[:, 1], tri), v / 1e6, shading="gouraud",
                           cmap="inferno")
        fig.colorbar(art, ax=ax, label="von Mises stress (MPa)", shrink=0.9)
    if probes:
        pq = xyz[:, uv]
        ax.plot(pq[:, 0], pq[:, 1], "o", ms=4, mfc="cyan", mec="k", mew=0.5)
        label_points(ax, pq, list(result.probes))
    ax.set_aspect("equal")
    unit = f" ({units.strip()})" if units and units.strip() else ""
    names = "xyz"
    ax.set_xlabel(f"{names[uv[0]]}{unit}")
    ax.set_ylabel(f"{names[uv[1]]}{unit}")
    ax.set_title(title or f"{result.model_name}: von Mises stress on {names[axis]} = "
                          f"{level:.6g}, {mesh.n_elements} tetrahedra, P{result.config.order}")
    return fig
