"""The tutorial (docs/api.md) and the docstring examples of the public API run as written."""

from __future__ import annotations

import doctest
import importlib
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCTEST_MODULES = ["brdflab.api", "brdflab.parameters", "brdflab.plugins", "brdflab.judges.public",
                   "brdflab.bsdf.roughconductor",
                   "brdflab.judges.material.battery", "brdflab.judges.material.consistency",
                   "brdflab.judges.samples.bsdf_checks",
                   "brdflab.judges.material.furnace", "brdflab.judges.core.guard", "brdflab.judges.core.seeding",
                   "brdflab.judges.material.stability", "brdflab.workflows",
                   "brdflab.judges.samples.tables", "brdflab.fitting", "brdflab.judges.samples.light_samples",
                   "brdflab.kernels", "brdflab.kernels.buffers"]
#: Issue 44: the delta and transmissive materials.
DOCTEST_MODULES += ["brdflab.bsdf.mirror", "brdflab.bsdf.dielectric", "brdflab.bsdf.roughdielectric",
                    "brdflab.bsdf.fresnel"]


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
