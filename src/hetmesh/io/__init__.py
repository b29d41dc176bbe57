"""Input and output: model files (``model.py``), mesh export and import (``export.py``) and
atomic file writes (``atomic.py``)."""
