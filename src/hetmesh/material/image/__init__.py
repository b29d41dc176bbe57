"""Material fields from images: micrographs, element maps, CT slices, voxel build data.

An image is a regular grid of samples. Here every sample is a *pixel centre*:

* ``values`` holds the samples with the spatial axes in numpy order, ``(ny, nx)`` in 2D
  and ``(nz, ny, nx)`` in 3D (a trailing channel axis for colour images), row 0 at the
  *smallest* y (physical order; raster files, stored top row first, are flipped on reading);
* ``origin`` is the position of the centre of the first pixel and ``spacing`` the distance
  between pixel centres, both in model units and in coordinate order ``(x, y[, z])``;
* the image covers the pixel squares: ``origin - spacing/2`` to
  ``origin + (n - 1/2) spacing`` per axis (:meth:`Image.extent`).

A pixel value becomes a composition through a *value map* (:class:`ValueMap`: linear between
two grey levels, a lookup table, or one channel or file per constituent), checked to lie in
[0, 1] and to sum to 1 pixel by pixel. Between pixel centres :class:`ImageField` interpolates
linearly or with a cubic B-spline, and returns the gradient of that same interpolant;
optional Gaussian pre-smoothing (its standard deviation in model units) removes measurement
noise first. A label image divides the domain into phases, each a subregion of
:class:`LabelField` (constant or graded from a grey image), whose boundaries
(:mod:`hetmesh.tri.geometry.trace`) become curves of the mesh.

Readers: PNG and other raster formats via ``imageio``, TIFF (8/16/32-bit, float, multi-page
stacks, ImageJ calibration) via ``tifffile``, NumPy ``.npy``, VTK ImageData ``.vti`` (a
small XML reader of our own), NRRD via ``pynrrd``. Every problem with a file raises
:class:`~hetmesh.errors.MaterialError` with one line naming the file and the problem.

>>> import numpy as np
>>> img = Image(np.array([[0.0, 1.0], [0.0, 1.0]]), origin=(0.5, 0.5), spacing=(1.0, 1.0))
>>> f = image_field(img, linear_map(0, 1, 1), ("a", "b"))
>>> f.composition([[1.0, 1.0]]).round(3).tolist()
[[0.5, 0.5]]
>>> f.gradient([[1.0, 1.0]])[0, 1].tolist()
[1.0, 0.0]
"""

from __future__ import annotations

from .field import INTERPOLATIONS, ImageField, LabelField, covers, image_field
from .maps import TOL, ValueMap, channel_map, linear_map, table_map
from .read import MAX_PIXELS, RASTER_SUFFIXES, SUFFIXES, Image, read_image
from .sampling import element_pixel_delta, pixel_centres_in_triangles
from .synthetic import write_examples

__all__ = ["Image", "read_image", "RASTER_SUFFIXES", "SUFFIXES", "ValueMap", "linear_map",
           "table_map", "channel_map", "ImageField", "LabelField", "image_field",
           "INTERPOLATIONS", "pixel_centres_in_triangles", "element_pixel_delta",
           "covers", "MAX_PIXELS", "TOL", "write_examples"]
