"""The compiled engine's two backends (brdflab.kernels.aot, brdflab.kernels.jit) give the same bits.

The prebuilt extension module and numba's JIT compile the same kernels with the same options; a process of
each computes every kernel on the same inputs (materials with textures and families, both light kinds,
the film splat, a whole render unit) and the results must be equal bit for bit. A process with the prebuilt
module must not import numba; a failed build must be remembered and fall back (the NumPy engine, or the JIT when
the compiled engine is asked for); a prebuilt kernel given the wrong array must raise, not read or write out
of bounds. The cache's safety and the first run after an install: ``tests/test_kernel_cache.py``.
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


def test_a_failed_build_is_remembered_and_falls_back(tmp_path):
    """A build that fails (here: a compiler that raises, as without a C compiler) leaves its error in the
    cache; the next process says so once and runs the NumPy engine, one that asks for the compiled engine
    runs the JIT, with the same results (1e-12); a build cut short by a signal is not remembered."""
    def no_cc(folder):
        raise RuntimeError("no cc")

    assert aot.run_build(tmp_path, aot.key(), no_cc) == 0
    assert aot.summary((tmp_path / aot.key() / aot.FAILED).read_text()) == "RuntimeError: no cc"

    def interrupted(folder):
        raise aot._Stopped(2)

    with pytest.raises(aot._Stopped):
        aot.run_build(tmp_path, "k2", interrupted)
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted([".build.lock", aot.key(), "builds.log"])  # not k2
    code = ("import sys; from brdflab import kernels, RoughConductor; import numpy as np; "
            "print(RoughConductor(alpha=0.3).eval(np.array([[0, 0, 1.0]]), np.array([[0, 0.6, 0.8]]))[0, 0]); "
            "print(kernels.engine(), kernels.backend() or '-')")
    env = {"BRDFLAB_KERNEL_CACHE": str(tmp_path), "BRDFLAB_ENGINE": ""}
    ref = _run(code, BRDFLAB_ENGINE="numpy")
    auto = [_run(code, **env) for _ in range(2)]
    strict = _run(code, **{**env, "BRDFLAB_ENGINE": "numba"})
    assert all(p.returncode == 0 for p in (ref, *auto, strict)), strict.stderr[-2000:]
    assert [p.stdout.splitlines()[1] for p in auto] == ["numpy -", "numpy -"]
    assert "could not be prebuilt (RuntimeError: no cc)" in auto[0].stderr and auto[1].stderr == "", auto[1].stderr
    assert strict.stdout.splitlines()[1] == "numba jit"
    assert float(strict.stdout.splitlines()[0]) == pytest.approx(float(ref.stdout.splitlines()[0]), rel=1e-12)


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


def test_a_build_without_a_c_compiler_warns_once(tmp_path):
    """A real failure (the C compiler is missing): the first run renders on the NumPy engine while the build
    fails in the background; the next says so in one warning line naming the error, no traceback; the one
    after says nothing."""
    cmd = [sys.executable, "-m", "brdflab.cli.main", "render", "scenes/cbox/cbox_diffuse.xml", "--spp", "1",
           "--workers", "1", "--force", "-o", str(tmp_path / "out" / "x.exr")]
    env = {**os.environ, "BRDFLAB_KERNEL_CACHE": str(tmp_path / "cache"), "CC": str(tmp_path / "no-such-cc")}
    env.pop("BRDFLAB_ENGINE", None)
    runs = []
    for _ in range(3):
        runs.append(subprocess.run(cmd, cwd=ROOT, env=env, capture_output=True, text=True, timeout=600))
        aot.wait_for_build(tmp_path / "cache")
    assert [r.returncode for r in runs] == [0, 0, 0], runs[0].stderr[-2000:]
    assert "building them in the background" in runs[0].stderr
    warned = [ln for ln in runs[1].stderr.splitlines() if "could not be prebuilt" in ln]
    assert len(warned) == 1 and warned[0].startswith("brdflab: warning:") and "Error" in warned[0], runs[1].stderr
    assert all("Traceback" not in r.stderr for r in runs) and "warning" not in runs[2].stderr
    assert (tmp_path / "out" / "x.exr").is_file()
