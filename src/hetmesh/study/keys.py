"""Content keys: what makes two runs the same run.

A run's key is a SHA-256 digest of the model file's text, the run's options (defaults filled
in, so spelling out a default does not change the key) and the hetmesh version. A sweep
interrupted and started again finds the runs already done under their keys and redoes only
the others; a run whose model file, options or hetmesh version changed gets a new key and
runs again.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Mapping
from typing import Any

__all__ = ["content_key", "text_digest", "KEY_LENGTH"]

#: hex digits kept of the SHA-256 digest (80 bits: no collision in any study that fits a disk)
KEY_LENGTH = 20


def text_digest(text: str) -> str:
    """SHA-256 (hex) of a model file's text.

    >>> text_digest("")[:12]
    'e3b0c44298fc'
    """
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


def content_key(model_digest: str, options: Mapping[str, Any], version: str | None = None) -> str:
    """The key of a run: ``model_digest`` (:func:`text_digest`), the run's options (plain
    data: strings, numbers, booleans, None, lists, dicts) and the hetmesh ``version``
    (default: the installed one).

    >>> a = content_key("ab", {"threshold": 0.1, "method": "auto"}, "1.0")
    >>> a == content_key("ab", {"method": "auto", "threshold": 0.1}, "1.0"), len(a)
    (True, 20)
    >>> a == content_key("ab", {"threshold": 0.1, "method": "auto"}, "1.1")
    False
    """
    if version is None:
        from ..version import __version__ as version
    doc = {"model": model_digest, "options": options, "hetmesh": version}
    text = json.dumps(doc, sort_keys=True, separators=(",", ":"), allow_nan=False)
    return hashlib.sha256(text.encode("utf-8")).hexdigest()[:KEY_LENGTH]
