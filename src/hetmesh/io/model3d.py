"""3D model files: TOML with a ``[solid]`` table -> :class:`Model3D`.

Same conventions as the 2D format (:mod:`hetmesh.io.model`): parsed with :mod:`tomllib`, every
key checked, formulas compiled by :mod:`hetmesh.expr` (variables ``x``, ``y``, ``z``), every
error one line starting with the file name and the key path. The format is documented in
``docs/model-format.md`` (section "3D models").

>>> from hetmesh.io.model import parse_model          # dispatches to parse_model3d
>>> m = parse_model({"solid": {"type": "box", "min": [0, 0, 0], "max": [1, 1, 1]},
...                  "material": {"constituents": ["ceramic", "metal"],
...                               "composition": {"metal": "(1 - z)**2"}}})
>>> m.dim, m.solid.volume, m.constituents
(3, 1.0, ('ceramic', 'metal'))
"""

from __future__ import annotations

import logging
import math
import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import FormulaError, GeometryError, HetmeshError, MaterialError, ModelFileError
from ..material import AnalyticField
from ..tet.field3d import VARIABLES, check_field3d
from ..tet.solid import AXES, Prism, box, cylinder

__all__ = ["Model3D", "parse_model3d", "SOLID_TYPES"]

log = logging.getLogger(__name__)

SOLID_TYPES = ("box", "cylinder", "sphere", "extrusion", "revolution", "surface")


@dataclass(frozen=True, eq=False)
class Model3D:
    """A heterogeneous solid: its geometry and its material field.

    ``solid`` is a :class:`~hetmesh.tet.solid.Prism` or a
    :class:`~hetmesh.tet.revolve.Revolution`; ``fea`` the parsed 3-D ``[fea]`` table
    (:func:`hetmesh.fea.config3d.parse_fea3d`) or None; ``material`` evaluates on ``(N, 3)``
    points; ``material2d`` is the section's field when the composition does not depend on
    the extrusion coordinate (an extruded 2D model), else None.
    """

    name: str
    solid: Any
    material: Any
    material2d: Any = None
    parameters: dict = field(default_factory=dict)
    source: Path | None = None
    description: str = ""
    units: str = ""
    fea: Any = None

    dim = 3

    @property
    def constituents(self) -> tuple[str, ...]:
        return tuple(self.material.constituents)


def _ctx(where: str):
    from .schema import SchemaContext
    return SchemaContext(where)


def _point3(ctx, value, key) -> np.ndarray:
    ok = (isinstance(value, list) and len(value) == 3
          and all(isinstance(c, (int, float)) and not isinstance(c, bool) and math.isfinite(c)
                  for c in value))
    if not ok:
        from .schema import describe
        raise ctx.fail(key, f"expected a point [x, y, z] of 3 finite numbers, got "
                            f"{describe(value)}")
    return np.array(value, dtype=float)


def _axis(ctx, t, key) -> int:
    a = ctx.string(t, key, "axis", default="z")
    if a not in AXES:
        raise ctx.fail(f"{key}.axis", f"expected \"x\", \"y\" or \"z\", got {a!r}")
    return AXES[a]


def _hole(ctx, t, key, axis: int, s0: float, s1: float, uv_of):
    """A subtracted primitive as a hole loop of the section: it must go through the solid
    along its axis."""
    from ..tri.geometry import Arc, Loop, Segment
    kind = t.get("type")
    if kind == "cylinder":
        t = ctx.table(t, key, required=("type", "center", "radius"),
                      optional=("axis", "name"))
        if _axis(ctx, t, key) != axis:
            raise ctx.fail(f"{key}.axis", "a subtracted cylinder must be parallel to the "
                                          "solid's axis (through-holes only)")
        c = ctx.point(t["center"], f"{key}.center")
        r = ctx.number(t["radius"], f"{key}.radius")
        if r <= 0:
            raise GeometryError(f"{ctx.pre}{key}.radius: a primitive's size must be "
                                f"positive, got {r:g}")
        name = ctx.string(t, key, "name", default=key.replace(".", "_"))
        from dataclasses import replace
        return Loop((replace(Arc.circle(c, r), name=name),), name)
    if kind == "box":
        t = ctx.table(t, key, required=("type", "min", "max"), optional=("name",))
        lo, hi = _point3(ctx, t["min"], f"{key}.min"), _point3(ctx, t["max"], f"{key}.max")
        if (hi - lo <= 0).any():
            k = int(np.argmax(hi - lo <= 0))
            raise GeometryError(f"{ctx.pre}{key}: a primitive's size must be positive, got "
                                f"{hi[k] - lo[k]:g} along {'xyz'[k]}")
        if lo[axis] > s0 or hi[axis] < s1:
            raise ctx.fail(key, "a subtracted box must go through the solid along its axis "
                                "(through-holes only)")
        u, v = uv_of
        pts = [(lo[u], lo[v]), (hi[u], lo[v]), (hi[u], hi[v]), (lo[u], hi[v])]
        name = ctx.string(t, key, "name", default=key.replace(".", "_"))
        return Loop(tuple(Segment(a, b, name=f"{name}[{i}]") for i, (a, b) in
                          enumerate(zip(pts, pts[1:] + pts[:1]))), name)
    raise ctx.fail(f"{key}.type", f"expected \"cylinder\" or \"box\", got {kind!r}")


def _with_holes(ctx, solid: Prism, subtract, key: str) -> Prism:
    from ..tri.geometry import make_domain
    if not isinstance(subtract, list):
        raise ctx.fail(key, "expected an array of tables [[solid.subtract]]")
    holes = list(solid.section.holes)
    for i, t in enumerate(subtract):
        if not isinstance(t, Mapping):
            raise ctx.fail(f"{key}[{i}]", "expected a table")
        holes.append(_hole(ctx, t, f"{key}[{i}]", solid.axis, solid.s0, solid.s1, solid.uv))
    sec = solid.section
    try:
        dom = make_domain(sec.outer, holes=holes, interfaces=sec.interfaces,
                          points=sec.points).validate(ctx.where)
    except GeometryError as exc:
        raise ctx.wrap(key, exc) from None
    if dom.area <= 0:
        raise GeometryError(f"{ctx.pre}{key}: the subtraction leaves nothing")
    return Prism(dom, solid.axis, solid.s0, solid.s1, solid.cap_names, where=ctx.where)


def _positive(ctx, value, key: str, what: str = "a primitive's size") -> float:
    v = ctx.number(value, key)
    if not v > 0:
        raise GeometryError(f"{ctx.pre}{key}: {what} must be positive, got {v:g}")
    return v


def _primitive(ctx, t, key: str, *, base: bool, bounds=None):
    """A box, cylinder or sphere table -> a :mod:`hetmesh.tet.implicit` primitive with its
    face names: the base's (``xmin`` ... ``zmax``; ``side``, ``bottom``, ``top``;
    ``outer``), or, subtracted, ``name`` for a sphere or a cylinder's side and
    ``name.<face>`` for the others (``name`` defaults to the key, dots as underscores).
    A subtracted cylinder without ``from``/``to`` goes through ``bounds``."""
    from ..tet.implicit import BOX_FACES, Box, Cylinder, Sphere
    kind = t.get("type")
    named = () if base else ("name",)
    if kind == "box":
        t = ctx.table(t, key, required=("type", "min", "max"), optional=named)
        lo, hi = _point3(ctx, t["min"], f"{key}.min"), _point3(ctx, t["max"], f"{key}.max")
        size = hi - lo
        if (size <= 0).any():
            k = int(np.argmax(size <= 0))
            raise GeometryError(f"{ctx.pre}{key}: a primitive's size must be positive, got "
                                f"{size[k]:g} along {'xyz'[k]} (max - min)")
        name = None if base else ctx.string(t, key, "name", default=key.replace(".", "_"))
        names = BOX_FACES if base else tuple(f"{name}.{n}" for n in BOX_FACES)
        return Box(tuple(lo), tuple(hi), names)
    if kind == "cylinder":
        req = ("type", "center", "radius") + (("from", "to") if base else ())
        opt = ("axis",) + (() if base else ("from", "to", "name"))
        t = ctx.table(t, key, required=req, optional=opt)
        axis = _axis(ctx, t, key)
        c = ctx.point(t["center"], f"{key}.center")
        r = _positive(ctx, t["radius"], f"{key}.radius")
        if "from" in t or "to" in t:
            if not ("from" in t and "to" in t):
                raise ctx.fail(key, "give both 'from' and 'to' (or neither: a through-hole)")
            s0, s1 = ctx.number(t["from"], f"{key}.from"), ctx.number(t["to"], f"{key}.to")
        else:  # through the solid along its axis
            lo, hi = bounds
            pad = float(np.linalg.norm(hi - lo))
            s0, s1 = float(lo[axis]) - pad, float(hi[axis]) + pad
        if s1 <= s0:
            raise GeometryError(f"{ctx.pre}{key}: a primitive's size must be positive, got "
                                f"length {s1 - s0:g} (to - from)")
        if base:
            names = ("side", "bottom", "top")
        else:
            name = ctx.string(t, key, "name", default=key.replace(".", "_"))
            names = (name, f"{name}.bottom", f"{name}.top")
        return Cylinder(tuple(c), r, axis, s0, s1, names)
    if kind == "sphere":
        opt = ("inner_radius", "clip", "subtract") if base else ("name",)
        t = ctx.table(t, key, required=("type", "center", "radius"), optional=opt)
        c = _point3(ctx, t["center"], f"{key}.center")
        r = _positive(ctx, t["radius"], f"{key}.radius")
        name = "outer" if base else ctx.string(t, key, "name", default=key.replace(".", "_"))
        return Sphere(tuple(c), r, (name,))
    raise ctx.fail(f"{key}.type", f"expected \"box\", \"cylinder\" or \"sphere\", got "
                                  f"{kind!r}")


def _is_through(t, axis: int, s0: float, s1: float) -> bool:
    """Whether a subtract table is a through-hole of a prism along ``axis`` (the swept
    section's hole): a cylinder along the axis without ``from``/``to``, or a box reaching
    past both ends."""
    if not isinstance(t, Mapping):
        return True  # reported by _with_holes
    kind = t.get("type")
    if kind == "cylinder":
        return AXES.get(t.get("axis", "z"), -1) == axis and "from" not in t and "to" not in t
    if kind == "box":
        lo, hi = t.get("min"), t.get("max")
        try:
            return float(lo[axis]) <= s0 and float(hi[axis]) >= s1
        except (TypeError, ValueError, IndexError, KeyError):
            return True  # reported by _with_holes
    return False


def _csg(ctx, value, base, key: str = "solid"):
    """``base`` (a primitive) clipped by ``clip`` and minus the ``subtract`` primitives:
    a :class:`~hetmesh.tet.implicit.CSGSolid`."""
    from ..tet.implicit import CSGSolid, Sphere
    clip = None
    if "clip" in value:
        c = value["clip"]
        if not isinstance(c, Mapping):
            raise ctx.fail(f"{key}.clip", "expected a table { min = [...], max = [...] }")
        clip = _primitive(ctx, {"type": "box", **c}, f"{key}.clip", base=True)
        lo, hi = np.maximum(base.bounds[0], clip.bounds[0]), \
            np.minimum(base.bounds[1], clip.bounds[1])
        if (hi <= lo).any():
            raise GeometryError(f"{ctx.pre}{key}.clip: the clip box leaves nothing")
    subs = []
    if "inner_radius" in value:
        ri = _positive(ctx, value["inner_radius"], f"{key}.inner_radius")
        if ri >= base.radius:
            raise GeometryError(f"{ctx.pre}{key}.inner_radius: must be below the radius "
                                f"({ri:g} >= {base.radius:g}), or the subtraction leaves "
                                f"nothing")
        subs.append(Sphere(base.center, ri, ("inner",)))
    tables = value.get("subtract", [])
    if not isinstance(tables, list):
        raise ctx.fail(f"{key}.subtract", "expected an array of tables [[solid.subtract]]")
    lo, hi = base.bounds
    for i, t in enumerate(tables):
        k = f"{key}.subtract[{i}]"
        if not isinstance(t, Mapping):
            raise ctx.fail(k, "expected a table")
        subs.append(_primitive(ctx, t, k, base=False, bounds=(np.asarray(lo), np.asarray(hi))))
    solid = CSGSolid(base, clip, tuple(subs), where=ctx.where)
    names = solid.face_names
    if not names or not solid.sample(24).size:
        raise GeometryError(f"{ctx.pre}{key}.subtract: the subtraction leaves nothing")
    seen = set()
    for n in names:
        if n in seen:
            raise ctx.fail(f"{key}.subtract", f"two faces are named {n!r}: give the "
                                              f"subtracted primitives distinct names")
        seen.add(n)
    if solid.volume <= 1e-9 * float(np.prod(hi - lo)):
        raise GeometryError(f"{ctx.pre}{key}.subtract: the subtraction leaves nothing")
    return solid


def _general(value) -> bool:
    """Whether a box or cylinder solid needs the general mesher: a ``clip``, or a
    subtracted primitive that is not a through-hole along its axis."""
    if "clip" in value:
        return True
    subs = value.get("subtract")
    if not isinstance(subs, list) or not subs:
        return False
    if value.get("type") == "box":
        try:
            s0, s1 = float(value["min"][2]), float(value["max"][2])
        except (TypeError, ValueError, IndexError, KeyError):
            return False  # reported by the box's own checks
        axis = 2
    else:
        axis = AXES.get(value.get("axis", "z"), 2)
        try:
            s0, s1 = float(value["from"]), float(value["to"])
        except (TypeError, ValueError, KeyError):
            return False
    return not all(_is_through(t, axis, s0, s1) for t in subs)


def _as_csg(ctx, value):
    """The ``[solid]`` table of a sphere, box or cylinder as a solid of primitives
    (:class:`hetmesh.tet.implicit.CSGSolid`)."""
    key = "solid"
    base = _primitive(ctx, {k: v for k, v in value.items()
                            if k not in ("subtract", "clip", "inner_radius")}, key, base=True)
    if value.get("type") != "sphere" and "inner_radius" in value:
        raise ctx.fail(key, "unknown key 'solid.inner_radius' (a sphere's)")
    return _csg(ctx, value, base, key)


def _jumps_move_along(material, solid) -> bool:
    """Whether the jumps of a piecewise ``material`` change along a prism's axis other than
    on planes across it (then the sweep, which embeds those planes and the sweeps of section
    curves, cannot embed them)."""
    from ..tet.extrude import prism_cuts
    from ..tet.jumps import has_jumps

    if not has_jumps(material):
        return False
    try:
        prism_cuts(solid, material)
    except MaterialError:
        return True
    return False


def _solid(ctx, value, top):
    if not isinstance(value, Mapping):
        raise ctx.fail("solid", "expected a table")
    kind = value.get("type")
    key = "solid"
    try:
        if kind == "sphere" or (kind in ("box", "cylinder") and _general(value)):
            return _as_csg(ctx, value)
        if kind == "box":
            t = ctx.table(value, key, required=("type", "min", "max"), optional=("subtract",))
            lo, hi = _point3(ctx, t["min"], "solid.min"), _point3(ctx, t["max"], "solid.max")
            size = hi - lo
            if (size <= 0).any():
                k = int(np.argmax(size <= 0))
                raise GeometryError(f"{ctx.pre}solid: a primitive's size must be positive, got "
                                    f"{size[k]:g} along {'xyz'[k]} (max - min)")
            solid = box(lo, hi, where=ctx.where)
        elif kind == "cylinder":
            t = ctx.table(value, key, required=("type", "center", "radius", "from", "to"),
                          optional=("axis", "subtract"))
            axis = _axis(ctx, t, key)
            c = ctx.point(t["center"], "solid.center")
            r = ctx.number(t["radius"], "solid.radius")
            s0, s1 = ctx.number(t["from"], "solid.from"), ctx.number(t["to"], "solid.to")
            if r <= 0:
                raise GeometryError(f"{ctx.pre}solid.radius: a primitive's size must be "
                                    f"positive, got {r:g}")
            if s1 <= s0:
                raise GeometryError(f"{ctx.pre}solid: cylinder length must be positive, got "
                                    f"{s1 - s0:g} (to - from)")
            solid = cylinder(c, r, s0, s1, axis, where=ctx.where)
        elif kind == "extrusion":
            t = ctx.table(value, key, required=("type", "length"),
                          optional=("from", "subtract"))
            length = ctx.number(t["length"], "solid.length")
            if length <= 0:
                raise GeometryError(f"{ctx.pre}solid.length: extrusion length must be "
                                    f"positive, got {length:g}")
            s0 = ctx.number(t.get("from", 0.0), "solid.from")
            if "domain" not in top:
                raise ModelFileError(f"{ctx.pre}missing key 'domain' (an extrusion sweeps "
                                     f"the 2D domain of the [domain] table along z)")
            dom = ctx.parse_domain(ctx, top["domain"])
            solid = Prism(dom, 2, s0, s0 + length, where=ctx.where)
        elif kind == "surface":  # a closed triangulated surface file (tet/surface.py)
            t = ctx.table(value, key, required=("type", "file"), optional=("feature_angle",))
            f = t["file"]
            if not isinstance(f, str) or not f.strip():
                from .schema import describe
                raise ctx.fail("solid.file", f"expected a file name, got {describe(f)}")
            angle = None
            if "feature_angle" in t:
                angle = ctx.number(t["feature_angle"], "solid.feature_angle")
                if not 0 < angle < 180:
                    raise ctx.fail("solid.feature_angle", f"must be in (0, 180) degrees, got "
                                                          f"{angle:g}")
            from ..tet.surface import SurfaceSolid
            return SurfaceSolid.read(Path(f) if os.path.isabs(f) else ctx.base / f,
                                     f"{ctx.pre}solid.file: {f}", angle)
        elif kind == "revolution":
            t = ctx.table(value, key, optional=("type", "angle", "subtract"))
            angle = ctx.number(t.get("angle", 360.0), "solid.angle")
            if not 0 < angle <= 360:
                raise GeometryError(f"{ctx.pre}solid.angle: revolution angle must be in "
                                    f"(0, 360] degrees, got {angle:g}")
            if "domain" not in top:
                raise ModelFileError(f"{ctx.pre}missing key 'domain' (a revolution turns the "
                                     f"2D profile of the [domain] table, x = r, y = z, about "
                                     f"the z axis)")
            from ..tet.revolve import Revolution
            dom = ctx.parse_domain(ctx, top["domain"])
            try:
                solid = Revolution(dom, angle, where=ctx.where)
            except GeometryError as exc:
                raise GeometryError(f"{ctx.pre}solid: {str(exc)[len(ctx.pre):]}") from None
        else:
            raise ctx.fail("solid.type", f"expected one of: {', '.join(SOLID_TYPES)}; got "
                                         f"{kind!r}")
    except (GeometryError, MaterialError) as exc:
        raise ctx.wrap("", exc) if not str(exc).startswith(ctx.pre or "\0") else exc from None
    if "subtract" in value:
        solid = _subtract(ctx, solid, value["subtract"], "solid.subtract")
    return solid


def _subtract(ctx, solid, subtract, key: str):
    """A prism's through-holes into its section (:func:`_with_holes`); any other subtracted
    primitive (every one of a revolution) carved out of the swept solid: a
    :class:`~hetmesh.tet.carve.CarvedSolid`."""
    from ..tet.carve import CarvedSolid
    if not isinstance(subtract, list):
        raise ctx.fail(key, "expected an array of tables [[solid.subtract]]")
    for i, t in enumerate(subtract):
        if not isinstance(t, Mapping):
            raise ctx.fail(f"{key}[{i}]", "expected a table")
    prism = isinstance(solid, Prism)
    carved = [i for i, t in enumerate(subtract)
              if not (prism and _is_through(t, solid.axis, solid.s0, solid.s1))]
    if prism and len(carved) < len(subtract):
        solid = _with_holes(ctx, solid, [t for i, t in enumerate(subtract) if i not in carved],
                            key)
    if not carved:
        return solid
    lo, hi = solid.bounds
    prims = tuple(_primitive(ctx, subtract[i], f"{key}[{i}]", base=False,
                             bounds=(np.asarray(lo), np.asarray(hi))) for i in carved)
    out = CarvedSolid(solid, prims, where=ctx.where)
    seen = {n for n in solid.face_names}
    for n in out.face_names[len(out.face_names) - sum(f.role == "primitive"
                                                        for f in out.faces):]:
        if n in seen:
            raise ctx.fail(key, f"two faces are named {n!r}: give the subtracted primitives "
                                f"distinct names")
        seen.add(n)
    if not out.sample(24).size or out.volume <= 1e-9 * solid.volume:
        raise GeometryError(f"{ctx.pre}{key}: the subtraction leaves nothing")
    return out


def _formula_names(formulas: Mapping[str, str], parameters) -> set[str]:
    from ..expr import compile_expr
    names: set[str] = set()
    for text in formulas.values():
        try:
            names |= set(compile_expr(text, VARIABLES, parameters).names)
        except FormulaError:
            pass  # reported by the field itself, with its key
    return names


def _volume(ctx, value):
    """The volumes of an image material (already read for ``[solid] image``, else read
    now), or None: not an image material, or a 2-D image (extruded or revolved)."""
    if not isinstance(value, Mapping) or value.get("type") != "image":
        return None
    src = getattr(ctx, "volume", None)
    if src is None:
        from ..material.image.parse3d import read_volume
        src = read_volume(ctx, value)
    return src


def _material(ctx, value, solid: Prism, parameters, top):
    """``(field3d, field2d or None)``."""
    material2d = ctx.parse_material
    if not isinstance(value, Mapping):
        raise ctx.fail("material", "expected a table")
    kind = value.get("type", "analytic")
    if (volume := _volume(ctx, value)) is not None:  # a 3-D image: voxels, not a section
        from ..material.image.parse3d import parse_volume
        return parse_volume(ctx, value, solid, volume), None
    prism = isinstance(solid, Prism)
    if kind != "analytic":
        if not prism:  # a revolution: the 2D field of the profile, turned about the axis
            from ..tet.revolve import RevolvedField
            f2 = material2d(ctx, value, solid.profile, parameters)
            return RevolvedField(f2, solid), f2
        if solid.axis != 2 or "domain" not in top:
            raise ctx.fail("material.type", f"a {kind!r} material needs an extrusion or a "
                                            f"revolution of a 2D domain (it is a 2D field)")
        f2 = material2d(ctx, value, solid.section, parameters)
        from ..tet.extrude import SectionField
        return SectionField(f2, solid), f2
    t = ctx.table(value, "material", required=("constituents", "composition"),
                  optional=("type",))
    cons = t["constituents"]
    if not isinstance(cons, list) or not all(isinstance(c, str) for c in cons):
        raise ctx.fail("material.constituents", "expected an array of names")
    comp = t["composition"]
    if not isinstance(comp, Mapping):
        raise ctx.fail("material.composition", "expected a table of formulas")
    formulas = {}
    for name, text in comp.items():
        k = f"material.composition.{name}"
        if isinstance(text, (int, float)) and not isinstance(text, bool):
            text = repr(float(text))
        if not isinstance(text, str):
            raise ctx.fail(k, "expected a formula string")
        formulas[name] = text
    field3 = AnalyticField(formulas, cons, parameters, where=ctx.where,
                           length=solid.diameter, dim=3)
    if prism and solid.axis == 2 and "domain" in top and \
            "z" not in _formula_names(formulas, parameters):
        # an extruded 2D model: the section's field (subregions of formulas with jumps)
        f2 = material2d(ctx, value, solid.section, parameters)
        from ..tet.extrude import SectionField
        return SectionField(f2, solid), f2
    return field3, None


def parse_model3d(data: Mapping, where: str = "model", *, parsers: tuple,
                  source: Path | None = None, default_name: str = "model",
                  check: bool = True) -> Model3D:
    """Build a :class:`Model3D` from a parsed model file with a ``[solid]`` table.

    ``parsers``: the 2D model format's ``(parameters, domain, material)`` parsers, each
    ``(ctx, value, ...)``, for the ``[parameters]``, the extruded or revolved ``[domain]``
    and a 2D ``[material]`` (:func:`hetmesh.io.model.parse_model` passes its own; this
    module does not import that one, which imports this one).
    """
    ctx = _ctx(where)
    _parameters, ctx.parse_domain, ctx.parse_material = parsers
    ctx.base = source.parent if source is not None else Path(".")
    top = ctx.table(data, "", required=("solid", "material"),
                    optional=("model", "parameters", "domain", "fea"))
    info = ctx.table(top.get("model", {}), "model", optional=("name", "description", "units"))
    name = ctx.string(info, "model", "name", default=default_name)
    description = ctx.string(info, "model", "description", default="")
    units = ctx.string(info, "model", "units", default="")
    parameters = _parameters(ctx, top.get("parameters", {}))
    if "z" in parameters:
        raise ctx.fail("parameters.z", "name 'z' is reserved (a coordinate)")
    if "domain" in top and top["solid"].get("type") not in ("extrusion", "revolution") \
            if isinstance(top["solid"], Mapping) else False:
        raise ctx.fail("domain", "a [domain] table goes with solid.type = \"extrusion\" or "
                                 "\"revolution\" only")
    if isinstance(top["solid"], Mapping) and "image" in top["solid"]:  # a volume's extent
        from ..material.image.parse3d import volume_solid
        solid, ctx.volume = volume_solid(ctx, top["solid"], top["material"])
    else:
        solid = _solid(ctx, top["solid"], top)
        swept = getattr(solid, "swept", solid)  # a carved extrusion or revolution's
        if not isinstance(swept, Prism) and not hasattr(swept, "profile") and \
                isinstance(top["material"], Mapping) and \
                top["material"].get("type", "analytic") != "analytic":
            raise ctx.fail("material.type", "a solid of primitives or a surface takes an "
                                            "analytic material (formulas in x, y, z)")
    swept = getattr(solid, "swept", solid)
    material, material2d = _material(ctx, top["material"], swept, parameters, top)
    if isinstance(solid, Prism) and top["solid"].get("type") == "box" and \
            _jumps_move_along(material, solid):
        # a box whose jumps change along its axis on other surfaces than planes across it
        # (an inclined one, say): a solid of primitives, whose mesher cuts any jump surface
        # (a sweep embeds the sweeps of section curves and planes across its axis)
        solid = swept = _as_csg(ctx, top["solid"])
        material, material2d = _material(ctx, top["material"], solid, parameters, top)
    if swept is not solid:  # carved: meshed as a whole, not as a swept section
        from ..tet.carve import carve_refusal
        if (why := carve_refusal(swept, material if material2d is None else material2d)):
            raise ctx.fail(*why)
        material2d = None
    from ..tet.jumps import has_jumps
    from ..tet.masked import VoxelSolid
    if isinstance(solid, VoxelSolid):
        if has_jumps(material):  # embedded in solids of primitives, surfaces and sweeps
            raise ctx.fail("material", "a composition with jumps (where, sign) is not "
                                       "available for a solid from a mask (its remeshing "
                                       "does not keep the discontinuities)")
    if check:
        samples = solid.sample(20)
        try:
            check_field3d(material, samples, where)
        except HetmeshError as exc:
            raise exc from None
    fea = None
    if "fea" in top:  # the 3-D [fea] table (docs/fea.md): faces by the solid's face names
        from ..fea.config3d import parse_fea3d
        fea = parse_fea3d(ctx, top["fea"], solid, material.constituents, units)
    log.debug("%s: 3D model %r", where, name)
    return Model3D(name=name, solid=solid, material=material, material2d=material2d,
                   parameters=parameters, source=source, description=description, units=units,
                   fea=fea)


def is_3d(data: Mapping) -> bool:
    """Whether a parsed model file describes a solid (has a ``[solid]`` table)."""
    return isinstance(data, Mapping) and "solid" in data


def where_of(path) -> str:
    return os.fspath(path)
