"""The ``[fea]`` table of a model file: properties, boundary conditions, probes (Sec. 4.4).

:func:`parse_fea` turns the raw table into an immutable :class:`FEAConfig`, checking it
against the model's constituents and domain when the model file is loaded, so that a bad
table fails before any mesh is read. Every error is one line naming the file and the key,
e.g. ``plate.toml: fea.temperature[0].curves: unknown curve 'BDC' (known: AB, BCD, ...)``.
The format is documented in ``docs/model-format.md`` (section "FEA"). Pure numpy: importing
this module does not import scikit-fem.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from ..errors import ModelFileError

__all__ = ["FEAConfig", "Properties", "TemperatureBC", "DisplacementBC", "parse_fea",
           "parse_choice", "table_array", "parse_properties", "parse_settings",
           "LENGTH_UNITS", "PLANES", "MIXINGS", "PROPERTY_KEYS", "rigid_rank",
           "length_scale"]

log = logging.getLogger(__name__)

#: metres per model length unit (``[model] units``); no unit means metres.
LENGTH_UNITS: dict[str, float] = {"": 1.0, "m": 1.0, "cm": 1e-2, "mm": 1e-3, "um": 1e-6,
                                  "µm": 1e-6, "km": 1e3, "in": 0.0254, "ft": 0.3048}
PLANES = ("strain", "stress")
MIXINGS = ("linear", "mori-tanaka")
#: property key (a :class:`Properties` attribute) -> what it is and the check that applies
PROPERTY_KEYS = {
    "conductivity": "thermal conductivity k in W/(m K), > 0",
    "youngs_modulus": "Young's modulus E in Pa, > 0",
    "poisson_ratio": "Poisson ratio nu, -1 < nu < 0.5",
    "expansion": "linear thermal expansion coefficient alpha in 1/K",
}
#: relative distance (x domain diameter) within which a point counts as on the boundary
ON_BOUNDARY = 1e-6


@dataclass(frozen=True)
class Properties:
    """One constituent's isotropic properties (SI units, paper Table 6)."""

    conductivity: float
    youngs_modulus: float
    poisson_ratio: float
    expansion: float


@dataclass(frozen=True)
class TemperatureBC:
    """A fixed temperature (K) on the named boundary curves; ``key`` is where it was given."""

    curves: tuple[str, ...]
    value: float
    key: str = "fea.temperature"


@dataclass(frozen=True)
class DisplacementBC:
    """Fixed displacement components (model length units) at a point or on curves.

    Exactly one of ``point`` (coordinates) and ``curves`` (names) is set; ``ux``/``uy`` are
    None where the component is free.
    """

    point: tuple[float, float] | None
    curves: tuple[str, ...]
    ux: float | None
    uy: float | None
    key: str = "fea.displacement"
    label: str = ""


@dataclass(frozen=True)
class FEAConfig:
    """What :func:`hetmesh.fea.solve` needs besides the mesh and the material field.

    Attributes
    ----------
    properties : dict constituent -> Properties
        In the order of the material's constituents.
    temperature, displacement : tuples of the boundary conditions
        Both empty for a table of material properties alone (``[fea.properties]``, and
        optionally ``mixing``/``matrix``/``plane``/``reference_temperature``), which
        :mod:`hetmesh.io.material` uses to carry the graded material into exported files.
    probes : dict name -> (x, y)
        In model coordinates.
    plane : "strain" or "stress"
    reference_temperature : float
        The stress-free temperature (K).
    mixing : "linear" or "mori-tanaka"
    matrix : str or None
        The matrix constituent of the Mori-Tanaka scheme.
    length_scale : float
        Metres per model length unit.
    order : 1 or 2
        Lagrange element order: linear (P1, the default, as in scikit-fem and most FE codes)
        or quadratic (P2) triangles. Probe stresses converge much faster with P2; the
        case-4 study (``examples/fgm_plate.toml``) sets ``order = 2``.
    """

    properties: Mapping[str, Properties]
    temperature: tuple[TemperatureBC, ...]
    displacement: tuple[DisplacementBC, ...]
    probes: Mapping[str, tuple[float, float]] = field(default_factory=dict)
    plane: str = "strain"
    reference_temperature: float = 293.15
    mixing: str = "linear"
    matrix: str | None = None
    length_scale: float = 1.0
    order: int = 1
    where: str = ""

    @property
    def has_problem(self) -> bool:
        """Whether boundary conditions are given (else only the material properties)."""
        return bool(self.temperature) or bool(self.displacement)

    def table(self) -> dict[str, np.ndarray]:
        """Constituent property columns ``{'conductivity': (m,), ...}`` (constituent order)."""
        props = list(self.properties.values())
        return {k: np.array([getattr(p, k) for p in props], dtype=np.float64)
                for k in PROPERTY_KEYS}


def length_scale(units: str) -> float | None:
    """Metres per ``units`` (``"mm"`` -> 1e-3), None if unknown."""
    return LENGTH_UNITS.get(units.strip())


# --------------------------------------------------------------------------------- parsing

def parse_settings(ctx, t: Mapping, units: str, constituents: Sequence[str]
                   ) -> tuple[float, str, float, int, str | None]:
    """The settings every ``[fea]`` table has, 2D or 3D: ``(length scale to m, mixing,
    reference temperature, element order, matrix constituent or None)``, each checked with
    the key it came from."""
    scale = length_scale(units)
    if scale is None:
        raise ctx.fail("model.units", f"unknown length unit {units!r} for the FEA (known: "
                                      f"{', '.join(u for u in LENGTH_UNITS if u)}; none means m)")
    mixing = parse_choice(ctx, t, "mixing", MIXINGS, "linear")
    ref = ctx.number(t.get("reference_temperature", 293.15), "fea.reference_temperature")
    if ref <= 0:
        raise ctx.fail("fea.reference_temperature", f"expected a temperature in K above 0, "
                                                    f"got {ref:g}")
    order = t.get("order", 1)
    if isinstance(order, bool) or order not in (1, 2):
        raise ctx.fail("fea.order", f"expected 1 (linear) or 2 (quadratic elements), got "
                                    f"{order!r}")
    matrix = ctx.string(t, "fea", "matrix")
    if mixing == "mori-tanaka":
        if matrix is None:
            raise ModelFileError(f"{ctx.pre}missing key 'fea.matrix' (mixing = \"mori-tanaka\" "
                                 f"needs the matrix constituent, one of: "
                                 f"{', '.join(constituents)})")
        if matrix not in constituents:
            raise ctx.fail("fea.matrix", f"unknown constituent {matrix!r} (expected one of: "
                                         f"{', '.join(constituents)})")
    elif matrix is not None:
        raise ctx.fail("fea.matrix", "only mixing = \"mori-tanaka\" has a matrix constituent")
    return scale, mixing, ref, int(order), matrix


def parse_fea(ctx, value, domain, constituents, units: str = ""):
    """Parse and check the ``[fea]`` table (see the module docstring).

    Parameters
    ----------
    ctx : the model parser's context (``fail``, ``table``, ``number``, ``point``, ``string``)
    value : the raw table
    domain : Domain
        Curve names, named points and containment for the checks.
    constituents : sequence of str
    units : str
        The model's ``[model] units``.

    Raises
    ------
    ModelFileError
        Unknown, missing or mistyped keys; properties missing for a constituent; a condition
        on an unknown curve or point; a probe outside the domain; no fixed temperature; too
        few displacement constraints to remove the rigid-body modes.
    """
    t = ctx.table(value, "fea", required=("properties",),
                  optional=("temperature", "displacement", "plane", "reference_temperature",
                            "mixing", "matrix", "probes", "order"))
    if ("temperature" in t) != ("displacement" in t):
        missing = "displacement" if "temperature" in t else "temperature"
        raise ModelFileError(f"{ctx.pre}missing key 'fea.{missing}' (the analysis needs both "
                             f"fixed temperatures and displacement conditions; give neither "
                             f"for the material properties alone)")
    plane = parse_choice(ctx, t, "plane", PLANES, "strain")
    scale, mixing, ref, order, matrix = parse_settings(ctx, t, units, constituents)
    props = parse_properties(ctx, t["properties"], constituents)
    names = _curve_names(domain)
    temps, disps = (), ()
    if "temperature" in t:
        temps = tuple(_temperature(ctx, item, f"fea.temperature[{i}]", names)
                      for i, item in enumerate(table_array(ctx, t["temperature"],
                                                           "fea.temperature")))
        if not temps:
            raise ctx.fail("fea.temperature", "at least one fixed temperature is needed (with "
                                              "every edge insulated the temperature is "
                                              "undefined)")
        disps = tuple(_displacement(ctx, item, f"fea.displacement[{i}]", names, domain)
                      for i, item in enumerate(table_array(ctx, t["displacement"],
                                                      "fea.displacement")))
        _check_rigid(ctx, disps, domain, names)
    probes = _probes(ctx, t.get("probes", {}), domain)
    return FEAConfig(properties=props, temperature=temps, displacement=disps, probes=probes,
                     plane=plane, reference_temperature=ref, mixing=mixing, matrix=matrix,
                     length_scale=scale, order=int(order), where=ctx.where)


def parse_choice(ctx, t, key, options, default):
    """The string ``fea.<key>`` of table ``t``, one of ``options`` (``default`` if absent)."""
    v = ctx.string(t, "fea", key, default=default)
    if v not in options:
        raise ctx.fail(f"fea.{key}", f"expected one of {', '.join(map(repr, options))}, "
                                     f"got {v!r}")
    return v


def table_array(ctx, value, key) -> list:
    """An array of tables (``[[key]]``); a single table counts as an array of one."""
    if isinstance(value, Mapping):
        value = [value]
    if not isinstance(value, list):
        raise ctx.fail(key, f"expected an array of tables ([[{key}]]), got {value!r}")
    return value


def parse_properties(ctx, value, constituents) -> dict[str, Properties]:
    """``[fea.properties.<constituent>]`` for every constituent, checked."""
    cons = tuple(constituents)
    if not isinstance(value, Mapping):
        raise ctx.fail("fea.properties", "expected a table of constituents "
                                         "([fea.properties.<constituent>])")
    for name in value:
        if name not in cons:
            raise ModelFileError(f"{ctx.pre}unknown key 'fea.properties.{name}': not a "
                                 f"constituent (expected one of: {', '.join(cons)})")
    out = {}
    for name in cons:
        key = f"fea.properties.{name}"
        if name not in value:
            raise ModelFileError(f"{ctx.pre}missing key {key!r} (properties are needed for "
                                 f"every constituent: {', '.join(cons)})")
        p = ctx.table(value[name], key, required=tuple(PROPERTY_KEYS))
        vals = {k: ctx.number(p[k], f"{key}.{k}") for k in PROPERTY_KEYS}
        for k in ("conductivity", "youngs_modulus"):
            if vals[k] <= 0:
                raise ctx.fail(f"{key}.{k}", f"expected the {PROPERTY_KEYS[k]}, got {vals[k]:g}")
        if not -1.0 < vals["poisson_ratio"] < 0.5:
            raise ctx.fail(f"{key}.poisson_ratio", f"expected -1 < nu < 0.5, got "
                                                   f"{vals['poisson_ratio']:g}")
        out[name] = Properties(**vals)
    return out


def _curve_names(domain) -> dict[str, list[int]]:
    """Curve name or loop/interface name -> indices into ``domain.curves``."""
    names: dict[str, list[int]] = {}
    for i, info in enumerate(domain.curves):
        names.setdefault(info.name, []).append(i)
        if info.owner != info.name:
            names.setdefault(info.owner, []).append(i)
    return names


def _curves(ctx, t, key, names) -> tuple[str, ...]:
    v = t["curves"]
    if isinstance(v, str):
        v = [v]
    if not isinstance(v, list) or not v or not all(isinstance(c, str) for c in v):
        raise ctx.fail(f"{key}.curves", f"expected a non-empty array of curve names, got {v!r}")
    for c in v:
        if c not in names:
            raise ctx.fail(f"{key}.curves", f"unknown curve {c!r} (known: {', '.join(names)})")
    return tuple(v)


def _temperature(ctx, item, key, names) -> TemperatureBC:
    t = ctx.table(item, key, required=("curves", "value"))
    value = ctx.number(t["value"], f"{key}.value")
    if value <= 0:
        raise ctx.fail(f"{key}.value", f"expected a temperature in K above 0, got {value:g}")
    return TemperatureBC(_curves(ctx, t, key, names), value, key)


def _where_point(ctx, value, key, domain) -> tuple[tuple[float, float], str]:
    """A point given by name (``[domain.points]``) or as ``[x, y]``, inside or on the
    domain; returns the coordinates and a label."""
    if isinstance(value, str):
        if value not in domain.points:
            known = ", ".join(domain.points) or "none: give coordinates [x, y]"
            raise ctx.fail(key, f"unknown point {value!r} (named points in [domain.points]: "
                                f"{known})")
        return tuple(domain.points[value]), value
    p = ctx.point(value, key)
    tol = ON_BOUNDARY * domain.diameter
    a = np.array([p])
    if not (domain.contains(a)[0] or domain.distance_to_boundary(a)[0] <= tol):
        raise ctx.fail(key, f"point ({p[0]:.12g}, {p[1]:.12g}) is outside the domain")
    return p, f"({p[0]:.12g}, {p[1]:.12g})"


def _displacement(ctx, item, key, names, domain) -> DisplacementBC:
    t = ctx.table(item, key, optional=("point", "curves", "ux", "uy"))
    if ("point" in t) == ("curves" in t):
        raise ctx.fail(key, "give either 'point' (a name or [x, y]) or 'curves' (names)")
    comps = {c: ctx.number(t[c], f"{key}.{c}") if c in t else None for c in ("ux", "uy")}
    if comps["ux"] is None and comps["uy"] is None:
        raise ctx.fail(key, "fixes nothing: give 'ux', 'uy' or both (0 to hold in place)")
    if "point" in t:
        p, label = _where_point(ctx, t["point"], f"{key}.point", domain)
        return DisplacementBC(p, (), comps["ux"], comps["uy"], key, label)
    curves = _curves(ctx, t, key, names)
    return DisplacementBC(None, curves, comps["ux"], comps["uy"], key, ", ".join(curves))


def _probes(ctx, value, domain) -> dict[str, tuple[float, float]]:
    if not isinstance(value, Mapping):
        raise ctx.fail("fea.probes", "expected a table name = [x, y] (or a point name)")
    return {name: _where_point(ctx, v, f"fea.probes.{name}", domain)[0]
            for name, v in value.items()}


# --------------------------------------------------------------------------- rigid modes

def rigid_rank(points: np.ndarray, fixed_x: np.ndarray, fixed_y: np.ndarray) -> int:
    """Rank of the 3 plane rigid-body modes restricted to the constrained components.

    ``points`` ``(N, 2)``; ``fixed_x``/``fixed_y`` ``(N,)`` bool. The modes are the two
    translations and the rotation ``(-y, x)`` about the centroid; the system is non-singular
    only if the constraints see all three (rank 3).

    >>> rigid_rank(np.array([[0., 0], [1, 0]]), np.array([True, False]),
    ...            np.array([True, True]))
    3
    >>> rigid_rank(np.array([[0., 0], [1, 0]]), np.array([True, True]),
    ...            np.array([False, False]))
    1
    """
    p = np.asarray(points, dtype=np.float64)
    if not len(p):
        return 0
    q = p - p.mean(axis=0)
    s = max(float(np.abs(q).max()), 1e-300)
    q = q / s
    rows_x = np.column_stack([np.ones(len(q)), np.zeros(len(q)), -q[:, 1]])[fixed_x]
    rows_y = np.column_stack([np.zeros(len(q)), np.ones(len(q)), q[:, 0]])[fixed_y]
    r = np.vstack([rows_x, rows_y])
    if not len(r):
        return 0
    ev = np.linalg.eigvalsh(r.T @ r)
    return int((ev > 1e-10 * max(float(ev.max()), 1e-300)).sum())


def _check_rigid(ctx, disps, domain, idx: dict[str, list[int]]) -> None:
    """Fail unless the displacement conditions remove the three rigid-body modes, judged on
    the points and on samples of the constrained curves (ends and 3 interior points);
    ``idx`` is :func:`_curve_names` of the domain."""
    if not disps:
        raise ctx.fail("fea.displacement", "at least one displacement condition is needed")
    pts, fx, fy = [], [], []
    t = np.linspace(0.0, 1.0, 5)
    for bc in disps:
        if bc.point is not None:
            p = np.array([bc.point])
        else:
            ids = sorted({i for c in bc.curves for i in idx[c]})
            p = np.vstack([domain.curves[i].curve.point(t) for i in ids])
        pts.append(p)
        fx.append(np.full(len(p), bc.ux is not None))
        fy.append(np.full(len(p), bc.uy is not None))
    rank = rigid_rank(np.vstack(pts), np.concatenate(fx), np.concatenate(fy))
    if rank < 3:
        raise ctx.fail("fea.displacement", f"too few constraints: the conditions remove only "
                                           f"{rank} of the 3 rigid-body modes (2 translations "
                                           f"and a rotation), so the elastic system is "
                                           f"singular; fix e.g. ux and uy at one point and uy "
                                           f"at another point not above it")
