"""Collection settings for the whole repository (the tests' fixtures are in tests/conftest.py).

``python -m pytest`` also runs the docstring examples of every module under ``src``
(``--doctest-modules``, see pyproject.toml). After ``pip install .`` the tests import the
installed ``hetmesh``; pytest would then refuse to import ``src/hetmesh/x.py`` as
``hetmesh.x`` (the name is taken by the installed file). Both are the same source, so the
examples run against the installed module, like the tests.
"""

import os

os.environ.setdefault("PY_IGNORE_IMPORTMISMATCH", "1")
