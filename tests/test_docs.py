"""The README's model example loads and meshes (documentation must not rot)."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

import hetmesh

README = Path(__file__).resolve().parents[1] / "README.md"


@pytest.mark.skipif(not README.exists(), reason="README.md not next to the tests")
def test_readme_model_block(tmp_path):
    block = re.search(r"```toml\n(.*?)```", README.read_text(), re.S).group(1)
    path = tmp_path / "readme.toml"
    path.write_text(block)
    model = hetmesh.load_model(path)
    r = hetmesh.generate(model, 0.1)
    assert r.stats.delta_max < 0.1
