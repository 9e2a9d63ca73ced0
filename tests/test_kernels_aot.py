"""The compiled engine's two backends (brdflab.kernels.aot, brdflab.kernels.jit) give the same bits.

The prebuilt extension module and numba's JIT compile the same kernels with the same options; a process of
each computes every kernel on the same inputs (materials with textures and families, both light kinds,
the film splat, a whole render unit) and the results must be equal bit for bit. A process with the prebuilt
module must not import numba; a failed build must be remembered and fall back to the JIT; a prebuilt
kernel given the wrong array must raise, not read or write out of bounds.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from brdflab import kernels
from brdflab.kernels import aot

ROOT = Path(__file__).resolve().parent.parent
pytestmark = pytest.mark.skipif(not kernels._numba_available(), reason="numba is not installed")

#: A process computing every kernel on fixed inputs (the materials and render units of test_kernels).
_OUTPUTS = r"""
import sys, zlib, numpy as np
from brdflab import kernels, load_scene
from brdflab.film import Film, Filter
from brdflab.workers import _render_unit
from tests.test_kernels import MATERIALS, bound, directions
out = {}
for name in MATERIALS:
    rng = np.random.default_rng(zlib.crc32(name.encode()))  # not hash(): salted per process
    n = 2000
    m = bound(name, n, rng)
    wi, wo, u, uv = directions(rng, n), directions(rng, n), rng.random((n, 3)), rng.random((n, 2))
    f, pdf = m.eval_pdf(wi, wo, uv)
    s = m.sample(wi, u, uv)
    out.update({name + ":f": f, name + ":pdf": pdf, name + ":wo": s.wo, name + ":w": s.weight, name + ":sp": s.pdf})
rng = np.random.default_rng(7)
film = Film(64, 48, Filter())
film.splat(rng.random(5000) * 64, rng.random(5000) * 48, rng.random((5000, 3)))
out["splat"] = film.data
for path in ("scenes/veach/veach_mis.xml", "scenes/lights/mixed_lights_mis.xml", "scenes/cbox/cbox_substrate.xml"):
    scene = load_scene(path, width=48, height=36)
    out[path] = _render_unit(scene, 0, 0, (8, 6, 24, 20), 4, 1234)[0].data
np.savez(sys.argv[1], **out)
print(kernels.backend(), "numba" in sys.modules, kernels.costs()["compile"])
"""


def _run(code: str, *args: str, **env: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", code, *args], cwd=ROOT, capture_output=True, text=True,
                          env={**os.environ, "BRDFLAB_ENGINE": "numba", **env}, timeout=600)


def test_prebuilt_module_and_jit_give_the_same_bits(tmp_path):
    """Every kernel, through the prebuilt module and through numba's JIT, on the same inputs: equal bits."""
    pre = _run(_OUTPUTS, str(tmp_path / "aot.npz"))
    jit = _run(_OUTPUTS, str(tmp_path / "jit.npz"), BRDFLAB_AOT="0")
    assert pre.returncode == 0 and jit.returncode == 0, pre.stderr[-1500:] + jit.stderr[-1500:]
    # The prebuilt process imported no numba and built nothing (the module existed or was built by now).
    assert pre.stdout.split()[:2] == ["aot", "False"], pre.stdout
    assert jit.stdout.split()[:2] == ["jit", "True"], jit.stdout
    a, b = np.load(tmp_path / "aot.npz"), np.load(tmp_path / "jit.npz")
    assert sorted(a.files) == sorted(b.files) and len(a.files) > 60
    for k in a.files:
        np.testing.assert_array_equal(a[k], b[k], err_msg=k)
    assert np.abs(a["scenes/veach/veach_mis.xml"]).sum() > 0


def test_a_fresh_cache_builds_once_then_loads(tmp_path):
    """An empty cache folder: the first process builds the module (in a child process: compile time > 0,
    no numba in the process itself), the second loads it without building."""
    code = ("import sys; from brdflab import kernels, RoughConductor; import numpy as np; "
            "RoughConductor().eval(np.array([[0, 0, 1.0]]), np.array([[0, 0.6, 0.8]])); "
            "print(kernels.backend(), 'numba' in sys.modules, kernels.costs()['compile'] > 0)")
    first = _run(code, BRDFLAB_KERNEL_CACHE=str(tmp_path))
    second = _run(code, BRDFLAB_KERNEL_CACHE=str(tmp_path))
    assert first.stdout.split() == ["aot", "False", "True"], first.stderr[-2000:]
    assert second.stdout.split() == ["aot", "False", "False"], second.stderr[-2000:]
    assert sorted(p.name for p in tmp_path.iterdir()) == [".build.lock", aot.key()]  # no temporary folder


def test_a_failed_build_is_remembered_and_falls_back_to_the_jit(tmp_path, monkeypatch):
    """A build that fails (here: a child that exits 1, as without a C compiler) leaves its error in the
    cache; this and later processes run the JIT, with the same results."""
    with monkeypatch.context() as m:
        m.setenv("BRDFLAB_KERNEL_CACHE", str(tmp_path))
        m.setattr(aot.subprocess, "run", lambda *a, **k: subprocess.CompletedProcess(a, 1, "", "no cc"))
        path, error = aot.build("k1")
        assert path is None and "no cc" in error
        assert aot.find("k1") == (None, "no cc")
        # A build cut short by a signal (or a timeout) is not a broken one: nothing is remembered.
        m.setattr(aot.subprocess, "run", lambda *a, **k: subprocess.CompletedProcess(a, -2, "", "KeyboardInterrupt"))
        assert aot.build("k2") == (None, "the build was stopped by signal 2") and aot.find("k2") == (None, None)
        assert sorted(p.name for p in tmp_path.iterdir()) == [".build.lock", "k1"]
    (tmp_path / aot.key()).mkdir()
    (tmp_path / aot.key() / aot.FAILED).write_text("no cc")
    code = ("import sys; from brdflab import kernels, RoughConductor; import numpy as np; "
            "print(RoughConductor(alpha=0.3).eval(np.array([[0, 0, 1.0]]), np.array([[0, 0.6, 0.8]]))[0, 0]); "
            "print(kernels.backend(), kernels.aot_error)")
    p = _run(code)
    ref = _run(code, BRDFLAB_ENGINE="numpy")
    p2 = _run(code, BRDFLAB_KERNEL_CACHE=str(tmp_path))
    assert p2.returncode == 0, p2.stderr[-2000:]
    assert p2.stdout.splitlines()[1] == "jit no cc"
    assert float(p2.stdout.splitlines()[0]) == pytest.approx(float(ref.stdout.splitlines()[0]), rel=1e-12)
    assert p.stdout.splitlines()[1].startswith("aot")


def test_prebuilt_kernels_refuse_wrong_arrays():
    """A prebuilt kernel trusts its arguments' memory layout, so the guard must refuse what would read or
    write out of bounds: a float32 array where float64 is compiled, a 1-d array for a 2-d one, a read-only
    output."""
    film_mod = kernels.load("film")
    if kernels.backend() != "aot":
        pytest.skip("the prebuilt module could not be built here: " + str(kernels.aot_error))
    args = [np.zeros(3), np.zeros(3), np.zeros((3, 3)), np.zeros((4, 8, 8)), np.ones((4, 8)),
            np.zeros(8, np.int64), 8, 3, 4, 0, 0]
    film_mod.splat(*args)  # well-formed: runs
    for i, bad in ((0, np.zeros(3, np.float32)), (2, np.zeros(9)), (3, np.zeros((4, 8, 8))[::1].copy())):
        if i == 3:
            bad.flags.writeable = False
        with pytest.raises(TypeError, match=f"kernel film__splat: argument {i} must be"):
            film_mod.splat(*args[:i], bad, *args[i + 1:])
    with pytest.raises(TypeError, match="argument 5"):
        film_mod.splat(*args[:5], [0] * 8, *args[6:])
    with pytest.raises(TypeError, match="takes 11 arguments, not 10"):
        film_mod.splat(*args[:10])


def test_a_build_without_a_c_compiler_warns_once_and_renders_with_the_jit(tmp_path):
    """A real failure (the C compiler is missing): one warning line naming the error, no traceback, the
    render done through the JIT; the next process remembers the failure and says nothing."""
    cmd = [sys.executable, "-m", "brdflab.cli.main", "render", "scenes/cbox/cbox_diffuse.xml", "--spp", "1",
           "--workers", "1", "-o", str(tmp_path / "out" / "x.exr")]
    env = {**os.environ, "BRDFLAB_ENGINE": "numba", "BRDFLAB_KERNEL_CACHE": str(tmp_path / "cache"),
           "CC": str(tmp_path / "no-such-cc")}
    runs = [subprocess.run(cmd + ["--force"] * i, cwd=ROOT, env=env, capture_output=True, text=True, timeout=600)
            for i in range(2)]
    assert [r.returncode for r in runs] == [0, 0], runs[0].stderr[-2000:]
    warned = [ln for ln in runs[0].stderr.splitlines() if "could not be prebuilt" in ln]
    assert len(warned) == 1 and warned[0].startswith("brdflab: warning:") and "Error" in warned[0], runs[0].stderr
    assert "Traceback" not in runs[0].stderr and "could not be prebuilt" not in runs[1].stderr
    assert (tmp_path / "out" / "x.exr").is_file()


def test_processes_starting_together_build_once(tmp_path):
    """Two processes on an empty cache at once: one builds while the other waits for it (a lock), both load
    the module, and no temporary folder is left."""
    # Each process says whether it ran the build's child itself ("built") or found the module ("found").
    code = ("import sys, subprocess; from brdflab import kernels; real = subprocess.run; ran = []\n"
            "def spy(*a, **k):\n    ran.append(1)\n    return real(*a, **k)\n"
            "kernels.aot.subprocess.run = spy; kernels.preload(); "
            "print(kernels.backend(), 'numba' in sys.modules, 'built' if ran else 'found')")
    env = {**os.environ, "BRDFLAB_ENGINE": "numba", "BRDFLAB_KERNEL_CACHE": str(tmp_path)}
    procs = [subprocess.Popen([sys.executable, "-c", code], cwd=ROOT, env=env, stdout=subprocess.PIPE,
                              stderr=subprocess.PIPE, text=True) for _ in range(2)]
    outs = [p.communicate(timeout=600) for p in procs]
    assert sorted(o[0].split()[-1] for o in outs) == ["built", "found"], outs
    assert [o[0].split()[:2] for o in outs] == [["aot", "False"]] * 2, outs
    assert sorted(p.name for p in tmp_path.iterdir()) == [".build.lock", aot.key()]
