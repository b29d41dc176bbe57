"""The ``[material] type = "hft"`` parser: TOML feature tables -> :class:`HFTField`
(schema in docs/model-format.md and the package docstring).
"""

from __future__ import annotations

import math
from typing import Mapping

import numpy as np

from ...errors import GeometryError, MaterialError, ModelFileError
from ...expr import compile_expr
from ...tri.geometry import Arc, Segment
from ..analytic import check_constituents
from .features import (BlendFeature, CurveFeature, NearestFeature, PointFeature,
                       SelectFeature, inside_predicate)
from .field import HFTField

__all__ = ["parse_hft"]


_LEAF_KEYS = {
    "point": (("at", "composition"), ()),
    "segment": (("from", "to", "composition"), ()),
    "arc": (("from", "to", "composition"), ("through", "center", "direction")),
    "circle": (("center", "radius", "composition"), ("direction",)),
}
_KINDS = ("point", "segment", "arc", "circle", "nearest", "composite", "select", "blend")


def parse_hft(ctx, table: dict, domain, parameters: dict) -> HFTField:
    """The ``[material]`` parser of ``type = "hft"`` (schema: :mod:`hetmesh.material.hft`)."""
    from ...io.model import _describe  # local: io.model imports this module

    t = ctx.table(table, "material", required=("type", "constituents", "root", "features"))
    cons = t["constituents"]
    if not isinstance(cons, list) or not all(isinstance(c, str) for c in cons):
        raise ctx.fail("material.constituents", f"expected an array of names, got "
                                                f"{_describe(cons)}")
    try:
        cons = check_constituents(cons)
    except MaterialError as exc:
        raise ctx.fail("material.constituents", str(exc).split(": ", 1)[-1]) from None
    m = len(cons)
    feats = t["features"]
    if not isinstance(feats, list) or not feats:
        raise ctx.fail("material.features", f"expected an array of tables "
                                             f"([[material.features]]), got {_describe(feats)}")
    raw: dict[str, tuple[str, dict]] = {}
    for i, item in enumerate(feats):
        key = f"material.features[{i}]"
        if not isinstance(item, Mapping):
            raise ctx.fail(key, f"expected a table, got {_describe(item)}")
        fid = item.get("id")
        if not isinstance(fid, str) or not fid.strip():
            raise ctx.fail(f"{key}.id", f"expected a non-empty feature id, got "
                                        f"{_describe(fid) if 'id' in item else 'nothing'}")
        if fid in raw:
            raise ctx.fail(f"{key}.id", f"feature {fid!r} is defined twice")
        kind = item.get("kind")
        if kind not in _KINDS:
            raise ctx.fail(f"material.features.{fid}.kind",
                           f"unknown kind {kind!r} (expected one of: {', '.join(_KINDS)})")
        raw[fid] = (f"material.features.{fid}", dict(item))
    root_id = t["root"]
    if not isinstance(root_id, str) or root_id not in raw:
        raise ctx.fail("material.root", f"unknown feature {root_id!r} (features: "
                                        f"{', '.join(raw)})")

    built: dict[str, object] = {}
    state: dict[str, int] = {}  # 1 = in progress, 2 = done

    def ref(fid: str, name, what: str, stack: list[str]):
        if not isinstance(name, str):
            raise ctx.fail(f"material.features.{fid}", f"{what}: expected a feature id, got "
                                               f"{_describe(name)}")
        if name not in raw:
            raise ctx.fail(f"material.features.{fid}", f"{what}: unknown feature {name!r}")
        return build(name, stack + [fid])

    def comp_vec(fid, v, what):
        ok = isinstance(v, list) and all(isinstance(c, (int, float)) and not isinstance(c, bool)
                                         and math.isfinite(c) for c in v)
        if not ok:
            raise ctx.fail(f"material.features.{fid}", f"{what}: expected an array of numbers, got "
                                               f"{_describe(v)}", MaterialError)
        if len(v) != m:
            raise ctx.fail(f"material.features.{fid}", f"{what} has {len(v)} values but there are "
                                               f"{m} constituents ({', '.join(cons)})",
                           MaterialError)
        a = np.array(v, dtype=float)
        if a.min() < 0 or a.max() > 1 or abs(a.sum() - 1.0) > 1e-9:
            shown = _describe(v).split(" (")[0]
            raise ctx.fail(f"material.features.{fid}", f"{what} {shown} is not a composition "
                                                       f"(values in [0, 1] summing to 1)",
                           MaterialError)
        return a

    def compositions(fid, v, pair_ok: bool):
        if isinstance(v, list) and v and all(isinstance(r, list) for r in v):
            if not pair_ok or len(v) != 2:
                raise ctx.fail(f"material.features.{fid}", "composition: expected [m numbers]" +
                               (" or [[start], [end]]" if pair_ok else ""), MaterialError)
            return comp_vec(fid, v[0], "start composition"), \
                comp_vec(fid, v[1], "end composition")
        return comp_vec(fid, v, "composition"), None

    def build(fid: str, stack: list[str]):
        if state.get(fid) == 2:
            return built[fid]
        if state.get(fid) == 1:
            cyc = stack[stack.index(fid):] + [fid]
            raise ctx.fail(f"material.features.{fid}", f"cycle in the feature tree: "
                                               f"{' -> '.join(cyc)}")
        state[fid] = 1
        key, item = raw[fid]
        kind = item["kind"]
        here = f"{ctx.pre}{key}"
        if kind in _LEAF_KEYS:
            req, opt = _LEAF_KEYS[kind]
            ctx.table(item, key, required=("id", "kind") + req, optional=opt)
            c0, c1 = compositions(fid, item["composition"], kind != "point")
            try:
                if kind == "point":
                    feat = PointFeature(fid, ctx.point(item["at"], f"{key}.at"), c0)
                elif kind == "segment":
                    a, b = ctx.point(item["from"], f"{key}.from"), ctx.point(item["to"],
                                                                          f"{key}.to")
                    if a == b:
                        raise ctx.fail(key, "zero-length segment", ModelFileError)
                    feat = CurveFeature(fid, Segment(a, b, fid), c0, c1)
                elif kind == "circle":
                    c = ctx.point(item["center"], f"{key}.center")
                    r = ctx.number(item["radius"], f"{key}.radius", positive=True)
                    feat = CurveFeature(fid, Arc.circle(c, r, ccw=ctx.ccw(item, key), name=fid),
                                        c0, c1)
                else:
                    a, b = ctx.point(item["from"], f"{key}.from"), ctx.point(item["to"],
                                                                          f"{key}.to")
                    if ("through" in item) == ("center" in item):
                        raise ctx.fail(key, "an arc needs exactly one of 'through' and "
                                            "'center'")
                    if "through" in item:
                        if "direction" in item:
                            raise ctx.fail(f"{key}.direction", "only an arc given by "
                                                               "'center' has a direction")
                        arc = Arc.through(a, ctx.point(item["through"], f"{key}.through"), b,
                                          name=fid, where=here)
                    else:
                        ccw = ctx.ccw(item, key)
                        arc = Arc.from_center(a, b, ctx.point(item["center"], f"{key}.center"),
                                              ccw=ccw, name=fid, where=here)
                    feat = CurveFeature(fid, arc, c0, c1)
            except GeometryError as exc:
                raise ctx.wrap(key, exc) from None
        elif kind in ("nearest", "composite"):
            ctx.table(item, key, required=("id", "kind", "children"))
            kids = item["children"]
            if not isinstance(kids, list) or not kids:
                raise ctx.fail(f"{key}.children", f"expected a non-empty array of feature "
                                                  f"ids, got {_describe(kids)}")
            children = [ref(fid, k, "children", stack) for k in kids]
            try:
                feat = NearestFeature(fid, children)
            except ModelFileError as exc:
                raise ctx.wrap("", exc) from None
        elif kind == "select":
            ctx.table(item, key, required=("id", "kind", "rules"))
            rules_in = item["rules"]
            if not isinstance(rules_in, list) or not rules_in:
                raise ctx.fail(f"{key}.rules", f"expected a non-empty array of "
                                               f"{{ child = ..., inside | outside | where }} "
                                               f"tables, got {_describe(rules_in)}")
            children, index, rules = [], {}, []
            for j, rt in enumerate(rules_in):
                rk = f"{key}.rules[{j}]"
                rt = ctx.table(rt, rk, required=("child",),
                               optional=("inside", "outside", "where"))
                conds = [k for k in ("inside", "outside", "where") if k in rt]
                if len(conds) > 1:
                    raise ctx.fail(rk, "give at most one of 'inside', 'outside' and 'where'")
                child = ref(fid, rt["child"], f"rules[{j}].child", stack)
                if id(child) not in index:
                    index[id(child)] = len(children)
                    children.append(child)
                pred = None
                if conds and conds[0] in ("inside", "outside"):
                    target = ref(fid, rt[conds[0]], f"rules[{j}].{conds[0]}", stack)
                    curves = target.curves() if target.geometric else []
                    if not curves:
                        raise ctx.fail(rk, f"{conds[0]}: feature {target.id!r} is not a "
                                           f"closed curve")
                    try:
                        ins = inside_predicate(curves, target.id)
                    except ModelFileError as exc:
                        raise ctx.wrap("", exc) from None
                    pred = ins if conds[0] == "inside" else (lambda p, _f=ins: ~_f(p))
                elif conds:
                    text = rt["where"]
                    if not isinstance(text, str):
                        raise ctx.fail(f"{rk}.where", f"expected a condition string, got "
                                                      f"{_describe(text)}")
                    e = compile_expr(f"where({text}, 1, 0)", ("x", "y"), parameters,
                                     where=f"{here}: rules[{j}].where {text!r}")
                    pred = (lambda p, _e=e: _e(x=p[:, 0], y=p[:, 1]) > 0.5)
                rules.append((index[id(child)], pred))
            feat = SelectFeature(fid, children, rules)
        else:  # blend
            ctx.table(item, key, required=("id", "kind", "first", "second", "distances"),
                      optional=("weight", "weights"))
            first = ref(fid, item["first"], "first", stack)
            second = ref(fid, item["second"], "second", stack)
            dist_in = item["distances"]
            if not isinstance(dist_in, Mapping) or not dist_in:
                raise ctx.fail(f"{key}.distances", f"expected a table variable = feature id, "
                                                   f"got {_describe(dist_in)}")
            distances = {}
            for var, target in dist_in.items():
                if not (var.isascii() and var.isidentifier()) or var in ("x", "y") \
                        or var in parameters:
                    raise ctx.fail(f"{key}.distances.{var}", f"{var!r} is not a usable "
                                                             f"variable name")
                distances[var] = ref(fid, target, f"distances.{var}", stack)
            weights = []
            if not isinstance(item.get("weights", []), list):
                raise ctx.fail(f"{key}.weights", f"expected an array of {{ owner, formula }} "
                                                 f"tables, got {_describe(item['weights'])}")
            for j, wt in enumerate(item.get("weights", [])):
                wk = f"{key}.weights[{j}]"
                wt = ctx.table(wt, wk, required=("owner", "formula"))
                owner = wt["owner"]
                if not isinstance(owner, str) or owner not in raw:
                    raise ctx.fail(key, f"weights[{j}].owner: unknown feature "
                                                       f"{owner!r}")
                formula = wt["formula"]
                if not isinstance(formula, str):
                    raise ctx.fail(f"{wk}.formula", f"expected a formula string, got "
                                                    f"{_describe(formula)}")
                weights.append((formula, owner))
            if "weight" in item:
                if not isinstance(item["weight"], str):
                    raise ctx.fail(f"{key}.weight", f"expected a formula string, got "
                                                    f"{_describe(item['weight'])}")
                weights.append((item["weight"], None))
            if not weights:
                raise ctx.fail(key, "a blend needs 'weight' and/or 'weights'")
            try:
                feat = BlendFeature(fid, first, second, distances, weights, parameters,
                                    where=ctx.where)
            except ModelFileError as exc:
                raise ctx.wrap("", exc) from None
        state[fid] = 2
        built[fid] = feat
        return feat

    root = build(root_id, [])
    for fid in raw:  # every feature is checked, also those the root does not reach
        build(fid, [])
    field = HFTField(root, cons)
    if domain is not None:
        field.check_domain(domain, ctx.where)
    return field
