"""Input and output: model files (``model.py``), mesh export (``export.py`` and the
writers it dispatches to), mesh import (``read.py``) and atomic file writes (``atomic.py``)."""
