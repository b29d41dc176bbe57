"""Model files: TOML -> :class:`Model` (a domain and a material field).

A model file is untrusted input: it is parsed with :mod:`tomllib` (no code execution), every
key is checked against the schema (unknown, missing and mistyped keys are errors), formulas
are compiled by :mod:`hetmesh.expr` and the material is sampled over the domain by
:func:`~hetmesh.material.check_field`. Every error is one line that starts with the file
name and the key path, e.g.
``power_plate.toml: unknown key 'domain.outer.pth' (expected one of: name, start, path, circle)``.
The format is documented in ``docs/model-format.md``.
"""

from __future__ import annotations

import keyword
import logging
import math
import os
import tomllib
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from importlib.resources import files
from pathlib import Path

import numpy as np

from ..errors import GeometryError, MaterialError, ModelFileError
from ..expr import FUNCTIONS
from ..fea.config import FEAConfig, parse_fea
from ..material import AnalyticField, MaterialField, check_field
from ..material.hft import parse_hft
from ..material.image.parse import parse_image, parse_image_model
from ..tri.geometry import Arc, Domain, Loop, Segment, make_domain
from ..tri.geometry import Path as CurvePath
from .schema import SchemaContext, describe

__all__ = ["Model", "load_model", "parse_model", "example_path", "MATERIAL_TYPES", "MAX_FILE_BYTES"]

logger = logging.getLogger(__name__)

#: Model files larger than this are refused (they are text written by people).
MAX_FILE_BYTES = 16 * 1024 * 1024

#: Names a parameter may not take: the coordinates and the formula constants.
RESERVED_NAMES = frozenset({"x", "y", "pi", "e"})


@dataclass(frozen=True, eq=False)
class Model:
    """A heterogeneous object: its domain and its material field.

    Parameters
    ----------
    name : str
    domain : Domain
        From :func:`hetmesh.tri.geometry.make_domain`.
    material : MaterialField
        Any object with ``constituents``, ``composition`` and ``gradient``.
    parameters : dict of str to float
        The named numbers of the model file (informational once formulas are compiled).
    source : Path or None
        The file the model was read from.
    description, units : str
        Free text from the ``[model]`` table (``units`` is the length unit, e.g. ``"mm"``;
        the FEA converts it to metres).
    fea : FEAConfig or None
        The parsed ``[fea]`` table (:mod:`hetmesh.fea.config`): properties, boundary
        conditions and probes for :func:`hetmesh.fea.solve`; None without one.

    Examples
    --------
    >>> from hetmesh.tri.geometry import Loop, Segment, make_domain
    >>> from hetmesh.material import CallableField
    >>> sq = [(0, 0), (1, 0), (1, 1), (0, 1)]
    >>> outer = Loop(tuple(Segment(a, b) for a, b in zip(sq, sq[1:] + sq[:1])), "outer")
    >>> m = Model(name="m", domain=make_domain(outer),
    ...           material=CallableField(lambda x, y: (1 - y) ** 2, ["ceramic", "metal"]))
    >>> m.constituents
    ('ceramic', 'metal')
    """

    name: str
    domain: Domain
    material: MaterialField
    parameters: dict = field(default_factory=dict)
    source: Path | None = None
    description: str = ""
    units: str = ""
    fea: FEAConfig | None = None

    def __post_init__(self):
        for attr in ("constituents", "composition", "gradient"):
            if not hasattr(self.material, attr):
                raise MaterialError(f"model {self.name!r}: material {self.material!r} has no "
                                    f"{attr!r}; expected a MaterialField")
        for attr in ("bounds", "contains", "curves"):
            if not hasattr(self.domain, attr):
                raise GeometryError(f"model {self.name!r}: domain {self.domain!r} has no "
                                    f"{attr!r}; expected a Domain from make_domain")

    @property
    def constituents(self) -> tuple[str, ...]:
        """The material's constituent names."""
        return tuple(self.material.constituents)

    def check(self, n: int = 200) -> None:
        """Raise :class:`MaterialError` unless the material is valid all over the domain."""
        where = os.fspath(self.source) if self.source is not None else f"model {self.name!r}"
        check_field(self.material, self.domain, where, n=n)


# --------------------------------------------------------------------------------- reading

def example_path(name: str) -> Path:
    """Path of a packaged example model, e.g. ``example_path("power_plate")``."""
    p = files("hetmesh") / "examples" / f"{name}.toml"
    return Path(str(p))


def load_model(path: str | os.PathLike, *, check: bool = True) -> Model:
    """Read a model file.

    Parameters
    ----------
    path : str or PathLike
        A TOML model file (``docs/model-format.md``).
    check : bool
        Sample the material over the domain (:func:`~hetmesh.material.check_field`).

    Raises
    ------
    ModelFileError, GeometryError, FormulaError, MaterialError
        With one line that starts with ``path`` and the key.

    Examples
    --------
    >>> from importlib.resources import files
    >>> m = load_model(files("hetmesh") / "examples" / "power_plate.toml")
    >>> m.name, m.constituents
    ('power_plate', ('ceramic', 'metal'))
    """
    p = Path(path)
    where = os.fspath(path)
    try:
        with open(p, "rb") as fh:
            raw = fh.read(MAX_FILE_BYTES + 1)
    except FileNotFoundError:
        raise ModelFileError(f"no such model file: {where}") from None
    except IsADirectoryError:
        raise ModelFileError(f"{where}: is a directory, not a model file") from None
    except OSError as exc:
        raise ModelFileError(f"{where}: cannot read the model file: {exc.strerror or exc}") \
            from None
    if len(raw) > MAX_FILE_BYTES:
        raise ModelFileError(f"{where}: file is larger than {MAX_FILE_BYTES} bytes; "
                             f"not a model file")
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise ModelFileError(f"{where}: not UTF-8 text (byte 0x{raw[exc.start]:02x} at "
                             f"offset {exc.start})") from None
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ModelFileError(f"{where}: not valid TOML: {exc}") from None
    return parse_model(data, where, source=p, default_name=p.stem, check=check)


def parse_model(data: Mapping, where: str = "model", *, source: Path | None = None,
                default_name: str = "model", check: bool = True) -> Model:
    """Build a :class:`Model` from a parsed model file (a dict as :mod:`tomllib` gives).

    ``where`` (normally the file name) starts every error message.

    >>> parse_model({"domain": {"outer": {"circle": {"center": [0, 0], "radius": 1}}},
    ...              "material": {"constituents": ["a", "b"],
    ...                           "composition": {"b": "x**2 + y**2"}}}).name
    'model'
    """
    if isinstance(data, Mapping) and "solid" in data:  # a 3D model (hetmesh.io.model3d)
        from .model3d import parse_model3d
        return parse_model3d(data, where, source=source, default_name=default_name,
                             check=check, parsers=(_parameters, _domain, _material))
    ctx = SchemaContext(where)
    ctx.base = source.parent if source is not None else Path(".")
    top = ctx.table(data, "", required=("domain", "material"),
                    optional=("model", "parameters", "fea"))
    info = ctx.table(top.get("model", {}), "model", optional=("name", "description", "units"))
    name = ctx.string(info, "model", "name", default=default_name)
    description = ctx.string(info, "model", "description", default="")
    units = ctx.string(info, "model", "units", default="")
    parameters = _parameters(ctx, top.get("parameters", {}))
    if isinstance(top["domain"], Mapping) and "image" in top["domain"]:
        domain, material = parse_image_model(ctx, top["domain"], top["material"])
    else:
        domain = _domain(ctx, top["domain"])
        material = _material(ctx, top["material"], domain, parameters)
    fea = (parse_fea(ctx, top["fea"], domain, material.constituents, units)
           if "fea" in top else None)
    model = Model(name=name, domain=domain, material=material, parameters=parameters,
                  source=source, description=description, units=units, fea=fea)
    if check:
        check_field(material, domain, where)
    logger.debug("%s: model %r, %d constituents", where, name, len(material.constituents))
    return model


# ------------------------------------------------------------------------------ parameters

def _reserved() -> frozenset[str]:
    return RESERVED_NAMES | frozenset(FUNCTIONS) | frozenset(keyword.kwlist)


def _parameters(ctx: SchemaContext, value) -> dict[str, float]:
    table = ctx.table(value, "parameters", optional=tuple(value) if isinstance(value, Mapping)
                      else ())
    reserved = _reserved()
    out = {}
    for name, v in table.items():
        key = f"parameters.{name}"
        if not (name.isascii() and name.isidentifier()) or name.startswith("_"):
            raise ctx.fail(key, f"{name!r} is not a valid name (letters, digits and '_', "
                                f"not starting with a digit or '_')")
        if name in reserved:
            raise ctx.fail(key, f"name {name!r} is reserved (x, y, pi, e and the formula "
                                f"functions such as sin, exp, sqrt cannot be parameters)")
        out[name] = ctx.number(v, key)
    return out


# -------------------------------------------------------------------------------- geometry

def _curves(ctx: SchemaContext, key: str, start, path) -> list:
    """Segments and arcs of ``path`` (a list of tables ``{to, name, through, center,
    direction}``) starting at ``start``."""
    p0 = ctx.point(start, f"{key}.start")
    if not isinstance(path, list) or not path:
        raise ctx.fail(f"{key}.path", f"expected a non-empty array of "
                                      f"{{ to = [x, y], ... }} tables, got {describe(path)}")
    curves = []
    for i, item in enumerate(path):
        k = f"{key}.path[{i}]"
        t = ctx.table(item, k, required=("to",),
                      optional=("name", "through", "center", "direction"))
        p1 = ctx.point(t["to"], f"{k}.to")
        name = ctx.string(t, k, "name")
        if "through" in t and "center" in t:
            raise ctx.fail(k, "give either 'through' or 'center' for an arc, not both")
        if "direction" in t and "center" not in t:
            raise ctx.fail(f"{k}.direction", "only an arc given by 'center' has a direction")
        here = ctx.pre + k
        if "through" in t:
            mid = ctx.point(t["through"], f"{k}.through")
            curve = Arc.through(p0, mid, p1, name=name, where=here)
        elif "center" in t:
            c = ctx.point(t["center"], f"{k}.center")
            curve = Arc.from_center(p0, p1, c, ccw=ctx.ccw(t, k), name=name, where=here)
        else:
            if p0 == p1:
                raise ctx.fail(f"{k}.to", f"zero-length segment: {_fmt_point(p1)} is where "
                                          f"the previous step ends", GeometryError)
            curve = Segment(p0, p1, name)
        curves.append(curve)
        p0 = p1
    return curves


def _circle(ctx: SchemaContext, key: str, value):
    t = ctx.table(value, f"{key}.circle", required=("center", "radius"))
    c = ctx.point(t["center"], f"{key}.circle.center")
    r = ctx.number(t["radius"], f"{key}.circle.radius", positive=True)
    try:
        return [Arc.circle(c, r)]
    except GeometryError as exc:
        raise ctx.wrap(f"{key}.circle", exc) from None


def _chain(ctx: SchemaContext, key: str, value, closed: bool, default_name: str):
    """``(name, curves)`` of an outer/hole (``closed``) or interface table."""
    t = ctx.table(value, key, optional=("name", "start", "path", "circle"))
    name = ctx.string(t, key, "name", default=default_name)
    if not name.strip():
        raise ctx.fail(f"{key}.name", "expected a non-empty name")
    if "circle" in t:
        if "start" in t or "path" in t:
            raise ctx.fail(key, "give either 'circle' or 'start' and 'path', not both")
        return name, _circle(ctx, key, t["circle"])
    for k in ("start", "path"):
        if k not in t:
            raise ModelFileError(f"{ctx.pre}missing key '{key}.{k}' (a curve is "
                                 f"circle = {{ center, radius }} or start = [x, y] with "
                                 f"path = [...])")
    curves = _curves(ctx, key, t["start"], t["path"])
    if closed:
        s, e = curves[0].start, curves[-1].end
        ends = [c.start for c in curves] + [e]
        span = float(np.ptp(ends, axis=0).max())
        tol = _REL_TOL * span + 64.0 * _EPS * float(np.abs(ends).max())
        if math.dist(s, e) > tol:
            raise ctx.fail(f"{key}.path[{len(curves) - 1}].to",
                           f"a closed loop must end at its start {_fmt_point(s)}, not at "
                           f"{_fmt_point(e)}", GeometryError)
    return name, curves


def _fmt_point(p) -> str:
    return f"({float(p[0]):.12g}, {float(p[1]):.12g})"


_REL_TOL = 1e-9  # geometry's relative tolerance (times the length scale)
_EPS = float(np.finfo(float).eps)


def _domain(ctx: SchemaContext, value):
    t = ctx.table(value, "domain", required=("outer",),
                  optional=("holes", "interfaces", "points"))
    used: dict[str, str] = {}  # loop / interface name -> key

    def claim(name: str, key: str):
        if name in used:
            raise ctx.fail(f"{key}.name", f"name {name!r} is already used by {used[name]}")
        used[name] = key

    def build(cls, key, curves, name):
        try:
            return cls(tuple(curves), name)
        except GeometryError as exc:
            raise ctx.wrap(key, exc) from None

    name, curves = _chain(ctx, "domain.outer", t["outer"], True, "outer")
    claim(name, "domain.outer")
    outer = build(Loop, "domain.outer", curves, name)
    holes, interfaces = [], []
    for kind, cls, out, closed, default in (("holes", Loop, holes, True, "hole"),
                                            ("interfaces", CurvePath, interfaces, False,
                                             "interface")):
        items = t.get(kind, [])
        if not isinstance(items, list):
            raise ctx.fail(f"domain.{kind}", f"expected an array of tables ([[domain.{kind}]]),"
                                             f" got {describe(items)}")
        for i, item in enumerate(items):
            key = f"domain.{kind}[{i}]"
            name, curves = _chain(ctx, key, item, closed, f"{default}[{i}]")
            claim(name, key)
            out.append(build(cls, key, curves, name))
    points = {}
    raw = t.get("points", {})
    ptable = ctx.table(raw, "domain.points",
                       optional=tuple(raw) if isinstance(raw, Mapping) else ())
    for pname, pv in ptable.items():
        points[pname] = ctx.point(pv, f"domain.points.{pname}")
    try:
        return make_domain(outer, tuple(holes), tuple(interfaces), points)
    except GeometryError as exc:
        raise ctx.fail(_owner_key(str(exc), used), str(exc), GeometryError) from None


def _owner_key(message: str, owners: Mapping[str, str]) -> str:
    """The key path of the loop, interface or point a geometry message starts with."""
    if message.startswith("point '"):
        name = message[len("point '"):].split("'", 1)[0]
        return f"domain.points.{name}"
    for name in sorted(owners, key=len, reverse=True):
        if message.startswith((f"{name}: ", f"{name} and ")):
            return owners[name]
    return "domain"


# -------------------------------------------------------------------------------- material

def _analytic(ctx: SchemaContext, table: dict, domain, parameters: dict) -> MaterialField:
    t = ctx.table(table, "material", required=("constituents", "composition"),
                  optional=("type",))
    cons = t["constituents"]
    key = "material.constituents"
    if not isinstance(cons, list) or not all(isinstance(c, str) for c in cons):
        raise ctx.fail(key, f"expected an array of names, got {describe(cons)}")
    seen = set()
    for c in cons:
        if not c.strip():
            raise ctx.fail(key, "names must be non-empty")
        if c in seen:
            raise ctx.fail(key, f"constituent {c!r} is listed twice")
        seen.add(c)
    if len(cons) < 2:
        raise ctx.fail(key, f"at least 2 constituents are needed, got {len(cons)}")
    comp = t["composition"]
    if not isinstance(comp, Mapping):
        raise ctx.fail("material.composition", f"expected a table of formulas, got "
                                               f"{describe(comp)}")
    formulas = {}
    for name, text in comp.items():
        k = f"material.composition.{name}"
        if name not in cons:
            raise ModelFileError(f"{ctx.pre}unknown key {k!r}: not a constituent "
                                 f"(expected one of: {', '.join(cons)})")
        if isinstance(text, (int, float)) and not isinstance(text, bool):
            text = repr(ctx.number(text, k))
        if not isinstance(text, str):
            raise ctx.fail(k, f"expected a formula string, got {describe(text)}")
        formulas[name] = text
    missing = [c for c in cons if c not in formulas]
    if len(missing) > 1:
        raise ModelFileError(f"{ctx.pre}missing key 'material.composition.{missing[-1]}' "
                             f"(give formulas for all {len(cons)} constituents, or all but "
                             f"one: it is then 1 - the sum of the others)")
    return AnalyticField(formulas, cons, parameters, where=ctx.where, length=domain.diameter)


#: Parsers of the ``[material]`` table by its ``type`` key:
#: ``parser(ctx, table, domain, parameters) -> MaterialField``.
MATERIAL_TYPES: dict[str, Callable] = {"analytic": _analytic}
MATERIAL_TYPES["hft"] = parse_hft  # feature trees (paper Sec. 3.3)
MATERIAL_TYPES["image"] = parse_image  # images and voxel data (docs/model-format.md)


def _material(ctx: SchemaContext, value, domain, parameters: dict) -> MaterialField:
    if not isinstance(value, Mapping):
        raise ctx.fail("material", f"expected a table, got {describe(value)}")
    kind = value.get("type", "analytic")
    if kind not in MATERIAL_TYPES:
        raise ctx.fail("material.type", f"unknown material type {kind!r} (expected one of: "
                                        f"{', '.join(MATERIAL_TYPES)})")
    return MATERIAL_TYPES[kind](ctx, dict(value), domain, parameters)
