"""The tutorial (docs/api.md) and the docstring examples of the public API run as written."""

from __future__ import annotations

import doctest
import importlib
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCTEST_MODULES = ["brdflab.api", "brdflab.plugins", "brdflab.validate", "brdflab.bsdf.roughconductor",
                   "brdflab.validate.battery", "brdflab.validate.consistency", "brdflab.validate.external",
                   "brdflab.validate.furnace", "brdflab.validate.guard", "brdflab.validate.seeding",
                   "brdflab.validate.stability", "brdflab.workflows",
                   "brdflab.validate.sample_files", "brdflab.fitting", "brdflab.validate.emitter_samples",
                   "brdflab.kernels", "brdflab.kernels.buffers"]


def test_tutorial_runs(monkeypatch):
    text = (ROOT / "docs" / "api.md").read_text()
    blocks = re.findall(r"```python\n(.*?)```", text, flags=re.S)
    assert len(blocks) >= 5
    monkeypatch.chdir(ROOT)
    namespace: dict = {"__name__": "tutorial"}
    try:
        for i, block in enumerate(blocks):
            exec(compile(block, f"docs/api.md[block {i}]", "exec"), namespace)
    finally:
        from brdflab import plugins

        plugins.unregister_bsdf("tutorial_phong")


@pytest.mark.parametrize("name", DOCTEST_MODULES)
def test_docstring_examples(name, monkeypatch):
    monkeypatch.chdir(ROOT)
    module = importlib.import_module(name)
    try:
        result = doctest.testmod(module, optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
    finally:
        from brdflab import plugins

        plugins.unregister_bsdf("flat_doc_example")
    assert result.attempted > 0, f"{name} has no examples"
    assert result.failed == 0
