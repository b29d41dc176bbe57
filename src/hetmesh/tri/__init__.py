"""The 2D kernel: triangle meshes of planar domains.

Everything that knows the domain is planar and the elements are triangles lives here; the
dimension-generic parts (the mesh, the metrics, the material fields, density, the pieces of
the refinement loop every kernel shares, export, FEA) live beside this package in
:mod:`hetmesh` (see :mod:`hetmesh.kernel` for what a kernel provides).

Modules, in the order the pipeline (:func:`hetmesh.tri.pipeline.generate`) uses them:

- :mod:`~hetmesh.tri.pipeline` -- ``generate``: the stages composed, the placements tried,
  the fallback;
- :mod:`~hetmesh.tri.geometry` -- curves, domains, the PSLG, tracing domains from images;
- :mod:`~hetmesh.tri.frame` -- the local frame (the model moved to the origin, scaled);
- :mod:`~hetmesh.tri.discontinuity` -- material discontinuities found and embedded as curves;
- :mod:`~hetmesh.tri.cdt` -- the one wrapper around the constrained Delaunay kernel;
- :mod:`~hetmesh.tri.workset` -- the working point set and its local operations;
- :mod:`~hetmesh.tri.placement` -- MOR's starts: the CVT placement and the rows;
- :mod:`~hetmesh.tri.cvt` -- the CVT step: the density-weighted conforming Lloyd step;
- :mod:`~hetmesh.tri.layers` -- row placement: nodes on the composition's level lines;
- :mod:`~hetmesh.tri.refine` -- the refinement loop: delta-driven splits (MOR) and
  Ruppert's off-centers (GOR);
- :mod:`~hetmesh.tri.corners`, :mod:`~hetmesh.tri.geosize`, :mod:`~hetmesh.tri.sizecap` --
  small input angles, the geometric size bound, the gradient cap;
- :mod:`~hetmesh.tri.optimize` -- smoothing and flips after refinement;
- :mod:`~hetmesh.tri.finish` -- the final verification of every claim;
- :mod:`~hetmesh.tri.verify` -- the checks of the mesh against the domain's curves;
- :mod:`~hetmesh.tri.uniform` -- the uniform baseline.
"""
