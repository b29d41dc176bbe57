"""The ``[material] type = "hft"`` parser: TOML feature tables -> :class:`HFTField`
(schema in docs/model-format.md and the package docstring).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from contextlib import contextmanager

import numpy as np

from ...errors import GeometryError, MaterialError, ModelFileError
from ...expr import compile_expr
from ...io.schema import describe
from ...tri.geometry import Arc, Segment
from ..analytic import check_constituents
from .blend import BlendFeature
from .features import (
    CurveFeature,
    NearestFeature,
    PointFeature,
    SelectFeature,
    inside_predicate,
)
from .field import HFTField

__all__ = ["parse_hft", "BUILDERS", "FeatureTree"]


_LEAF_KEYS = {
    "point": (("at", "composition"), ()),
    "segment": (("from", "to", "composition"), ()),
    "arc": (("from", "to", "composition"), ("through", "center", "direction")),
    "circle": (("center", "radius", "composition"), ("direction",)),
}


def parse_hft(ctx, table: dict, domain, parameters: dict) -> HFTField:
    """The ``[material]`` parser of ``type = "hft"`` (schema: :mod:`hetmesh.material.hft`).

    Every feature table is built by the builder of its kind (:data:`BUILDERS`), children
    first; every feature is built and checked, also those the root does not reach.
    """
    t = ctx.table(table, "material", required=("type", "constituents", "root", "features"))
    cons = _constituents(ctx, t["constituents"])
    raw = _feature_tables(ctx, t["features"])
    root_id = t["root"]
    if not isinstance(root_id, str) or root_id not in raw:
        raise ctx.fail("material.root", f"unknown feature {root_id!r} (features: "
                                        f"{', '.join(raw)})")
    tree = FeatureTree(ctx, raw, cons, parameters)
    root = tree.build(root_id, [])
    for fid in raw:
        tree.build(fid, [])
    field = HFTField(root, cons)
    if domain is not None:
        field.check_domain(domain, ctx.where)
    return field


def _constituents(ctx, cons) -> list[str]:
    if not isinstance(cons, list) or not all(isinstance(c, str) for c in cons):
        raise ctx.fail("material.constituents", f"expected an array of names, got "
                                                f"{describe(cons)}")
    try:
        return check_constituents(cons)
    except MaterialError as exc:
        raise ctx.fail("material.constituents", str(exc).split(": ", 1)[-1]) from None


def _feature_tables(ctx, feats) -> dict[str, tuple[str, dict]]:
    """Feature id -> (its key path, its table), each table's id and kind checked."""
    if not isinstance(feats, list) or not feats:
        raise ctx.fail("material.features", f"expected an array of tables "
                                             f"([[material.features]]), got {describe(feats)}")
    raw: dict[str, tuple[str, dict]] = {}
    for i, item in enumerate(feats):
        key = f"material.features[{i}]"
        if not isinstance(item, Mapping):
            raise ctx.fail(key, f"expected a table, got {describe(item)}")
        fid = item.get("id")
        if not isinstance(fid, str) or not fid.strip():
            raise ctx.fail(f"{key}.id", f"expected a non-empty feature id, got "
                                        f"{describe(fid) if 'id' in item else 'nothing'}")
        if fid in raw:
            raise ctx.fail(f"{key}.id", f"feature {fid!r} is defined twice")
        kind = item.get("kind")
        if not isinstance(kind, str) or kind not in BUILDERS:
            raise ctx.fail(f"material.features.{fid}.kind",
                           f"unknown kind {kind!r} (expected one of: {', '.join(BUILDERS)})")
        raw[fid] = (f"material.features.{fid}", dict(item))
    return raw


class FeatureTree:
    """The features of one ``[material]`` table, built on demand, children first.

    ``raw`` maps a feature id to its key path and table; :meth:`build` builds a feature
    once (later calls return it) and reports a cycle in the tree.
    """

    def __init__(self, ctx, raw: dict[str, tuple[str, dict]], constituents: list[str],
                 parameters: dict):
        self.ctx = ctx
        self.raw = raw
        self.constituents = constituents
        self.parameters = parameters
        self.built: dict[str, object] = {}
        self.building: set[str] = set()

    def build(self, fid: str, stack: list[str]):
        """The feature ``fid``; ``stack`` lists the features whose building asked for it."""
        if fid in self.built:
            return self.built[fid]
        if fid in self.building:
            cyc = stack[stack.index(fid):] + [fid]
            raise self.ctx.fail(f"material.features.{fid}", f"cycle in the feature tree: "
                                                            f"{' -> '.join(cyc)}")
        self.building.add(fid)
        key, item = self.raw[fid]
        feat = BUILDERS[item["kind"]](self, fid, key, item, stack)
        self.building.discard(fid)
        self.built[fid] = feat
        return feat

    def ref(self, fid: str, name, what: str, stack: list[str]):
        """The feature ``name`` that ``fid``'s ``what`` refers to."""
        if not isinstance(name, str):
            raise self.ctx.fail(f"material.features.{fid}", f"{what}: expected a feature id, "
                                                            f"got {describe(name)}")
        if name not in self.raw:
            raise self.ctx.fail(f"material.features.{fid}", f"{what}: unknown feature "
                                                            f"{name!r}")
        return self.build(name, stack + [fid])

    def composition(self, fid: str, v, what: str) -> np.ndarray:
        """``v`` checked as one composition (m fractions in [0, 1] summing to 1)."""
        ctx, m, cons = self.ctx, len(self.constituents), self.constituents
        ok = isinstance(v, list) and all(isinstance(c, (int, float)) and not isinstance(c, bool)
                                         and math.isfinite(c) for c in v)
        if not ok:
            raise ctx.fail(f"material.features.{fid}", f"{what}: expected an array of numbers, "
                                                       f"got {describe(v)}", MaterialError)
        if len(v) != m:
            raise ctx.fail(f"material.features.{fid}", f"{what} has {len(v)} values but there "
                                                       f"are {m} constituents "
                                                       f"({', '.join(cons)})", MaterialError)
        a = np.array(v, dtype=float)
        if a.min() < 0 or a.max() > 1 or abs(a.sum() - 1.0) > 1e-9:
            shown = describe(v).split(" (")[0]
            raise ctx.fail(f"material.features.{fid}", f"{what} {shown} is not a composition "
                                                       f"(values in [0, 1] summing to 1)",
                           MaterialError)
        return a

    def leaf(self, fid: str, key: str, item: dict) -> tuple[np.ndarray, np.ndarray | None]:
        """A leaf's keys checked; its start and end compositions (end None: constant)."""
        kind = item["kind"]
        req, opt = _LEAF_KEYS[kind]
        self.ctx.table(item, key, required=("id", "kind") + req, optional=opt)
        v = item["composition"]
        if isinstance(v, list) and v and all(isinstance(r, list) for r in v):
            if kind == "point" or len(v) != 2:
                raise self.ctx.fail(f"material.features.{fid}", "composition: expected "
                                    "[m numbers]" + ("" if kind == "point" else
                                                     " or [[start], [end]]"), MaterialError)
            return (self.composition(fid, v[0], "start composition"),
                    self.composition(fid, v[1], "end composition"))
        return self.composition(fid, v, "composition"), None


@contextmanager
def _geometry_errors(ctx, key: str):
    """A :class:`GeometryError` re-raised with the file's name and ``key``."""
    try:
        yield
    except GeometryError as exc:
        raise ctx.wrap(key, exc) from None


# ---------------------------------------------------------------------------- builders
# Each builds the feature of one kind from its table: (tree, id, key path, table, stack).

def _point(tree: FeatureTree, fid: str, key: str, item: dict, stack: list[str]):
    c0, _ = tree.leaf(fid, key, item)
    with _geometry_errors(tree.ctx, key):
        return PointFeature(fid, tree.ctx.point(item["at"], f"{key}.at"), c0)


def _segment(tree: FeatureTree, fid: str, key: str, item: dict, stack: list[str]):
    ctx = tree.ctx
    c0, c1 = tree.leaf(fid, key, item)
    with _geometry_errors(ctx, key):
        a, b = ctx.point(item["from"], f"{key}.from"), ctx.point(item["to"], f"{key}.to")
        if a == b:
            raise ctx.fail(key, "zero-length segment", ModelFileError)
        return CurveFeature(fid, Segment(a, b, fid), c0, c1)


def _circle(tree: FeatureTree, fid: str, key: str, item: dict, stack: list[str]):
    ctx = tree.ctx
    c0, c1 = tree.leaf(fid, key, item)
    with _geometry_errors(ctx, key):
        c = ctx.point(item["center"], f"{key}.center")
        r = ctx.number(item["radius"], f"{key}.radius", positive=True)
        return CurveFeature(fid, Arc.circle(c, r, ccw=ctx.ccw(item, key), name=fid), c0, c1)


def _arc(tree: FeatureTree, fid: str, key: str, item: dict, stack: list[str]):
    ctx = tree.ctx
    here = f"{ctx.pre}{key}"
    c0, c1 = tree.leaf(fid, key, item)
    with _geometry_errors(ctx, key):
        a, b = ctx.point(item["from"], f"{key}.from"), ctx.point(item["to"], f"{key}.to")
        if ("through" in item) == ("center" in item):
            raise ctx.fail(key, "an arc needs exactly one of 'through' and 'center'")
        if "through" in item:
            if "direction" in item:
                raise ctx.fail(f"{key}.direction", "only an arc given by 'center' has a "
                                                   "direction")
            arc = Arc.through(a, ctx.point(item["through"], f"{key}.through"), b,
                              name=fid, where=here)
        else:
            ccw = ctx.ccw(item, key)
            arc = Arc.from_center(a, b, ctx.point(item["center"], f"{key}.center"),
                                  ccw=ccw, name=fid, where=here)
        return CurveFeature(fid, arc, c0, c1)


def _nearest(tree: FeatureTree, fid: str, key: str, item: dict, stack: list[str]):
    ctx = tree.ctx
    ctx.table(item, key, required=("id", "kind", "children"))
    kids = item["children"]
    if not isinstance(kids, list) or not kids:
        raise ctx.fail(f"{key}.children", f"expected a non-empty array of feature ids, got "
                                          f"{describe(kids)}")
    children = [tree.ref(fid, k, "children", stack) for k in kids]
    try:
        return NearestFeature(fid, children)
    except ModelFileError as exc:
        raise ctx.wrap("", exc) from None


def _select(tree: FeatureTree, fid: str, key: str, item: dict, stack: list[str]):
    ctx = tree.ctx
    ctx.table(item, key, required=("id", "kind", "rules"))
    rules_in = item["rules"]
    if not isinstance(rules_in, list) or not rules_in:
        raise ctx.fail(f"{key}.rules", f"expected a non-empty array of "
                                       f"{{ child = ..., inside | outside | where }} "
                                       f"tables, got {describe(rules_in)}")
    children, index, rules = [], {}, []
    for j, rt in enumerate(rules_in):
        child, pred = _select_rule(tree, fid, key, j, rt, stack)
        if id(child) not in index:
            index[id(child)] = len(children)
            children.append(child)
        rules.append((index[id(child)], pred))
    return SelectFeature(fid, children, rules)


def _select_rule(tree: FeatureTree, fid: str, key: str, j: int, rt, stack: list[str]):
    """The child and the condition (None: always) of a select's rule ``j``."""
    ctx = tree.ctx
    rk = f"{key}.rules[{j}]"
    rt = ctx.table(rt, rk, required=("child",), optional=("inside", "outside", "where"))
    conds = [k for k in ("inside", "outside", "where") if k in rt]
    if len(conds) > 1:
        raise ctx.fail(rk, "give at most one of 'inside', 'outside' and 'where'")
    child = tree.ref(fid, rt["child"], f"rules[{j}].child", stack)
    if not conds:
        return child, None
    if conds[0] in ("inside", "outside"):
        target = tree.ref(fid, rt[conds[0]], f"rules[{j}].{conds[0]}", stack)
        curves = target.curves() if target.geometric else []
        if not curves:
            raise ctx.fail(rk, f"{conds[0]}: feature {target.id!r} is not a closed curve")
        try:
            ins = inside_predicate(curves, target.id)
        except ModelFileError as exc:
            raise ctx.wrap("", exc) from None
        return child, (ins if conds[0] == "inside" else (lambda p, _f=ins: ~_f(p)))
    text = rt["where"]
    if not isinstance(text, str):
        raise ctx.fail(f"{rk}.where", f"expected a condition string, got {describe(text)}")
    e = compile_expr(f"where({text}, 1, 0)", ("x", "y"), tree.parameters,
                     where=f"{ctx.pre}{key}: rules[{j}].where {text!r}")
    return child, (lambda p, _e=e: _e(x=p[:, 0], y=p[:, 1]) > 0.5)


def _blend(tree: FeatureTree, fid: str, key: str, item: dict, stack: list[str]):
    ctx = tree.ctx
    ctx.table(item, key, required=("id", "kind", "first", "second", "distances"),
              optional=("weight", "weights"))
    first = tree.ref(fid, item["first"], "first", stack)
    second = tree.ref(fid, item["second"], "second", stack)
    distances = _blend_distances(tree, fid, key, item["distances"], stack)
    weights = _blend_weights(tree, key, item)
    try:
        return BlendFeature(fid, first, second, distances, weights, tree.parameters,
                            where=ctx.where)
    except ModelFileError as exc:
        raise ctx.wrap("", exc) from None


def _blend_distances(tree: FeatureTree, fid: str, key: str, dist_in, stack: list[str]) -> dict:
    """A blend's ``distances``: formula variable -> the feature it is the distance to."""
    ctx = tree.ctx
    if not isinstance(dist_in, Mapping) or not dist_in:
        raise ctx.fail(f"{key}.distances", f"expected a table variable = feature id, "
                                           f"got {describe(dist_in)}")
    distances = {}
    for var, target in dist_in.items():
        if not (var.isascii() and var.isidentifier()) or var in ("x", "y") \
                or var in tree.parameters:
            raise ctx.fail(f"{key}.distances.{var}", f"{var!r} is not a usable variable name")
        distances[var] = tree.ref(fid, target, f"distances.{var}", stack)
    return distances


def _blend_weights(tree: FeatureTree, key: str, item: dict) -> list[tuple[str, str | None]]:
    """A blend's weight formulas with their owners (None: the ``weight`` of the rest)."""
    ctx = tree.ctx
    weights = []
    if not isinstance(item.get("weights", []), list):
        raise ctx.fail(f"{key}.weights", f"expected an array of {{ owner, formula }} "
                                         f"tables, got {describe(item['weights'])}")
    for j, wt in enumerate(item.get("weights", [])):
        wk = f"{key}.weights[{j}]"
        wt = ctx.table(wt, wk, required=("owner", "formula"))
        owner = wt["owner"]
        if not isinstance(owner, str) or owner not in tree.raw:
            raise ctx.fail(key, f"weights[{j}].owner: unknown feature {owner!r}")
        formula = wt["formula"]
        if not isinstance(formula, str):
            raise ctx.fail(f"{wk}.formula", f"expected a formula string, got "
                                            f"{describe(formula)}")
        weights.append((formula, owner))
    if "weight" in item:
        if not isinstance(item["weight"], str):
            raise ctx.fail(f"{key}.weight", f"expected a formula string, got "
                                            f"{describe(item['weight'])}")
        weights.append((item["weight"], None))
    if not weights:
        raise ctx.fail(key, "a blend needs 'weight' and/or 'weights'")
    return weights


#: The builder of every feature kind; the order is the one error messages list.
BUILDERS: dict[str, Callable] = {
    "point": _point,
    "segment": _segment,
    "arc": _arc,
    "circle": _circle,
    "nearest": _nearest,
    "composite": _nearest,  # a curve made of pieces: the nearest piece's value
    "select": _select,
    "blend": _blend,
}
