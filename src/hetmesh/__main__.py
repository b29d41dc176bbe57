"""``python -m hetmesh`` is the ``hetmesh`` command."""

import sys

from .cli import main

sys.exit(main())
