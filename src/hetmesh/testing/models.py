"""Seeded random models (:func:`random_model`), their thresholds and their model files."""

from __future__ import annotations

import math
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .fields import random_field
from .geometry import Geometry, random_geometry, toml_float, toml_point

__all__ = ["RandomModel", "random_model", "robust_suite", "estimate", "model_toml", "bump_toml",
           "FAMILIES", "ELEMENT_BUDGET", "HARD_TAGS", "THRESHOLD_RANGE"]

#: The material families, in the order ``random_model`` assigns them (``seed % 7``).
FAMILIES = ("gentle", "tanh", "power", "sfgm", "gaussian", "sines", "kink")

#: Thresholds are raised (never above 0.2) until the a-priori element estimate
#: (:func:`estimate`) is at most this many elements, so a suite run takes minutes, not hours.
ELEMENT_BUDGET = 40_000

THRESHOLD_RANGE = (0.02, 0.2)
_ATTEMPTS = 40


@dataclass(frozen=True)
class RandomModel:
    """One generated model.

    Attributes
    ----------
    seed : int
        :func:`random_model` ``(seed)`` makes it again, byte for byte.
    name : str
        ``random-<seed>-<family>``, also the ``[model] name`` of the TOML.
    toml : str
        The model file's text.
    family : str
        One of :data:`FAMILIES`.
    kind : tuple of str
        Tags of the domain and the field: ``star``, ``arcs``, ``lshape``, ``ushape``,
        ``fillet``, ``holes``, ``small-holes``, ``interface``, ``sharp-bend``, ``point``, ``far``,
        ``steep``, ``p<1``, ``edge-singular``, ``plateaus``, ``point-kink``, ``corner-kink``,
        ``line-kink``, ``ridge``, ...
    thresholds : tuple of float
        The thresholds delta_0 to run, in [0.02, 0.2], coarse first.
    """

    seed: int
    name: str
    toml: str
    family: str
    kind: tuple = ()
    thresholds: tuple = ()

    @property
    def hard(self) -> bool:
        """Whether a tag marks a known-difficult feature (steep front, p < 1, plateaus,
        kinks, small holes, sharp interface bends, corners below 40 degrees)."""
        return bool(set(self.kind) & HARD_TAGS)

    def write(self, path) -> Path:
        """Write the TOML to ``path``; returns the path."""
        p = Path(path)
        p.write_text(self.toml, encoding="utf-8")
        return p

    def load(self):
        """The model, read back through :func:`hetmesh.load_model` from a temporary file."""
        from ..io.model import load_model

        with tempfile.TemporaryDirectory(prefix="hetmesh-random-") as tmp:
            return load_model(self.write(Path(tmp) / f"{self.name}.toml"))


HARD_TAGS = frozenset({"steep", "p<1", "edge-singular", "plateaus", "point-kink",
                       "corner-kink", "line-kink", "ridge", "small-holes", "sharp-bend",
                       "sharp-corner"})


# =============================================================================== generator
def random_model(seed: int, *, budget: int = ELEMENT_BUDGET) -> RandomModel:
    """The random model of ``seed`` (deterministic: same seed, same text).

    Parameters
    ----------
    seed : int
        Any non-negative integer. The family is ``FAMILIES[seed % 7]``; everything else
        (domain, holes, interface, field parameters, thresholds) comes from
        ``numpy.random.default_rng([seed, attempt])``.
    budget : int
        The thresholds are raised until the a-priori element estimate (:func:`estimate`) is
        at most ``budget`` (or 0.2 is reached).

    Returns
    -------
    RandomModel
        A model that loads (checked here by loading it).

    Raises
    ------
    RuntimeError
        If no attempt produced a loadable model (a bug of the generator).
    """
    from ..errors import HetmeshError

    seed = int(seed)
    if seed < 0:
        raise ValueError(f"seed must be >= 0, got {seed}")
    family = FAMILIES[seed % len(FAMILIES)]
    errors = []
    for attempt in range(_ATTEMPTS):
        rng = np.random.default_rng([seed, attempt])
        try:
            geo = random_geometry(rng)
            if geo is None:
                continue
            geo_model = _load_text(model_toml(f"random-{seed:04d}-{family}", geo, "0.5", {}, ()),
                                   "geometry")
            field_txt, params, tags = random_field(family, rng, geo, geo_model.domain)
            name = f"random-{seed:04d}-{family}"
            tags = tuple(geo.tags) + tuple(tags)
            text = model_toml(name, geo, field_txt, params, tags)
            model = _load_text(text, name)
        except HetmeshError as exc:  # the generator's fault: try another geometry
            errors.append(f"attempt {attempt}: {str(exc).splitlines()[0]}")
            continue
        thresholds = _thresholds(rng, model, budget)
        return RandomModel(seed=seed, name=name, toml=text, family=family, kind=tags,
                           thresholds=thresholds)
    raise RuntimeError(f"random_model({seed}): no valid model in {_ATTEMPTS} attempts "
                       f"(a generator bug): " + "; ".join(errors[-3:]))


def robust_suite(n: int = 48, seed: int = 0, *, budget: int = ELEMENT_BUDGET) -> list:
    """The fixed seeded set: ``[random_model(seed + i) for i in range(n)]``.

    Consecutive seeds cycle through :data:`FAMILIES`, so with ``n >= 28`` every family
    appears at least 4 times (``n = 48``: 6 or 7 times).
    """
    return [random_model(seed + i, budget=budget) for i in range(int(n))]


def _load_text(text: str, name: str):
    from ..io.model import load_model

    with tempfile.TemporaryDirectory(prefix="hetmesh-random-") as tmp:
        p = Path(tmp) / f"{name}.toml"
        p.write_text(text, encoding="utf-8")
        return load_model(p)


def model_toml(name: str, geo: Geometry, formula: str, params: dict, tags) -> str:
    out = [f"# generated by hetmesh.testing.random_model: {', '.join(tags) or '-'}",
           "[model]", f'name = "{name}"', f'description = "random model ({", ".join(tags)})"',
           ""]
    used = {k: v for k, v in params.items() if _uses(formula, k)}
    if used:
        out.append("[parameters]")
        out += [f"{k} = {toml_float(v)}" for k, v in used.items()]
        out.append("")
    out += ["[domain.outer]", f"start = {toml_point(geo.start)}", "path = ["]
    for to, kind, extra in geo.path:
        if kind == "seg":
            out.append(f"  {{ to = {toml_point(to)} }},")
        elif kind == "through":
            out.append(f"  {{ to = {toml_point(to)}, through = {toml_point(extra)} }},")
        else:
            c, direction = extra
            out.append(f'  {{ to = {toml_point(to)}, center = {toml_point(c)}, '
                       f'direction = "{direction}" }},')
    out += ["]", ""]
    for c, r in geo.holes:
        out += ["[[domain.holes]]",
                f"circle = {{ center = {toml_point(c)}, radius = {toml_float(r)} }}", ""]
    if geo.interface:
        pts = geo.interface
        out += ["[[domain.interfaces]]", f"start = {toml_point(pts[0])}",
                "path = [" + ", ".join(f"{{ to = {toml_point(p)} }}" for p in pts[1:]) + "]", ""]
    if geo.point is not None:
        out += ["[domain.points]", f"probe = {toml_point(geo.point)}", ""]
    out += ["[material]", 'constituents = ["ceramic", "metal"]', "", "[material.composition]",
            f'metal = "{formula}"', ""]
    return "\n".join(out)


def _uses(formula: str, name: str) -> bool:
    import re

    return re.search(rf"\b{re.escape(name)}\b", formula) is not None


def estimate(model, threshold: float, n: int = 200) -> float:
    """A-priori element count of ``model`` at ``threshold``: equilateral triangles of side
    ``min(threshold / |grad f|, diameter / 8)`` tiling the domain (``|grad f|`` the largest
    over the constituents, on an ``n``-cell grid over the bounding box). This module's own,
    so that the thresholds :func:`random_model` picks do not move when hetmesh's estimator
    does."""
    dom = model.domain
    x0, y0, x1, y1 = dom.bounds
    step = max(x1 - x0, y1 - y0) / n
    xs = x0 + step * (np.arange(int(math.ceil((x1 - x0) / step))) + 0.5)
    ys = y0 + step * (np.arange(int(math.ceil((y1 - y0) / step))) + 0.5)
    X, Y = np.meshgrid(xs, ys)
    pts = np.column_stack([X.ravel(), Y.ravel()])
    pts = pts[dom.contains(pts)]
    if len(pts) == 0:
        return 0.0
    g = np.sqrt((np.asarray(model.material.gradient(pts)) ** 2).sum(axis=2)).max(axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        h = np.minimum(threshold / np.nan_to_num(g, nan=0.0, posinf=np.inf), dom.diameter / 8)
    return float(4.0 / math.sqrt(3.0) * np.mean(1.0 / h ** 2) * dom.area)


def _thresholds(rng, model, budget: int) -> tuple:
    lo, hi = THRESHOLD_RANGE
    coarse = 10.0 ** rng.uniform(math.log10(0.08), math.log10(hi))
    fine = 10.0 ** rng.uniform(math.log10(lo), math.log10(0.08))
    out = []
    for t in (coarse, fine):
        t = float(f"{t:.2g}")
        while t < hi:
            est = estimate(model, t)
            if np.isfinite(est) and est <= budget:
                break
            t = min(hi, float(f"{t * 1.25:.2g}"))
        if t not in out:
            out.append(t)
    return tuple(sorted(out, reverse=True))


def bump_toml(a: float, b: float, w: float) -> str:
    """Model text of the unit square with a narrow Gaussian bump of metal centred at (a, b),
    ``metal = exp(-((x - a)**2 + (y - b)**2)/w)``: a peak that vertex sampling can miss."""
    return f"""
[model]
name = "bump"
[domain.outer]
start = [0, 0]
path = [ {{ to = [1, 0] }}, {{ to = [1, 1] }}, {{ to = [0, 1] }}, {{ to = [0, 0] }} ]
[material]
constituents = ["ceramic", "metal"]
[material.composition]
metal = "exp(-((x - {a!r})**2 + (y - {b!r})**2)/{w!r})"
"""
