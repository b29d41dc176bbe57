"""Heterogeneous Feature Tree (HFT) material fields (paper Section 3.3, case studies 2-3).

A feature tree has three kinds of node, all evaluated on whole ``(N, 2)`` arrays (no Python
loop over points):

* **Leaf features** carry a composition vector: a point, a segment, an arc or a circle. On a
  curve the composition is constant or varies linearly with arc length from its start
  composition to its end composition. A leaf gives, at every point, its distance ``d``, the
  composition at its nearest point and the gradients of both.
* **Parent features** choose one child per point: ``nearest`` (alias ``composite``; the
  child holding the nearest point, as for the bottom composite curve of case study 3) or
  ``select`` (an ordered rule list; the first rule whose predicate holds wins, e.g. "inside
  interface A -> circle C, else circle B" for the ring of Fig. 7; without a default rule
  the rules must own every point of the domain). A parent of curves is itself a curve: its
  distance is that of the chosen child.
* **Blend (region) features** mix two features through a weight
  ``f = W M_1 + (1 - W) M_2`` (Eqs. 19, 27), ``W`` a formula of named distances (``d_b``,
  ``d_int``, ...), optionally a different ``W`` per subregion (Eq. 20).

Subregions and discontinuities
------------------------------
Every feature has ``n_regions`` subregions: 1 for a leaf, the sum over its children for a
parent (1 for a *uniform* ``nearest``, whose children all carry the same constant
composition), ``n_1 * n_2`` for a blend (id ``r_1 * n_2 + r_2``). :meth:`HFTField.region` gives the
subregion owning each point and :attr:`HFTField.region_names` names them by their leaves
(``"BCD|MN"``). Inside one subregion the field is smooth; where ownership changes it may
jump (material discontinuities). ``composition(points, region=r)`` evaluates the smooth
field *of subregion* ``r`` at the points (the owning leaves are forced, their nearest-point
formulas extrapolated), so an element on a discontinuity can use its own subregion's values
at all its vertices.

Gradients
---------
Exact, by the chain rule. ``grad d`` is the unit vector from the nearest feature point to the
point. Where ``d = 0`` it is undefined; we use the curve's *left* normal (so orient boundary
curves with the material on their left, as counter-clockwise outer loops are) and the zero
vector at a point feature. The gradient of a curve's composition (linear in arc length ``s``)
is ``dM/ds * grad s``, with ``grad s`` the gradient of the nearest-point parameter: the unit
tangent for a segment, ``r/rho`` times the tangent for an arc (``rho`` the distance to the
centre), and zero where the nearest point is an end point (or at an arc's centre). The blend
gradient is ``(M_1 - M_2) sum_i dW/dd_i grad d_i + W grad M_1 + (1 - W) grad M_2``, with
``dW/dd_i`` from :meth:`hetmesh.expr.Expr.diff`. Points equidistant from two children take the
first child in the list: never NaN.

Model file schema (``[material] type = "hft"``)
-----------------------------------------------
.. code-block:: toml

    [material]
    type = "hft"
    constituents = ["ceramic", "metal"]
    root = "plate"                        # id of the root feature

    [[material.features]]                 # leaves: composition = [m numbers] (constant) or
    id = "AB"                             #   [[m numbers], [m numbers]] (start, end: linear
    kind = "segment"                      #   in arc length), every row summing to 1
    from = [0, 0]
    to = [7, 0]
    composition = [1, 0]

    [[material.features]]
    id = "BCD"
    kind = "arc"                          # from, to and either through = [x, y] or
    from = [7, 0]                         # center = [x, y] (+ direction = "ccw" | "cw")
    to = [23, 0]
    through = [15, 8]
    composition = [[1, 0], [0.75, 0.25]]

    # kind = "point": at = [x, y];  kind = "circle": center = [x, y], radius = r
    # (+ direction = "ccw" | "cw"; it fixes the left normal used where d = 0)

    [[material.features]]
    id = "bottom"
    kind = "nearest"                      # or "composite"
    children = ["AB", "BCD", "DE", "EFG", "GH"]

    [[material.features]]
    id = "boundary"
    kind = "select"                       # first matching rule wins; a rule without a
    rules = [                             # condition is a default (optional, but the rules
                                          # must then own the whole domain)
      { child = "C", inside = "A" },      # inside / outside = id of a closed curve feature
      { child = "B", where = "x > 100" }, # where = a condition in x, y (and parameters)
      { child = "B" },
    ]

    [[material.features]]
    id = "plate"
    kind = "blend"                        # f = W M_first + (1 - W) M_second
    first = "bottom"
    second = "top"
    distances = { d_b = "bottom", d_t = "top" }   # variable -> curve feature
    weight = "exp(-5*d_b/(d_b + d_t))"    # default W
    weights = [ { owner = "C", formula = "(d_b/(d_int + d_b))**3" } ]  # per subregion:
                                          # the first rule whose owner feature is on the
                                          # subregion's path wins, else `weight`

Formulas may use the model's ``[parameters]``. The full schema, with an example per construct,
is docs/model-format.md. Errors (one line, naming the feature):
:class:`~hetmesh.errors.ModelFileError` for unknown keys or kinds, an unknown feature
reference, a cycle in the tree, a blend used as a curve; :class:`~hetmesh.errors.MaterialError`
for a composition of the wrong length or not summing to 1, and, on the points of
:func:`~hetmesh.material.sample_domain` (:meth:`HFTField.check_domain`), for a weight leaving
[0, 1], a ``select`` leaving a point unowned, and a leaf the root uses lying outside the
domain (a point, or one of 64 samples of a curve, farther than 1e-6 x the domain's diameter).
"""

from __future__ import annotations

from .blend import BlendFeature
from .features import (
    CurveFeature,
    NearestFeature,
    PointFeature,
    SelectFeature,
    inside_predicate,
)
from .field import HFTField
from .parse import parse_hft

__all__ = ["HFTField", "PointFeature", "CurveFeature", "NearestFeature", "SelectFeature",
           "BlendFeature", "inside_predicate", "parse_hft"]
