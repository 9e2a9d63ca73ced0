"""A user's plugin through every command that loads a scene (issue 25): ``check --plugin``, ``bench`` of a
user's scene with ``--plugin``; plugin paths in a scene resolve from the scene's folder; a plugin that fails
while a scene loads is an error with the scene's file:line and the plugin's own file:line (exit 2, no
traceback)."""

from __future__ import annotations

import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import brdflab as bl
from brdflab import plugins
from brdflab.cli.main import main

ROOT = Path(__file__).resolve().parents[1]
PLUGIN = ROOT / "tests" / "plugins" / "uniform_lambert.py"
CBOX = ROOT / "scenes" / "cbox" / "cbox_diffuse.xml"

FAILING = '''
import numpy as np
import brdflab as bl


class Fails(bl.BSDF):
    type_name = "fails_at_construction"

    def __init__(self, k=1.0):
        self.k = float(k)
        if self.k > 1:
            raise ZeroDivisionError("k is too large for this lobe")  # line 12

    def eval(self, wi, wo, uv=None):
        return np.ones((len(wi), 3)) / np.pi

    def pdf(self, wi, wo, uv=None):
        return np.where(wo[:, 2] > 0, wo[:, 2] / np.pi, 0.0)

    def sample(self, wi, u, uv=None):
        wo = bl.warps.square_to_cosine_hemisphere(u[:, :2])
        return bl.BSDFSample(wo, np.ones((len(wi), 3)), self.pdf(wi, wo))
'''


def _scene(folder: Path, bsdf: str, width: int = 32, height: int = 24) -> Path:
    """cbox_diffuse at a small size in ``folder``, mesh paths absolute, its last material replaced by ``bsdf``."""
    text = CBOX.read_text()
    text = re.sub(r'value="(meshes/[^"]+)"', lambda m: f'value="{CBOX.parent / m.group(1)}"', text)
    text = re.sub(r'(name="width" value=")\d+', rf"\g<1>{width}", text)
    text = re.sub(r'(name="height" value=")\d+', rf"\g<1>{height}", text)
    i = text.rindex('<bsdf type="diffuse">')
    j = text.index("</bsdf>", i) + len("</bsdf>")
    path = folder / "scene.xml"
    path.write_text(text[:i] + bsdf + text[j:])
    return path


@pytest.fixture
def cleanup():
    yield
    for name in ("uniform_lambert", "uniform_lambert_broken", "fails_at_construction"):
        plugins.unregister_bsdf(name)


def test_scene_plugin_paths_resolve_from_the_scene_folder(tmp_path, monkeypatch, cleanup):
    folder = tmp_path / "elsewhere"
    folder.mkdir()
    shutil.copy(PLUGIN, folder / "my_lambert.py")
    monkeypatch.chdir(tmp_path)  # not the scene's folder
    for spec in ("my_lambert.py:UniformLambert", "my_lambert:UniformLambert"):
        plugins.unregister_bsdf("uniform_lambert")
        scene = bl.load_scene(_scene(folder, f'<bsdf type="{spec}"/>'))
        assert "uniform_lambert" in plugins.bsdf_names() and len(scene.bsdfs) == 6, spec
    assert "my_lambert" not in sys.modules or Path(sys.modules["my_lambert"].__file__).parent == folder
    assert str(folder) not in sys.path  # the scene's folder is not left on the import path
    # a file-based spec is recorded by absolute path, so cluster workers load the same file
    assert any(s.startswith(str(folder.resolve())) for s in plugins.LOADED_SPECS)


@pytest.mark.parametrize("source, expect", [
    (FAILING, "Fails(k) failed: ZeroDivisionError: k is too large for this lobe (at {plugin}:12)"),
    ("x = 1\nraise RuntimeError('broken at import')\n", "the plugin failed to import: RuntimeError: broken at "
     "import (at {plugin}:2)"),
    ("def f(:\n", "the plugin failed to import: SyntaxError"),
    ("import sys\nsys.exit(0)\n", "the plugin failed to import: SystemExit"),
])
def test_a_failing_plugin_at_scene_load_is_a_located_error(tmp_path, capsys, cleanup, source, expect):
    plugin = tmp_path / "failing.py"
    plugin.write_text(source)
    scene = _scene(tmp_path, '<bsdf type="failing.py:Fails"><float name="k" value="5"/></bsdf>')
    status = main(["render", str(scene), "--spp", "1", "-o", str(tmp_path / "out.exr"), "--quiet"])
    err = capsys.readouterr().err
    assert status == 2, err
    line = next(n for n, t in enumerate(scene.read_text().splitlines(), 1) if "failing.py:Fails" in t)
    shown = str(plugin) if len(str(plugin)) <= 50 else "…" + str(plugin)[-49:]  # a long path keeps its end
    assert f"{scene}:{line}:" in err and expect.format(plugin=shown) in err, err
    assert "Traceback" not in err and not (tmp_path / "out.exr").exists()
    if source is FAILING:
        with pytest.raises(bl.BrdflabError, match="k is too large"):
            bl.load_scene(scene)


def test_plugin_file_that_is_a_folder_is_named_as_such(tmp_path, capsys):
    (tmp_path / "dir.py").mkdir()
    assert main(["chi2", "--plugin", str(tmp_path / "dir.py"), "--bsdf", "x"]) == 2
    assert "plugin file is a directory" in capsys.readouterr().err


def test_check_takes_a_plugin(tmp_path, capsys, cleanup):
    scene = _scene(tmp_path, '<bsdf type="uniform_lambert"><color name="albedo" value="0.6,0.5,0.4"/></bsdf>')
    plugins.load_plugin(PLUGIN)
    img = bl.render(bl.load_scene(scene), spp=16, seed=5, workers=1)
    plugins.unregister_bsdf("uniform_lambert")
    plugins.unregister_bsdf("uniform_lambert_broken")
    bl.write_exr(tmp_path / "mine.exr", img)
    args = ["check", str(tmp_path / "mine.exr"), "--scene", str(scene), "--spp", "16", "--runs", "2",
            "--user-spp", "16", "--block", "8", "--levels", "1", "--workers", "1", "-o", str(tmp_path / "c")]
    assert main(args) == 2  # without --plugin the scene does not load
    assert "--plugin" in capsys.readouterr().err
    assert main([*args, "--plugin", str(PLUGIN)]) == 0
    assert "consistent" in capsys.readouterr().out
    assert (tmp_path / "c" / "check.html").exists()


def test_bench_runs_a_users_scene_with_its_plugin(tmp_path):
    scene = _scene(tmp_path, '<bsdf type="uniform_lambert"/>', 16, 12)
    out = subprocess.run([sys.executable, "-m", "brdflab.cli.main", "bench", str(scene), "--plugin", str(PLUGIN),
                          "--spp", "1", "--runs", "1", "--workers", "1", "--json", str(tmp_path / "b.json")],
                         capture_output=True, text=True, timeout=300, cwd=tmp_path)
    assert out.returncode == 0, out.stderr[-2000:]
    import json

    rec = json.loads((tmp_path / "b.json").read_text())["results"]
    assert len(rec) == 1 and rec[0]["integrator"] == "direct_ems" and rec[0]["width"] == 16
    assert np.isfinite(rec[0]["median"]["whole_seconds"])


def test_report_takes_a_plugin(tmp_path, capsys, cleanup):
    scene = _scene(tmp_path, '<bsdf type="uniform_lambert"/>', 16, 12)
    args = ["report", str(scene), "--integrators", "direct_ems,direct_mats", "--spp", "2", "--runs", "2",
            "--ref-spp", "4", "--resolution", "16x12", "--workers", "1", "--no-flip", "--no-mis-weights",
            "-o", str(tmp_path / "r")]
    assert main(args) == 2 and "--plugin" in capsys.readouterr().err
    assert main([*args, "--plugin", str(PLUGIN)]) == 0
    assert (tmp_path / "r" / "report.html").exists()
