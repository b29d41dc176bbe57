"""Write the example images and the model files that read them, into this folder.

    python examples/images/make_images.py            # then, for instance:
    hetmesh mesh examples/images/graded_part_noisy.toml -d 0.05 -o part.vtu --plot part.png

Nothing is downloaded; every image is computed (``hetmesh.material.image.synthetic``):

* ``graded_part_clean.tif`` -- a 40 x 20 mm plate, 512 x 256 pixels, 16-bit grey: the metal
  fraction rises from 0 at the bottom to 1 at the top across an 8 mm wide front that waves
  around y = 10 mm (0.5 (1 + tanh((y - 10 - 2 sin(2 pi x / 40)) / 4))), grey = 65535 x metal;
* ``graded_part.tif`` -- the same with 2 % grey-level noise (Gaussian, standard deviation
  0.02 x 65535, seed 0), as a measured map would have;
* ``two_phase_labels.png`` / ``two_phase_grey.png`` -- a label image (1 matrix, 2 a graded
  round inclusion, 3 a metal particle, 0 a hole) and the grey image grading the inclusion;
* ``graded_volume.tif`` -- a 3D volume, a TIFF stack of 96 pages of 96 x 96 voxels, 16-bit,
  covering a 20 mm cube (ImageJ calibration in the file: unit mm, pixel size and slice
  spacing 20/96 mm): the metal fraction is 0 in a ceramic core and 1 in a metal shell,
  0.5 (1 + tanh((r - 6 - 1.5 sin(2 pi z / 20)) / 3)) with r the distance to the cube's
  centre (10, 10, 10), plus 2 % grey-level noise (seed 0). Mesh it with tetrahedra:

      hetmesh mesh examples/images/graded_volume.toml -d 0.1 -o cube.vtu --plot cube.png

* ``masked_part_mask.tif`` / ``masked_part.tif`` -- a mask volume and a grey volume, TIFF
  stacks of 48 pages of 48 x 48 voxels covering a 24 mm cube (calibrated, 0.5 mm): the mask
  is 255 in a cylinder of radius 10 mm about x = y = 12 mm from z = 2 to 22 mm, except a
  ball of radius 4 mm about (12, 12, 13) (an enclosed cavity), 0 elsewhere; the grey is
  65535 x 0.5 (1 + tanh((z - 12 - 2 sin(2 pi x / 24)) / 4)). The solid is the mask's
  non-zero voxels:

      hetmesh mesh examples/images/masked_part.toml -d 0.1 -o part.vtu

* ``phase_volume_labels.tif`` / ``phase_volume_grey.tif`` -- a label volume and a grey
  volume, 8-bit TIFF stacks of 32 pages of 32 x 32 voxels covering a 16 mm cube
  (calibrated, 0.5 mm): label 1 a matrix, 2 the ball of radius 5 mm about (7, 8, 8) (its
  grey 255 x (0.2 + 0.6 r / 5), r the distance to that centre), 3 a fibre of radius
  1.5 mm along x about y = 12, z = 4, 0 a hole of radius 2 mm along z about x = y = 3:

      hetmesh mesh examples/images/phase_volume.toml -d 0.1 -o phases.vtu

The model files (``graded_part.toml``, ``graded_part_noisy.toml``, ``two_phase.toml``,
``graded_volume.toml``, ``masked_part.toml``, ``phase_volume.toml``) are also in this
folder; this script rewrites them from the same text (hetmesh.material.image.synthetic.
MODELS). Options: ``--out DIR``, ``--size NX NY``, ``--volume N`` (voxels per edge of the
cube), ``--masked N`` (voxels per edge of the masked part's cube), ``--phases N`` (voxels
per edge of the label volume), ``--noise F``, ``--seed S``.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from hetmesh.material.image.synthetic import write_examples


def main(argv=None) -> int:
    here = Path(__file__).resolve().parent
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", type=Path, default=here, help="folder (default: this one)")
    p.add_argument("--size", type=int, nargs=2, default=(512, 256), metavar=("NX", "NY"),
                   help="pixels of the graded part (default: 512 256)")
    p.add_argument("--noise", type=float, default=0.02,
                   help="grey-level noise, fraction of the range (default: 0.02)")
    p.add_argument("--volume", type=int, default=96, metavar="N",
                   help="voxels per edge of the graded cube (default: 96)")
    p.add_argument("--masked", type=int, default=48, metavar="N",
                   help="voxels per edge of the masked part's cube (default: 48)")
    p.add_argument("--phases", type=int, default=32, metavar="N",
                   help="voxels per edge of the label volume (default: 32)")
    p.add_argument("--seed", type=int, default=0)
    a = p.parse_args(argv)
    models = write_examples(a.out, shape=(a.size[1], a.size[0]), noise=a.noise, seed=a.seed,
                            volume=a.volume, masked=a.masked,
                            phases=a.phases)
    for path in models.values():
        print(f"wrote {path} (and the images it reads)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
