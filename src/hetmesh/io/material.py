"""The graded material, carried into exported files.

The constituent properties of the model's ``[fea]`` table (``[fea.properties.<name>]``;
boundary conditions not needed) and its mixing rule (``linear`` or ``mori-tanaka``,
:mod:`hetmesh.fea.mixing`) give every element its properties:

1. **Mean composition** of each element: the material field at the 3-point (degree 2)
   quadrature rule of the triangle (the 4-point degree-2 rule of the tetrahedron),
   averaged, each element evaluated in its own feature-tree subregion (so an element
   beside a discontinuity never sees the other side).
2. **Element properties**: the mixing rule applied to the mean composition:
   ``conductivity`` (k), ``youngs_modulus`` (E), ``poisson_ratio`` (nu), ``expansion``
   (alpha). :func:`with_material` adds them and ``mean_<constituent>`` as cell data, which
   every format writes (VTU, MSH ``$ElementData``, XDMF cell attributes).
3. **Bins** for solvers that take one material per element set (Abaqus, CalculiX):
   :func:`bin_material` groups the elements whose mean compositions fall in one cell of a
   grid of width ``w`` in every constituent fraction, so within a bin no constituent varies
   by more than ``w``; choose ``w`` at most delta_0 and the binning adds no more than the
   mesh's own guarantee. Each bin gets the properties of its elements' average composition;
   :attr:`MaterialBins.max_error` is the largest relative change of any property of any
   element that binning introduced (reported by the writers).
"""

from __future__ import annotations

import logging
from collections.abc import Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from ..errors import FEAError, OptionError
from ..topology import unique

if TYPE_CHECKING:  # the writers take any mesh with Mesh's attributes
    from ..mesh import Mesh

__all__ = ["ElementMaterial", "MaterialBins", "element_material", "bin_material",
           "with_material", "material_config", "PROPERTY_NAMES"]

log = logging.getLogger(__name__)

#: the cell data names of the properties (the keys of ``[fea.properties.<name>]``)
PROPERTY_NAMES = ("conductivity", "youngs_modulus", "poisson_ratio", "expansion")

_RULE = np.array([[2 / 3, 1 / 6, 1 / 6], [1 / 6, 2 / 3, 1 / 6], [1 / 6, 1 / 6, 2 / 3]])
_A, _B = 0.5854101966249685, 0.1381966011250105  # (5 + 3 sqrt 5) / 20, (5 - sqrt 5) / 20
_RULE_TET = np.full((4, 4), _B) + np.eye(4) * (_A - _B)

#: barycentric points (equal weights) of the rule averaged for each element, by dimension
RULES = {2: _RULE, 3: _RULE_TET}


@dataclass(frozen=True, eq=False)
class ElementMaterial:
    """Per element: ``mean`` composition ``(M, m)``, ``delta`` (the largest range of a
    constituent over the element's vertices, ``(M,)``) and ``properties``
    ``{name: (M,)}``."""

    constituents: tuple[str, ...]
    mean: np.ndarray
    delta: np.ndarray
    properties: Mapping[str, np.ndarray]


@dataclass(frozen=True, eq=False)
class MaterialBins:
    """Elements grouped by composition.

    Attributes
    ----------
    width : float
        The bins' width in every constituent fraction.
    index : (M,) int
        The bin (0-based) of every element.
    composition : (B, m)
        The average mean composition of each bin's elements.
    properties : dict name -> (B,)
        Each bin's properties (the mixing rule at ``composition``).
    errors : dict name -> float
        The largest relative difference between a bin's and one of its elements' property.
    """

    width: float
    index: np.ndarray
    composition: np.ndarray
    properties: Mapping[str, np.ndarray]
    errors: Mapping[str, float]

    @property
    def count(self) -> int:
        return len(self.composition)

    @property
    def max_error(self) -> float:
        return max(self.errors.values(), default=0.0)


def material_config(model):
    """The model's ``[fea]`` table, or :class:`FEAError` naming what is missing."""
    cfg = getattr(model, "fea", None)
    if cfg is None:
        raise FEAError(f"model {model.name!r} has no [fea] table: the graded material needs "
                       f"the constituent properties ([fea.properties.<constituent>]) and the "
                       f"mixing rule; see docs/model-format.md")
    return cfg


def element_material(mesh: Mesh, model, config=None) -> ElementMaterial:
    """Mean compositions, vertex ranges and mixed properties of every element of ``mesh``
    (a triangle or tetrahedral mesh of ``model``, in its coordinates)."""
    from ..fea.mixing import mix_config
    from ..material.field import element_subregions, has_subregions

    cfg = config if config is not None else material_config(model)
    field = model.material
    P, t = np.asarray(mesh.points), np.asarray(mesh.cells)
    M, rule = len(t), RULES[P.shape[1]]
    sub = element_subregions(field, P, t) if has_subregions(field) else None

    def comp(x: np.ndarray) -> np.ndarray:  # (M, d) -> (M, m), each in its subregion
        c = field.composition(x) if sub is None else field.composition(x, region=sub)
        return np.asarray(c, np.float64)

    corners = P[t]  # (M, d + 1, d)
    mean = sum(comp(np.einsum("k,mkd->md", w, corners)) for w in rule) / len(rule)
    at = np.stack([comp(corners[:, k]) for k in range(t.shape[1])], axis=1)  # (M, d + 1, m)
    delta = (at.max(axis=1) - at.min(axis=1)).max(axis=1) if M else np.zeros(0)
    if not np.isfinite(mean).all():
        raise FEAError("the material field gave a non-finite composition inside an element")
    props = mix_config(mean, cfg, field.constituents)
    return ElementMaterial(tuple(field.constituents), mean, delta, props)


def bin_material(material: ElementMaterial, width: float, config, constituents) -> MaterialBins:
    """Group the elements by composition in bins of ``width`` (see the module docstring)."""
    from ..fea.mixing import mix_config

    if not (0 < width <= 1):
        raise OptionError(f"the composition bin width must be in (0, 1], got {width:g}")
    key = np.floor(material.mean / width).astype(np.int64)
    _, index, counts = unique(key, axis=0, return_inverse=True, return_counts=True)
    index = index.ravel()
    comp = np.zeros((len(counts), material.mean.shape[1]))
    np.add.at(comp, index, material.mean)
    comp /= counts[:, None]
    props = mix_config(comp, config, constituents)
    errors = {}
    for k, v in props.items():
        elem = material.properties[k]
        scale = np.maximum(np.abs(elem), 1e-300)
        errors[k] = float(np.max(np.abs(v[index] - elem) / scale, initial=0.0))
    return MaterialBins(float(width), index, comp, props, errors)


def with_material(mesh: Mesh, material: ElementMaterial) -> Mesh:
    """``mesh`` with the element properties and ``mean_<constituent>`` as cell data."""
    data = {k: material.properties[k] for k in PROPERTY_NAMES if k in material.properties}
    data.update({f"mean_{c}": material.mean[:, i] for i, c in enumerate(material.constituents)})
    return mesh.with_data(cell_data=data)
