"""Robustness testing: seeded random models and an independent check of a mesh.

hetmesh must mesh every valid model. This module makes many different valid models from a
seed, and checks a finished mesh with code that shares nothing with the pipeline's own
verification (:func:`hetmesh.tri.finish.finish`), in the spirit of :mod:`numpy.testing`: it is
used by ``tests/test_robust.py`` and ``benchmarks/bench_robust.py``, and by anyone who
changes the mesher and wants to know what they broke.

- :func:`random_model` -- the model of one seed, as **model-file TOML** (docs/model-format.md),
  so that loading it exercises the whole load path (parser, geometry validation, formula
  compiler, material sampling).
- :func:`robust_suite` -- the fixed seeded set the benchmark and the tests run.
- :func:`independent_check` -- the problems of a :class:`hetmesh.Result`, as messages; an empty
  list means the mesh is what hetmesh promises.

Families (the material field; ``FAMILIES[seed % 7]``):

``gentle``
    linear, quadratic, bilinear or bowl-shaped gradings.
``tanh``
    a front ``0.5 + 0.5 A tanh((s - s0)/w)``, straight (random direction) or circular, of
    width ``w`` from 20 % down to 0.5 % of the domain's width.
``power``
    the power law ``((x - x0)/L)**p``, ``p`` in 0.5..8 along an axis or a random direction;
    with ``p < 1`` the gradient is infinite where ``x = x0`` touches the domain (a vertex or a
    whole edge).
``sfgm``
    the sigmoid power law (S-FGM): two power-law halves ``0.5 (2u)**p`` and
    ``1 - 0.5 (2 - 2u)**p`` meeting at ``u = 1/2``, ``u`` clipped to [0, 1] so that the
    material is flat (plateaus) beyond the graded band.
``gaussian``
    one to three (possibly anisotropic) Gaussian bumps or dips, 2 % to 30 % wide.
``sines``
    products of sines, 0.3 to 3 periods across the domain.
``kink``
    distance fields with kinks: the distance to a point inside the domain or to one of its
    corners (a cone), ``abs(s - c)`` (a crease along a line), or the smaller of two ramps.

Domains: star-shaped polygons (4-9 vertices, radius jitter, no corner sharper than 20
degrees), star polygons with some edges bent into circular arcs (outward or inward),
L- and U-shaped re-entrant outlines (sometimes with a concave fillet); a random size (0.01 to
1000) and position, some far from the origin (10^3 to 10^5 widths away); 0 to 3 circular
holes (some small) that touch neither each other nor the boundary; sometimes an interface
polyline inside the domain and a named point. Every composition stays in [0, 1] over the
domain's bounding box by construction. A generated model that does not load would be a bug
of this generator, so :func:`random_model` loads every model it makes (it tries another
geometry of the same seed if one does not).

Examples
--------
>>> from hetmesh.testing import random_model, independent_check
>>> rm = random_model(5)
>>> rm.family, rm.name
('sines', 'random-0005-sines')
>>> model = rm.load()                                         # doctest: +SKIP
>>> result = hetmesh.generate(model, rm.thresholds[0])        # doctest: +SKIP
>>> independent_check(result, model, rm.thresholds[0])        # doctest: +SKIP
[]
"""

from __future__ import annotations

from .check import independent_check
from .geometry import MIN_CORNER_DEG
from .models import (
    ELEMENT_BUDGET,
    FAMILIES,
    HARD_TAGS,
    RandomModel,
    bump_toml,
    estimate,
    random_model,
    robust_suite,
)
from .surfaces import torus_surface

__all__ = ["RandomModel", "random_model", "robust_suite", "independent_check", "estimate",
           "bump_toml", "FAMILIES", "ELEMENT_BUDGET", "MIN_CORNER_DEG", "HARD_TAGS",
           "torus_surface"]
