"""The 2D kernel: triangle meshes of planar domains.

Everything that knows the domain is planar and the elements are triangles lives here; the
dimension-generic parts (the mesh, the metrics, the material fields, density, export, FEA)
live beside this package in :mod:`hetmesh`.

Modules, in the order the pipeline uses them (:func:`hetmesh.tri.adapt.generate`):

- :mod:`~hetmesh.tri.geometry` -- curves, domains, the PSLG, tracing domains from images;
- :mod:`~hetmesh.tri.frame` -- the local frame (the model moved to the origin, scaled);
- :mod:`~hetmesh.tri.discontinuity` -- material discontinuities found and embedded as curves;
- :mod:`~hetmesh.tri.cdt` -- the one wrapper around the constrained Delaunay kernel;
- :mod:`~hetmesh.tri.workset` -- the working point set and its local operations;
- :mod:`~hetmesh.tri.layers` -- row placement: nodes on the composition's level lines;
- :mod:`~hetmesh.tri.cvt` -- the density-weighted Lloyd step (CVT placement);
- :mod:`~hetmesh.tri.adapt` -- the refinement loop (delta-driven insertion, Ruppert), the
  final verification, and ``generate``;
- :mod:`~hetmesh.tri.corners`, :mod:`~hetmesh.tri.geosize`, :mod:`~hetmesh.tri.sizecap` --
  small input angles, the geometric size bound, the gradient cap;
- :mod:`~hetmesh.tri.optimize` -- smoothing and flips after refinement;
- :mod:`~hetmesh.tri.verify` -- the checks of the mesh against the domain's curves;
- :mod:`~hetmesh.uniform` -- the uniform baseline.
"""
