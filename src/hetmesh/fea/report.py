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

__all__ = ["report_document", "write_report", "von_mises_figure", "plot_von_mises"]

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
