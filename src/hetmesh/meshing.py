"""``hetmesh.generate`` and ``hetmesh.uniform``: the kernel of the model's dimension.

A planar model (:class:`~hetmesh.io.model.Model`) goes to the triangle kernel
(:func:`hetmesh.tri.pipeline.generate`, :func:`hetmesh.tri.uniform.uniform`), a solid
(:class:`~hetmesh.io.model3d.Model3D`, ``dim = 3``) to the tetrahedral one
(:func:`hetmesh.tet.api.generate`). Both return a :class:`~hetmesh.kernel.Result`.
"""

from __future__ import annotations

from .kernel import Result
from .tet.api import generate as generate_tets
from .tri.pipeline import generate as generate_triangles
from .tri.uniform import uniform as uniform_triangles

__all__ = ["generate", "uniform", "model_dim"]


def model_dim(model) -> int:
    """The dimension of ``model``'s geometry: its ``dim`` attribute, 2 without one."""
    return int(getattr(model, "dim", 2))


def generate(model, threshold: float, **options) -> Result:
    """Mesh ``model`` so that every element has delta(T) < ``threshold`` (Eq. 1), with the
    kernel of its dimension: triangles for a planar model
    (:func:`hetmesh.tri.pipeline.generate`, whose options are documented there), tetrahedra
    for a solid (:func:`hetmesh.tet.api.generate`: ``seed``, ``chord_tol``,
    ``max_elements``, ``max_size``).

    >>> import hetmesh
    >>> r = hetmesh.generate(hetmesh.load_model(hetmesh.example_path("unit_cube")), 0.2)
    >>> r.mesh.dim, r.mesh.cell_type, bool(r.stats.delta_max < 0.2)
    (3, 'tetra', True)
    """
    if model_dim(model) == 3:
        return generate_tets(model, threshold, **options)
    return generate_triangles(model, threshold, **options)


def uniform(model, threshold: float, **options) -> Result:
    """The coarsest uniform quality mesh meeting ``threshold``: triangles for a planar model
    (:func:`hetmesh.tri.uniform.uniform`), tetrahedra for a solid
    (:func:`hetmesh.tet.uniform.uniform_tets`: ``chord_tol``, ``max_elements``,
    ``min_angle`` of the section's triangles).

    >>> import hetmesh
    >>> r = hetmesh.uniform(hetmesh.load_model(hetmesh.example_path("unit_cube")), 0.3)
    >>> r.mesh.cell_type, bool(r.stats.delta_max < 0.3)
    ('tetra', True)
    """
    if model_dim(model) == 3:
        from .tet.uniform import uniform_tets

        return uniform_tets(model, threshold, **options)
    return uniform_triangles(model, threshold, **options)
