"""The ``[fea]`` table of a 3-D model: properties, conditions on named faces, pressures,
probes.

The same table as in 2-D (``docs/model-format.md``, section "FEA") with the 3-D changes:
conditions name **faces** of the solid (``faces = ["inner"]``; the face names of the
``[solid]``), an **edge** as the two faces meeting there (``edge = ["bottom", "xmin"]``) or a
**point** ``[x, y, z]``; displacements have ``ux``, ``uy``, ``uz``; ``[[fea.pressure]]``
puts a pressure (Pa, pushing on the face) on faces; probes are ``[x, y, z]``; there is no
``plane`` (the analysis is 3-D), and ``solver`` chooses the linear solver (``auto``,
``direct``, ``amg``). Without ``[[fea.temperature]]`` the part is isothermal at
``reference_temperature`` (a purely mechanical analysis)::

    [fea]
    reference_temperature = 273.15
    order = 2

    [fea.properties.ceramic]
    conductivity = 35.0
    youngs_modulus = 393e9
    poisson_ratio = 0.25
    expansion = 7.4e-6
    # ... every constituent

    [[fea.pressure]]
    faces = ["inner"]
    value = 100e6

    [[fea.displacement]]
    faces = ["bottom", "top"]
    uz = 0

    [fea.probes]
    R1 = [12.5, 0, 2.5]

:func:`parse_fea3d` checks the table against the solid's face names (``solid.face_names``)
and containment (``solid.contains``) when given, so a bad table fails when the model file is
loaded; every error is one line naming the file and the key. Pure numpy.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from .config import (
    PROPERTY_KEYS,
    Properties,
    parse_choice,
    parse_properties,
    parse_settings,
    table_array,
)

#: the linear solvers by name (:func:`hetmesh.fea.linsolve.solve_spd`); ``auto`` factorises
#: small systems directly and solves larger ones by multigrid-preconditioned CG
SOLVERS = ("auto", "direct", "amg")

__all__ = ["FEAConfig3D", "Selection", "TemperatureBC3D", "DisplacementBC3D", "PressureBC",
           "parse_fea3d", "SOLVERS"]


@dataclass(frozen=True)
class Selection:
    """Where a condition applies: named ``faces``, an ``edge`` (two face names), or a
    ``point`` ``(x, y, z)``; exactly one is set."""

    faces: tuple[str, ...] = ()
    edge: tuple[str, str] | None = None
    point: tuple[float, float, float] | None = None

    @property
    def label(self) -> str:
        if self.point is not None:
            return "point ({:.12g}, {:.12g}, {:.12g})".format(*self.point)
        if self.edge is not None:
            return f"edge {self.edge[0]} / {self.edge[1]}"
        return "faces " + ", ".join(self.faces)


@dataclass(frozen=True)
class TemperatureBC3D:
    where: Selection
    value: float
    key: str = "fea.temperature"


@dataclass(frozen=True)
class DisplacementBC3D:
    where: Selection
    ux: float | None
    uy: float | None
    uz: float | None
    key: str = "fea.displacement"

    @property
    def components(self) -> tuple[float | None, float | None, float | None]:
        return (self.ux, self.uy, self.uz)


@dataclass(frozen=True)
class PressureBC:
    where: Selection
    value: float
    key: str = "fea.pressure"


@dataclass(frozen=True)
class FEAConfig3D:
    """What :func:`hetmesh.fea.solve` needs for a tetrahedral mesh besides the mesh and the
    material (see the module docstring; attributes as in
    :class:`~hetmesh.fea.config.FEAConfig` plus ``pressure`` and ``solver``)."""

    properties: Mapping[str, Properties]
    temperature: tuple[TemperatureBC3D, ...] = ()
    displacement: tuple[DisplacementBC3D, ...] = ()
    pressure: tuple[PressureBC, ...] = ()
    probes: Mapping[str, tuple[float, float, float]] = field(default_factory=dict)
    reference_temperature: float = 293.15
    mixing: str = "linear"
    matrix: str | None = None
    length_scale: float = 1.0
    order: int = 1
    solver: str = "auto"
    where: str = ""

    dim = 3
    plane = "3d"

    @property
    def has_problem(self) -> bool:
        return bool(self.displacement)

    def table(self) -> dict[str, np.ndarray]:
        props = list(self.properties.values())
        return {k: np.array([getattr(p, k) for p in props], dtype=np.float64)
                for k in PROPERTY_KEYS}


def _point3(ctx, value, key) -> tuple[float, float, float]:
    ok = (isinstance(value, list) and len(value) == 3
          and all(isinstance(c, (int, float)) and not isinstance(c, bool) and math.isfinite(c)
                  for c in value))
    if not ok:
        raise ctx.fail(key, f"expected a point [x, y, z] of 3 finite numbers, got {value!r}")
    return tuple(float(c) for c in value)


def _names(ctx, v, key, known) -> tuple[str, ...]:
    if isinstance(v, str):
        v = [v]
    if not isinstance(v, list) or not v or not all(isinstance(c, str) for c in v):
        raise ctx.fail(key, f"expected a non-empty array of face names, got {v!r}")
    if known is not None:
        for c in v:
            if c not in known:
                raise ctx.fail(key, f"unknown face {c!r} (known: {', '.join(known)})")
    return tuple(v)


def _inside(ctx, p, key, solid) -> None:
    if solid is None or not callable(getattr(solid, "contains", None)):
        return
    if not bool(np.asarray(solid.contains(np.array([p])))[0]):
        raise ctx.fail(key, "point ({:.12g}, {:.12g}, {:.12g}) is outside the solid".format(*p))


def _selection(ctx, t, key, known, solid) -> Selection:
    given = [k for k in ("faces", "edge", "point") if k in t]
    if len(given) != 1:
        raise ctx.fail(key, "give exactly one of 'faces' (names), 'edge' (two face names) "
                            "or 'point' ([x, y, z])")
    if "faces" in t:
        return Selection(faces=_names(ctx, t["faces"], f"{key}.faces", known))
    if "edge" in t:
        e = _names(ctx, t["edge"], f"{key}.edge", known)
        if len(e) != 2 or e[0] == e[1]:
            raise ctx.fail(f"{key}.edge", f"expected two different face names, got {list(e)}")
        return Selection(edge=(e[0], e[1]))
    p = _point3(ctx, t["point"], f"{key}.point")
    _inside(ctx, p, f"{key}.point", solid)
    return Selection(point=p)


def parse_fea3d(ctx, value, solid, constituents, units: str = "") -> FEAConfig3D:
    """Parse and check the ``[fea]`` table of a 3-D model.

    Parameters
    ----------
    ctx : the model parser's context (``fail``, ``table``, ``number``, ``string``, ``pre``)
    value : the raw table
    solid : the model's solid, or None: its ``face_names`` and ``contains`` are used for the
        checks when it has them
    constituents : sequence of str
    units : ``[model] units``

    Raises
    ------
    ModelFileError
        Unknown, missing or mistyped keys; properties missing for a constituent; an unknown
        face; a point or probe outside the solid; no displacement condition.
    """
    t = ctx.table(value, "fea", required=("properties",),
                  optional=("temperature", "displacement", "pressure", "reference_temperature",
                            "mixing", "matrix", "probes", "order", "solver"))
    scale, mixing, ref, order, matrix = parse_settings(ctx, t, units, constituents)
    solver = parse_choice(ctx, t, "solver", SOLVERS, "auto")
    props = parse_properties(ctx, t["properties"], constituents)
    known = tuple(getattr(solid, "face_names", ())) or None
    temps = []
    for i, item in enumerate(table_array(ctx, t.get("temperature", []), "fea.temperature")):
        key = f"fea.temperature[{i}]"
        tt = ctx.table(item, key, required=("value",), optional=("faces", "edge", "point"))
        v = ctx.number(tt["value"], f"{key}.value")
        if v <= 0:
            raise ctx.fail(f"{key}.value", f"expected a temperature in K above 0, got {v:g}")
        temps.append(TemperatureBC3D(_selection(ctx, tt, key, known, solid), v, key))
    disps = []
    for i, item in enumerate(table_array(ctx, t.get("displacement", []), "fea.displacement")):
        key = f"fea.displacement[{i}]"
        tt = ctx.table(item, key, optional=("faces", "edge", "point", "ux", "uy", "uz"))
        comps = {c: ctx.number(tt[c], f"{key}.{c}") if c in tt else None
                 for c in ("ux", "uy", "uz")}
        if all(c is None for c in comps.values()):
            raise ctx.fail(key, "fixes nothing: give 'ux', 'uy', 'uz' (0 to hold in place)")
        disps.append(DisplacementBC3D(_selection(ctx, tt, key, known, solid), comps["ux"],
                                      comps["uy"], comps["uz"], key))
    if not disps and ("temperature" in t or "pressure" in t):
        raise ctx.fail("fea.displacement", "at least one displacement condition is needed "
                                           "(the six rigid-body modes must be removed)")
    press = []
    for i, item in enumerate(table_array(ctx, t.get("pressure", []), "fea.pressure")):
        key = f"fea.pressure[{i}]"
        tt = ctx.table(item, key, required=("faces", "value"))
        press.append(PressureBC(Selection(faces=_names(ctx, tt["faces"], f"{key}.faces",
                                                       known)),
                                ctx.number(tt["value"], f"{key}.value"), key))
    probes_raw = t.get("probes", {})
    if not isinstance(probes_raw, Mapping):
        raise ctx.fail("fea.probes", "expected a table name = [x, y, z]")
    probes = {}
    for name, v in probes_raw.items():
        p = _point3(ctx, v, f"fea.probes.{name}")
        _inside(ctx, p, f"fea.probes.{name}", solid)
        probes[name] = p
    return FEAConfig3D(properties=props, temperature=tuple(temps), displacement=tuple(disps),
                       pressure=tuple(press), probes=probes, reference_temperature=ref,
                       mixing=mixing, matrix=matrix, length_scale=scale, order=int(order),
                       solver=solver, where=ctx.where)
