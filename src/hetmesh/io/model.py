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

import json
import keyword
import logging
import math
import os
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Mapping

import numpy as np

from ..errors import GeometryError, HetmeshError, MaterialError, ModelFileError
from ..expr import FUNCTIONS
from ..fea.config import FEAConfig, parse_fea
from ..geometry import Arc, Loop, Segment, make_domain
from ..geometry import Path as CurvePath
from ..material import AnalyticField, MaterialField, check_field
from ..material.hft import parse_hft

__all__ = ["Model", "load_model", "parse_model", "MATERIAL_TYPES", "MAX_FILE_BYTES"]

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
        From :func:`hetmesh.geometry.make_domain`.
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
    >>> from hetmesh.geometry import Loop, Segment, make_domain
    >>> from hetmesh.material import CallableField
    >>> sq = [(0, 0), (1, 0), (1, 1), (0, 1)]
    >>> outer = Loop(tuple(Segment(a, b) for a, b in zip(sq, sq[1:] + sq[:1])), "outer")
    >>> m = Model(name="m", domain=make_domain(outer),
    ...           material=CallableField(lambda x, y: (1 - y) ** 2, ["ceramic", "metal"]))
    >>> m.constituents
    ('ceramic', 'metal')
    """

    name: str
    domain: Any
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
    ctx = _Ctx(where)
    ctx.base = source.parent if source is not None else Path(".")
    top = ctx.table(data, "", required=("domain", "material"),
                    optional=("model", "parameters", "fea"))
    info = ctx.table(top.get("model", {}), "model", optional=("name", "description", "units"))
    name = ctx.string(info, "model", "name", default=default_name)
    description = ctx.string(info, "model", "description", default="")
    units = ctx.string(info, "model", "units", default="")
    parameters = _parameters(ctx, top.get("parameters", {}))
    if isinstance(top["domain"], Mapping) and "image" in top["domain"]:
        domain, material = _image_model(ctx, top["domain"], top["material"])
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


# ------------------------------------------------------------------------- schema helpers

def _toml(value) -> str:
    """``value`` written as in a TOML file (``true``, ``"text"``, ``[1, 2]``, ``{ a = 1 }``)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return json.dumps(value, ensure_ascii=False)
    if isinstance(value, list):
        return "[" + ", ".join(_toml(v) for v in value) + "]"
    if isinstance(value, Mapping):
        return "{ " + ", ".join(f"{k} = {_toml(v)}" for k, v in value.items()) + " }"
    return repr(value)


def _describe(value) -> str:
    """A short description of a wrong value: ``[0, true] (array)``."""
    kind = {bool: "boolean", int: "integer", float: "number", str: "string", list: "array",
            dict: "table"}.get(type(value), type(value).__name__)
    text = _toml(value)
    if len(text) > 40:
        text = text[:37] + "..."
    return f"{text} ({kind})"


def _join(prefix: str, key: str) -> str:
    return f"{prefix}.{key}" if prefix else key


class _Ctx:
    """Builds error messages ``<where>: <key path>: <problem>`` for one file."""

    def __init__(self, where: str):
        self.where = where
        self.pre = f"{where}: " if where else ""

    def fail(self, key: str, problem: str, cls=ModelFileError):
        return cls(f"{self.pre}{key}: {problem}" if key else f"{self.pre}{problem}")

    def table(self, value, key: str, required=(), optional=()) -> dict:
        if not isinstance(value, Mapping):
            raise self.fail(key or "model file", f"expected a table, got {_describe(value)}")
        allowed = tuple(required) + tuple(optional)
        for k in value:
            if k not in allowed:
                raise ModelFileError(f"{self.pre}unknown key {_join(key, str(k))!r} "
                                     f"(expected one of: {', '.join(allowed)})")
        for k in required:
            if k not in value:
                raise ModelFileError(f"{self.pre}missing key {_join(key, k)!r}")
        return dict(value)

    def string(self, table: Mapping, key: str, name: str, default=None) -> str:
        if name not in table:
            return default
        v = table[name]
        if not isinstance(v, str):
            raise self.fail(_join(key, name), f"expected a string, got {_describe(v)}")
        return v

    def number(self, value, key: str, positive: bool = False) -> float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise self.fail(key, f"expected a number, got {_describe(value)}")
        v = float(value)
        if not math.isfinite(v):
            raise self.fail(key, f"expected a finite number, got {value!r}")
        if positive and v <= 0:
            raise self.fail(key, f"expected a positive number, got {value!r}")
        return v

    def point(self, value, key: str) -> tuple[float, float]:
        ok = (isinstance(value, list) and len(value) == 2
              and all(isinstance(c, (int, float)) and not isinstance(c, bool)
                      and math.isfinite(c) for c in value))
        if not ok:
            raise self.fail(key, f"expected a point [x, y] of 2 finite numbers, got "
                                 f"{_describe(value)}")
        return (float(value[0]), float(value[1]))

    def ccw(self, table: Mapping, key: str) -> bool:
        """The optional ``direction`` of ``table``: True for ``"ccw"`` (the default)."""
        direction = self.string(table, key, "direction", default="ccw")
        if direction not in ("ccw", "cw"):
            raise self.fail(f"{key}.direction", f"expected \"ccw\" or \"cw\", got "
                                                f"{direction!r}")
        return direction == "ccw"

    def wrap(self, key: str, exc: HetmeshError) -> HetmeshError:
        """Re-raise a geometry/material error with this file's prefix and ``key``."""
        msg = str(exc)
        if self.where and msg.startswith(self.where):
            return exc
        return type(exc)(f"{self.pre}{key}: {msg}" if key else f"{self.pre}{msg}")


# ------------------------------------------------------------------------------ parameters

def _reserved() -> frozenset[str]:
    return RESERVED_NAMES | frozenset(FUNCTIONS) | frozenset(keyword.kwlist)


def _parameters(ctx: _Ctx, value) -> dict[str, float]:
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

def _curves(ctx: _Ctx, key: str, start, path) -> list:
    """Segments and arcs of ``path`` (a list of tables ``{to, name, through, center,
    direction}``) starting at ``start``."""
    p0 = ctx.point(start, f"{key}.start")
    if not isinstance(path, list) or not path:
        raise ctx.fail(f"{key}.path", f"expected a non-empty array of "
                                      f"{{ to = [x, y], ... }} tables, got {_describe(path)}")
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


def _circle(ctx: _Ctx, key: str, value):
    t = ctx.table(value, f"{key}.circle", required=("center", "radius"))
    c = ctx.point(t["center"], f"{key}.circle.center")
    r = ctx.number(t["radius"], f"{key}.circle.radius", positive=True)
    try:
        return [Arc.circle(c, r)]
    except GeometryError as exc:
        raise ctx.wrap(f"{key}.circle", exc) from None


def _chain(ctx: _Ctx, key: str, value, closed: bool, default_name: str):
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


def _domain(ctx: _Ctx, value):
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
                                             f" got {_describe(items)}")
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

def _analytic(ctx: _Ctx, table: dict, domain, parameters: dict) -> MaterialField:
    t = ctx.table(table, "material", required=("constituents", "composition"),
                  optional=("type",))
    cons = t["constituents"]
    key = "material.constituents"
    if not isinstance(cons, list) or not all(isinstance(c, str) for c in cons):
        raise ctx.fail(key, f"expected an array of names, got {_describe(cons)}")
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
                                               f"{_describe(comp)}")
    formulas = {}
    for name, text in comp.items():
        k = f"material.composition.{name}"
        if name not in cons:
            raise ModelFileError(f"{ctx.pre}unknown key {k!r}: not a constituent "
                                 f"(expected one of: {', '.join(cons)})")
        if isinstance(text, (int, float)) and not isinstance(text, bool):
            text = repr(ctx.number(text, k))
        if not isinstance(text, str):
            raise ctx.fail(k, f"expected a formula string, got {_describe(text)}")
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
MATERIAL_TYPES["image"] = lambda ctx, table, domain, parameters: \
    _image_material(ctx, table, domain)  # images, voxel data (docs/model-format.md)


def _material(ctx: _Ctx, value, domain, parameters: dict) -> MaterialField:
    if not isinstance(value, Mapping):
        raise ctx.fail("material", f"expected a table, got {_describe(value)}")
    kind = value.get("type", "analytic")
    if kind not in MATERIAL_TYPES:
        raise ctx.fail("material.type", f"unknown material type {kind!r} (expected one of: "
                                        f"{', '.join(MATERIAL_TYPES)})")
    return MATERIAL_TYPES[kind](ctx, dict(value), domain, parameters)


# --------------------------------------------------------------------------------- images
#: keys of ``[material] type = "image"``
_IMAGE_KEYS = ("type", "constituents", "file", "labels", "phases", "map", "spacing", "origin",
               "bounds", "first_row", "slice", "array", "interpolation", "smoothing")


def _image_model(ctx: _Ctx, dtable, mtable):
    """``[domain] image = "extent" | "mask"``: the domain taken from the material's image."""
    from ..geometry.trace import DEFAULT_TOL, OUTSIDE, extent_domain, label_domain, mask_domain

    t = ctx.table(dtable, "domain", required=("image",), optional=("mask", "tolerance"))
    how = t["image"]
    if how not in ("extent", "mask"):
        raise ctx.fail("domain.image", f"expected \"extent\" or \"mask\", got {_describe(how)}")
    if not isinstance(mtable, Mapping) or mtable.get("type") != "image":
        raise ctx.fail("domain.image", "a domain taken from an image needs [material] "
                                       "type = \"image\"")
    tol = ctx.number(t.get("tolerance", DEFAULT_TOL), "domain.tolerance", positive=True)
    if "mask" in t and how != "mask":
        raise ctx.fail("domain.mask", "a mask file needs image = \"mask\"")
    src = _image_sources(ctx, mtable)
    shape, geo = src["shape"], src["geometry"]
    labels = src.get("labels")
    if how == "extent":
        lo, hi = geo.extent()
        domain = extent_domain(lo, hi)
        return domain, _image_material(ctx, mtable, domain, src, None)
    if "mask" in t:
        mimg = _read(ctx, "domain.mask", t["mask"], mtable, shape)
        mask = _scalar(ctx, "domain.mask", mimg) != 0
    elif labels is not None:
        mask = labels != 0
    else:
        raise ctx.fail("domain.mask", "image = \"mask\" needs a mask file (domain.mask) or a "
                                      "label image (material.labels, label 0 outside)")
    where = f"{ctx.pre}domain"
    try:
        if labels is None:
            domain = mask_domain(mask, geo.origin, geo.spacing, tol=tol, where=where)
            return domain, _image_material(ctx, mtable, domain, src, None)
        lab = np.where(mask, labels, OUTSIDE)
        domain, chains, lab = label_domain(lab, geo.origin, geo.spacing, tol=tol, where=where)
    except (GeometryError, MaterialError) as exc:
        raise ctx.wrap("domain", exc) from None
    return domain, _image_material(ctx, mtable, domain, src, (chains, lab, tol))


def _read(ctx: _Ctx, key: str, value, mtable, shape=None):
    """Read one image file named at ``key`` with the geometry keys of ``mtable``."""
    from ..material.image import read_image

    if not isinstance(value, str) or not value.strip():
        raise ctx.fail(key, f"expected a file name, got {_describe(value)}")
    path = Path(value) if os.path.isabs(value) else ctx.base / value
    array = ctx.string(mtable, "material", "array")
    img = read_image(path, array=array)
    img = _geometry(ctx, mtable, img)
    if shape is not None and img.shape != shape:
        raise MaterialError(f"{img.source}: {img.shape[1]} x {img.shape[0]} pixels, but the "
                            f"other images have {shape[1]} x {shape[0]}")
    return img


def _geometry(ctx: _Ctx, t: Mapping, img):
    """``img`` with the slice, row order, origin, spacing and bounds the model file gives."""
    from dataclasses import replace as _replace

    if "slice" in t:
        k = t["slice"]
        if isinstance(k, bool) or not isinstance(k, int):
            raise ctx.fail("material.slice", f"expected an integer, got {_describe(k)}")
        if img.dim != 3:
            raise ctx.fail("material.slice", f"{img.source} is a 2-D image, not a volume")
        if not 0 <= k < img.shape[0]:
            raise ctx.fail("material.slice", f"{k} is outside [0, {img.shape[0]}) (the "
                                             f"number of slices of {img.source})")
        img = _replace(img, values=img.values[k], origin=img.origin[:2],
                       spacing=img.spacing[:2])
    if img.dim == 3:
        raise MaterialError(f"{img.source}: a 3-D volume of {img.shape[0]} slices; 2-D "
                            f"meshing needs one of them (material.slice = k)")
    if "first_row" in t:
        row = ctx.string(t, "material", "first_row")
        if row not in ("top", "bottom"):
            raise ctx.fail("material.first_row", f"expected \"top\" or \"bottom\", got "
                                                 f"{row!r}")
        from ..material.image import RASTER_SUFFIXES

        raster = Path(img.source).suffix.lower() in RASTER_SUFFIXES + (".npy",)
        if (row == "bottom") == raster:  # undo the reader's flip, or flip
            ax = 0
            img = _replace(img, values=np.ascontiguousarray(np.flip(img.values, axis=ax)))
    n = np.array(img.shape[::-1], float)
    if "bounds" in t:
        if "origin" in t or "spacing" in t:
            raise ctx.fail("material.bounds", "give either bounds or origin/spacing, not both")
        b = t["bounds"]
        ok = isinstance(b, list) and len(b) == 4 and all(
            isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)
            for v in b)
        if not ok:
            raise ctx.fail("material.bounds", f"expected [x0, y0, x1, y1], got {_describe(b)}")
        lo, hi = np.array(b[:2], float), np.array(b[2:], float)
        if (hi <= lo).any():
            raise ctx.fail("material.bounds", f"spacing <= 0: x1 > x0 and y1 > y0 needed, "
                                              f"got {_describe(b)}")
        sp = (hi - lo) / n
        return _replace(img, origin=tuple(lo + 0.5 * sp), spacing=tuple(sp))
    sp, org = img.spacing, img.origin
    if "spacing" in t:
        v = t["spacing"]
        if isinstance(v, (int, float)) and not isinstance(v, bool):
            v = [v, v]
        s = ctx.point(v, "material.spacing")
        if min(s) <= 0:
            raise ctx.fail("material.spacing", f"spacing must be positive, got {list(s)}")
        sp = s
        if "origin" not in t and not img.origin_from_file:
            org = tuple(0.5 * np.asarray(s))
    if "origin" in t:
        org = ctx.point(t["origin"], "material.origin")
    return _replace(img, origin=tuple(float(o) for o in org),
                    spacing=tuple(float(s) for s in sp))


def _scalar(ctx: _Ctx, key: str, img) -> np.ndarray:
    if img.channels:
        raise MaterialError(f"{img.source}: {img.values.shape[-1]} channels; {key} needs a "
                            f"single-channel image")
    return img.values


def _image_sources(ctx: _Ctx, t) -> dict:
    """The images of an image material: ``{"image", "labels", "files", "shape",
    "geometry"}`` (the image whose geometry all share)."""
    t = ctx.table(t, "material", required=("type", "constituents"), optional=_IMAGE_KEYS)
    if "file" not in t and "labels" not in t:
        raise ModelFileError(f"{ctx.pre}missing key 'material.file' (an image material needs "
                             f"file = \"...\", a table of files, or labels = \"...\")")
    out: dict = {}
    shape = None
    if "labels" in t:
        lab = _read(ctx, "material.labels", t["labels"], t)
        v = _scalar(ctx, "material.labels", lab)
        if v.dtype.kind not in "ui":
            raise MaterialError(f"{lab.source}: a label image needs integer pixels, got "
                                f"{v.dtype}")
        out["labels"], shape, out["geometry"] = v.astype(np.int64), lab.shape, lab
    f = t.get("file")
    if isinstance(f, Mapping):
        out["files"] = {}
        for name, fname in f.items():
            img = _read(ctx, f"material.file.{name}", fname, t, shape)
            out["files"][name] = img
            shape = shape or img.shape
            out.setdefault("geometry", img)
    elif f is not None:
        img = _read(ctx, "material.file", f, t, shape)
        out["image"] = img
        shape = shape or img.shape
        out.setdefault("geometry", img)
    out["shape"] = shape
    return out


def _constituents(ctx: _Ctx, t) -> tuple[str, ...]:
    from ..material.analytic import check_constituents

    cons = t["constituents"]
    if not isinstance(cons, list) or not all(isinstance(c, str) for c in cons):
        raise ctx.fail("material.constituents", f"expected an array of names, got "
                                                f"{_describe(cons)}")
    try:
        return check_constituents(cons)
    except MaterialError as exc:
        raise ctx.fail("material.constituents", str(exc).split(": ", 1)[-1]) from None


def _value_map(ctx: _Ctx, key: str, value, cons, src):
    """A ``map = {...}`` table -> :class:`~hetmesh.material.image.ValueMap`."""
    from ..material.image import channel_map, linear_map, table_map

    if not isinstance(value, Mapping):
        raise ctx.fail(key, f"expected a table, got {_describe(value)}")
    kinds = [k for k in ("linear", "levels", "channels") if k in value]
    if "files" in src:
        kinds = ["files"]
    if len(kinds) != 1:
        raise ctx.fail(key, "give one of: linear = [g0, g1], levels = [...] with fractions, "
                            "channels = {...} (with range)")
    kind = kinds[0]
    m = len(cons)
    if kind == "linear":
        t = ctx.table(value, key, required=("linear", "constituent"))
        g = ctx.point(t["linear"], f"{key}.linear")
        c = ctx.string(t, key, "constituent")
        if c not in cons:
            raise ctx.fail(f"{key}.constituent", f"{c!r} is not a constituent (expected one "
                                                 f"of: {', '.join(cons)})")
        if m != 2:
            raise ctx.fail(key, f"a linear map needs 2 constituents, got {m}; use levels")
        if g[0] == g[1]:
            raise ctx.fail(f"{key}.linear", "the two grey levels must differ")
        return linear_map(g[0], g[1], cons.index(c), m)
    if kind == "levels":
        t = ctx.table(value, key, required=("levels", "fractions"))
        lv = t["levels"]
        if not (isinstance(lv, list) and len(lv) >= 2):
            raise ctx.fail(f"{key}.levels", f"expected at least 2 grey levels, got "
                                            f"{_describe(lv)}")
        levels = [ctx.number(v, f"{key}.levels[{i}]") for i, v in enumerate(lv)]
        fr = _per_constituent(ctx, f"{key}.fractions", t["fractions"], cons,
                              lambda v, k: _numbers(ctx, v, k, len(levels)))
        try:
            return table_map(levels, _complete(fr, cons, len(levels)).T)
        except MaterialError as exc:
            raise ctx.fail(key, str(exc), MaterialError) from None
    t = ctx.table(value, key, required=("range",) + (("channels",) if kind == "channels"
                                                       else ()))
    r = ctx.point(t["range"], f"{key}.range")
    if kind == "channels":
        ch = _per_constituent(ctx, f"{key}.channels", t["channels"], cons,
                              lambda v, k: _channel(ctx, v, k))
        img = src.get("image")
        if img is None or not img.channels:
            raise ctx.fail(f"{key}.channels", "the image has one channel; channels need a "
                                              "colour or multi-channel image")
        integer = img.values.dtype.kind in "ui"
    else:
        ch = {name: i for i, name in enumerate(src["files"])}
        integer = all(im.values.dtype.kind in "ui" for im in src["files"].values())
    index = [ch.get(c, -1) for c in cons]
    try:
        return channel_map(index, r[0], r[1], integer=integer)
    except MaterialError as exc:
        raise ctx.fail(f"{key}.range", str(exc), MaterialError) from None


def _channel(ctx, v, k) -> int:
    if isinstance(v, bool) or not isinstance(v, int) or v < 0:
        raise ctx.fail(k, f"expected a channel number >= 0, got {_describe(v)}")
    return v


def _numbers(ctx, v, k, n) -> list[float]:
    if not isinstance(v, list) or len(v) != n:
        raise ctx.fail(k, f"expected {n} numbers (one per level), got {_describe(v)}")
    return [ctx.number(x, f"{k}[{i}]") for i, x in enumerate(v)]


def _per_constituent(ctx, key, value, cons, item) -> dict:
    """A table keyed by constituent names, all of them or all but one."""
    if not isinstance(value, Mapping):
        raise ctx.fail(key, f"expected a table keyed by constituent, got {_describe(value)}")
    out = {}
    for name, v in value.items():
        if name not in cons:
            raise ModelFileError(f"{ctx.pre}unknown key '{key}.{name}': not a constituent "
                                 f"(expected one of: {', '.join(cons)})")
        out[name] = item(v, f"{key}.{name}")
    missing = [c for c in cons if c not in out]
    if len(missing) > 1:
        raise ModelFileError(f"{ctx.pre}missing key '{key}.{missing[-1]}' (give all "
                             f"{len(cons)} constituents, or all but one: it is then 1 - the "
                             f"sum of the others)")
    return out


def _complete(fr: dict, cons, n: int) -> np.ndarray:
    """``(m, n)`` fractions, the missing constituent 1 - the others."""
    rows = [np.asarray(fr[c], float) if c in fr else None for c in cons]
    given = sum(r for r in rows if r is not None)
    return np.vstack([r if r is not None else 1.0 - given for r in rows])


def _image_material(ctx: _Ctx, table, domain, src=None, traced=None) -> MaterialField:
    """``[material] type = "image"``: an :class:`~hetmesh.material.image.ImageField` or,
    with ``labels``, a :class:`~hetmesh.material.image.LabelField`."""
    from ..material.image import covers, image_field

    t = ctx.table(table, "material", required=("type", "constituents"), optional=_IMAGE_KEYS)
    cons = _constituents(ctx, t)
    src = src if src is not None else _image_sources(ctx, t)
    interp = ctx.string(t, "material", "interpolation", default="linear")
    if interp not in ("linear", "cubic"):
        raise ctx.fail("material.interpolation", f"expected \"linear\" or \"cubic\", got "
                                                 f"{interp!r}")
    sigma = ctx.number(t.get("smoothing", 0.0), "material.smoothing")
    if sigma < 0:
        raise ctx.fail("material.smoothing", f"expected a number >= 0, got {sigma:g}")
    geo = src["geometry"]
    covers(geo, domain.bounds, geo.source)
    opts = dict(interpolation=interp, smoothing=sigma)
    if "labels" not in src:
        if "phases" in t:
            raise ctx.fail("material.phases", "phases need a label image (material.labels)")
        if "map" not in t:
            raise ModelFileError(f"{ctx.pre}missing key 'material.map' (how pixel values "
                                 f"become volume fractions)")
        vmap = _value_map(ctx, "material.map", t["map"], cons, src)
        if "files" in src:
            stacked = np.stack([_scalar(ctx, "material.file", im).astype(float)
                                for im in src["files"].values()], axis=-1)
            from dataclasses import replace as _replace

            img = _replace(geo, values=stacked, channels=True,
                           source=", ".join(im.source for im in src["files"].values()))
            return image_field(img, vmap, cons, **opts)
        return image_field(src["image"], vmap, cons, **opts)
    if "map" in t:
        raise ctx.fail("material.map", "with a label image every phase has its own map "
                                       "([[material.phases]] map = ...)")
    return _label_field(ctx, t, domain, src, traced, cons, opts)


def _label_field(ctx, t, domain, src, traced, cons, opts):
    from ..geometry.trace import DEFAULT_TOL, OUTSIDE, label_chains, region_lookup
    from ..material.image import ImageField, LabelField

    lab_img = src["geometry"]
    labels = src["labels"]
    phases = t.get("phases", [])
    if not isinstance(phases, list):
        raise ctx.fail("material.phases", f"expected an array of tables ([[material.phases]]),"
                                          f" got {_describe(phases)}")
    if traced is None:  # the domain is given: the labels of the pixels in its bounding box
        chains_lab = None
        lo = np.floor((np.asarray(domain.bounds[:2]) - lab_img.origin) /
                      lab_img.spacing + 0.5).astype(int)
        hi = np.floor((np.asarray(domain.bounds[2:]) - lab_img.origin) /
                      lab_img.spacing + 0.5).astype(int)
        ny, nx = labels.shape
        sub = labels[max(lo[1], 0):min(hi[1], ny - 1) + 1, max(lo[0], 0):min(hi[0], nx - 1) + 1]
        present = np.unique(sub)
    else:
        chains_lab = traced
        present = np.unique(traced[1][traced[1] != OUTSIDE])
    spec: dict[int, tuple[str, object]] = {}
    for i, item in enumerate(phases):
        key = f"material.phases[{i}]"
        p = ctx.table(item, key, required=("label",), optional=("composition", "map", "name"))
        lab = p["label"]
        if isinstance(lab, bool) or not isinstance(lab, int):
            raise ctx.fail(f"{key}.label", f"expected an integer label, got {_describe(lab)}")
        if lab in spec:
            raise ctx.fail(f"{key}.label", f"label {lab} is given twice")
        name = ctx.string(p, key, "name", default=f"label {lab}")
        if ("composition" in p) == ("map" in p):
            raise ctx.fail(key, "give either composition = {...} (a constant phase) or "
                                "map = {...} (graded from material.file)")
        if "composition" in p:
            fr = _per_constituent(ctx, f"{key}.composition", p["composition"], cons,
                                  lambda v, k: ctx.number(v, k))
            c = _complete({k: [v] for k, v in fr.items()}, cons, 1)[:, 0]
            if (c < -1e-12).any() or (c > 1 + 1e-12).any():
                raise ctx.fail(f"{key}.composition", f"fractions {c.tolist()} must lie in "
                                                     f"[0, 1] and sum to 1", MaterialError)
            spec[lab] = (name, np.clip(c, 0.0, 1.0))
        else:
            if "image" not in src and "files" not in src:
                raise ctx.fail(f"{key}.map", "a graded phase needs a grey image "
                                             "(material.file)")
            spec[lab] = (name, _value_map(ctx, f"{key}.map", p["map"], cons, src))
    for lab in present.tolist():
        if lab not in spec:
            count = int((labels == lab).sum())
            j, i = np.argwhere(labels == lab)[0]
            raise MaterialError(f"{lab_img.source}: label {lab} ({count:,} pixels, the first "
                                f"at pixel ({i}, {j})) has no composition: add a "
                                f"[[material.phases]] entry with label = {lab}")
    used = [lab for lab in sorted(spec) if lab in set(present.tolist())]
    index = {lab: k for k, lab in enumerate(used)}
    fields = []
    for lab in used:
        name, what = spec[lab]
        if isinstance(what, np.ndarray):
            fields.append(what)
            continue
        inside = labels == lab
        img = src.get("image")
        values = img.values
        frac = what(values, img.source, mask=inside)
        fields.append(ImageField(_fill(frac, inside), img, cons, **opts))
    if chains_lab is None:
        tol = DEFAULT_TOL
        chains = label_chains(labels, tol)
        lab_arr = labels
    else:
        chains, lab_arr, tol = chains_lab
    region = region_lookup(chains, lab_arr, index, lab_img.origin, lab_img.spacing, tol)
    return LabelField(region, fields, [spec[lab][0] for lab in used], cons,
                      source=lab_img.source)


def _fill(frac: np.ndarray, inside: np.ndarray) -> np.ndarray:
    """``frac`` ``(m, ny, nx)`` with the pixels outside ``inside`` set to the nearest pixel
    inside, so that interpolation within a phase never mixes in another phase's pixels."""
    from scipy.ndimage import distance_transform_edt

    if inside.all():
        return frac
    idx = distance_transform_edt(~inside, return_distances=False, return_indices=True)
    return frac[(slice(None),) + tuple(idx)]
