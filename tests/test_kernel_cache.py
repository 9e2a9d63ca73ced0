"""The prebuilt kernels' cache against damaged, foreign and unbuildable caches (issue 41) and the first run
after an install (issue 42): no run waits for the build, and a bad cache costs one warning line and the
NumPy engine, never the run.

Most cases copy the module the session built (``conftest.py``) into a temporary cache and damage it, or
drive the builder with a stand-in compiler; two build for real (concurrent first runs, Ctrl-C during a
build). Each guard of :mod:`brdflab.kernels.cache` / :mod:`brdflab.kernels.aot` has a case that fails
without it (the hash checked before ``dlopen``, owner and permissions, the fallback on a failing init or
a failing numba, the full disk named, the builder killed on a signal, its temporaries kept out of
``$TMPDIR``, stray files moved aside).
"""

from __future__ import annotations

import errno
import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import pytest

from brdflab import kernels
from brdflab.kernels import aot, cache

ROOT = Path(__file__).resolve().parent.parent
CBOX = "scenes/cbox/cbox_diffuse.xml"
pytestmark = pytest.mark.skipif(not kernels._numba_available(), reason="numba is not installed")


def _env(cache_root: Path, **extra: str) -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if k not in ("BRDFLAB_ENGINE", "BRDFLAB_AOT")}
    return {**env, "BRDFLAB_KERNEL_CACHE": str(cache_root), "BRDFLAB_AOT_BUILD": "0", **extra}


def _render(tmp_path: Path, cache_root: Path, *args: str, **extra: str) -> subprocess.CompletedProcess:
    out = tmp_path / "out" / "x.exr"
    cmd = [sys.executable, "-m", "brdflab.cli.main", "render", CBOX, "--spp", "1", "--workers", "1", "-o", str(out),
           "--force", *args]
    return subprocess.run(cmd, cwd=ROOT, env=_env(cache_root, **extra), capture_output=True, text=True,
                          timeout=600)  # hang bound


#: A process that reports its engine, its backend and whether the cached module's file was mapped.
PROBE = ("import sys; from brdflab import kernels; from brdflab.kernels import cache\n"
         "e = kernels.engine()\n"
         "maps = open('/proc/self/maps').read() if sys.platform == 'linux' else ''\n"
         "print(e, kernels.backend() or '-', cache.module_name() in maps)\n")


def _probe(cache_root: Path, code: str = PROBE, **extra: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", code], cwd=ROOT, env=_env(cache_root, **extra),
                          capture_output=True, text=True, timeout=600)  # hang bound


def _warnings(stderr: str) -> list[str]:
    return [ln for ln in stderr.splitlines() if "warning" in ln.lower() or "KernelNotice" in ln]


@pytest.fixture
def built(tmp_path) -> Path:
    """A cache root (0700, as a user's) holding a copy of the session's verified build for this key."""
    entry = aot.lookup()
    if entry.state != "built":
        pytest.skip(f"the compiled kernels could not be built here: {entry.message[-300:]}")
    root = tmp_path / "cache"
    root.mkdir(mode=0o700)
    shutil.copytree(entry.path.parent, root / aot.key())
    return root


def test_the_copied_build_loads(built):
    """The baseline of the cases below: a verified build is loaded, quietly."""
    p = _probe(built)
    assert p.stdout.split() == ["numba", "aot", "True"] and p.stderr == "", p.stderr[-2000:]


def test_a_truncated_module_is_refused_before_dlopen(built, tmp_path):
    """A truncated module (a full disk, a copy cut short) used to kill every render with SIGBUS: its hash is
    checked before it is loaded, so the run costs one warning line and the NumPy engine."""
    module = built / aot.key() / cache.module_name()
    module.write_bytes(module.read_bytes()[: module.stat().st_size // 3])
    r = _render(tmp_path, built)
    assert r.returncode == 0, (r.returncode, r.stderr[-2000:])
    assert len(_warnings(r.stderr)) == 1 and "does not match its manifest" in r.stderr, r.stderr
    assert "Traceback" not in r.stderr and (tmp_path / "out" / "x.exr").is_file()
    assert _probe(built).stdout.split() == ["numpy", "-", "False"]


def test_a_planted_module_is_never_loaded(built):
    """Another extension module put in place of ours (its init code would run in every brdflab process):
    its bytes do not match the manifest, so it is not even mapped; with a manifest rewritten to match it,
    the folder's permissions give it away (only a writable-by-others folder lets someone else plant)."""
    folder = built / aot.key()
    import _csv

    planted = Path(getattr(_csv, "__file__", ""))
    if not planted.is_file():
        pytest.skip("no stdlib extension module to plant")
    shutil.copyfile(planted, folder / cache.module_name())
    p = _probe(built)
    assert p.stdout.split() == ["numpy", "-", "False"], p.stdout + p.stderr[-2000:]
    assert "does not match its manifest" in p.stderr
    # The planter rewrites the manifest too, which needs write access to the folder: refused for that.
    cache.write_manifest(folder, aot.key())
    folder.chmod(0o777)
    p = _probe(built)
    assert p.stdout.split() == ["numpy", "-", "False"] and "writable by group and others" in p.stderr, p.stderr


@pytest.mark.parametrize("how", ["root writable by others", "root writable by group", "module of another user",
                                 "folder of another user", "module through a link"])
def test_a_foreign_or_shared_cache_is_refused(built, how):
    folder = built / aot.key()
    module = folder / cache.module_name()
    if how == "root writable by others":
        built.chmod(0o757)
    elif how == "root writable by group":
        built.chmod(0o770)
    elif how == "module of another user":
        os.chown(module, 65534, -1) if os.geteuid() == 0 else pytest.skip("needs root to give a file away")
    elif how == "folder of another user":
        os.chown(folder, 65534, -1) if os.geteuid() == 0 else pytest.skip("needs root to give a file away")
    else:
        module.rename(folder / "real.so")
        module.symlink_to(folder / "real.so")
    p = _probe(built)
    assert p.returncode == 0 and p.stdout.split() == ["numpy", "-", "False"], p.stdout + p.stderr[-2000:]
    assert len(_warnings(p.stderr)) == 1, p.stderr
    assert ("writable by" in p.stderr) if "writable" in how else ("another user" in p.stderr or "link" in p.stderr)


_FAKE_LOAD = ("import sys, types; from brdflab.kernels import aot\n"
              "def load(path):\n{body}\n"
              "aot.load_module = load\n")


@pytest.mark.parametrize("body", ["    return types.ModuleType('brdflab_kernels')",  # no kernels in it
                                  "    raise RuntimeError('init failed')",
                                  "    raise SystemExit(3)",
                                  "    raise MemoryError()"])
def test_a_module_without_kernels_or_whose_init_raises_costs_one_warning(built, body):
    """The module loads but lacks the kernels, or its init raises anything: one warning line, the NumPy
    engine, and the material still evaluates (through its NumPy code)."""
    code = (_FAKE_LOAD.format(body=body) + PROBE
            + "import numpy as np; from brdflab import RoughConductor\n"
            "print(RoughConductor(alpha=0.3).eval(np.array([[0, 0, 1.0]]), np.array([[0, 0.6, 0.8]]))[0, 0] > 0)\n")
    p = _probe(built, code)
    assert p.returncode == 0, p.stderr[-2000:]
    assert p.stdout.split() == ["numpy", "-", "False", "True"], p.stdout + p.stderr[-2000:]
    assert len(_warnings(p.stderr)) == 1 and "could not be loaded" in p.stderr, p.stderr


def _broken_numba(tmp_path: Path) -> str:
    fake = tmp_path / "fake" / "numba"
    fake.mkdir(parents=True)
    (fake / "__init__.py").write_text("raise ImportError('numba is broken here')\n")
    return os.pathsep.join([str(tmp_path / "fake"), str(ROOT)])


def test_numba_failing_at_import_costs_one_warning(tmp_path):
    """numba that raises at import: the JIT (asked for) falls back to the NumPy engine in one line; a
    background build records the failure, the next run says it once, later runs nothing."""
    root = tmp_path / "cache"
    root.mkdir(mode=0o700)
    path = _broken_numba(tmp_path)
    r = _render(tmp_path, root, BRDFLAB_AOT="0", PYTHONPATH=path)
    assert r.returncode == 0 and "Traceback" not in r.stderr, r.stderr[-2000:]
    assert len(_warnings(r.stderr)) == 1 and "numba is broken here" in r.stderr, r.stderr
    # A first run starts the build in the background, which meets the same numba: the failure is recorded.
    first = _render(tmp_path, root, PYTHONPATH=path, BRDFLAB_AOT_BUILD="1")
    assert first.returncode == 0 and "building them in the background" in first.stderr, first.stderr[-2000:]
    aot.wait_for_build(root)
    (failed,) = root.glob("*/" + cache.FAILED)
    assert "numba is broken here" in failed.read_text()
    runs = [_render(tmp_path, root, PYTHONPATH=path) for _ in range(2)]
    assert [r.returncode for r in runs] == [0, 0], runs[0].stderr[-2000:]
    assert len(_warnings(runs[0].stderr)) == 1 and "numba is broken here" in runs[0].stderr, runs[0].stderr
    assert _warnings(runs[1].stderr) == [], runs[1].stderr


def _fake_compile(folder: str) -> None:
    (Path(folder) / cache.module_name()).write_bytes(b"\x7fELF stand-in module")


def test_a_full_disk_during_the_build_names_the_folder(tmp_path):
    """ENOSPC while building: recorded (the partial module removed first, so that the note fits), named with
    the cache folder; a render then says so in one line and runs on the NumPy engine."""
    root = tmp_path / "cache"
    root.mkdir(mode=0o700)

    def full(folder: str) -> None:
        (Path(folder) / cache.module_name()).write_bytes(b"partial")
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    assert aot.run_build(root, aot.key(), full) == 0
    entry = cache._inspect(root, aot.key())
    assert entry.state == "failed" and f"no space left on device in {root}" in aot.summary(entry.message)
    assert sorted(p.name for p in (root / aot.key()).iterdir()) == [cache.FAILED]
    assert "failed" in (root / cache.LOG).read_text()
    r = _render(tmp_path, root)
    assert r.returncode == 0 and (tmp_path / "out" / "x.exr").is_file(), r.stderr[-2000:]
    assert len(_warnings(r.stderr)) == 1 and f"no space left on device in {root}" in r.stderr, r.stderr


def test_stray_files_do_not_force_rebuilds(tmp_path):
    """A stray file in the cache folder, or at the key's own place, does not stop a build from being
    installed, and a built key is not built again."""
    root = tmp_path / "cache"
    root.mkdir(mode=0o700)
    (root / "notes.txt").write_text("mine")
    (root / ".stray-folder-x").mkdir()
    (root / "k1").write_text("a stray file where the build goes")
    calls = []

    def counting(folder: str) -> None:
        calls.append(folder)
        _fake_compile(folder)

    before = os.environ.get("TMPDIR"), tempfile.gettempdir()
    for _ in range(2):
        assert aot.run_build(root, "k1", counting) == 0
    assert (os.environ.get("TMPDIR"), tempfile.gettempdir()) == before  # the caller's TMPDIR is its own again
    assert len(calls) == 1 and cache._inspect(root, "k1").state == "built"
    assert sorted(p.name for p in root.iterdir()) == [".build.lock", ".stray-folder-x", cache.LOG, "k1", "notes.txt"]
    manifest = json.loads((root / "k1" / cache.MANIFEST).read_text())
    assert manifest["sha256"] == cache.sha256(root / "k1" / cache.module_name())
    # A damaged build at the key's place (its module cut short) is replaced by the next build.
    (root / "k1" / cache.module_name()).write_bytes(b"\x7fELF")
    assert cache._inspect(root, "k1").state == "damaged"
    assert aot.run_build(root, "k1", counting) == 0 and len(calls) == 2
    assert cache._inspect(root, "k1").state == "built"


def _processes_mentioning(text: str) -> list[int]:
    pids = []
    for d in Path("/proc").iterdir():
        if d.name.isdigit():
            try:
                if text.encode() in (d / "cmdline").read_bytes():
                    pids.append(int(d.name))
            except OSError:
                continue
    return pids


@pytest.mark.skipif(not Path("/proc/self/cmdline").exists(), reason="needs /proc")
def test_ctrl_c_during_a_first_build_is_honoured_at_once(tmp_path):
    """A run that waits for the build (``--engine numba``) and gets Ctrl-C: it kills the builder and exits
    130 then, not when the build would have ended (the build does not exist afterwards), leaving no
    builder process, no temporary folder in the cache and nothing in ``$TMPDIR``."""
    root, tmpdir = tmp_path / "cache", tmp_path / "tmpdir"
    root.mkdir(mode=0o700)
    tmpdir.mkdir()
    cmd = [sys.executable, "-m", "brdflab.cli.main", "render", CBOX, "--spp", "1", "--workers", "1", "--engine",
           "numba", "-o", str(tmp_path / "x.exr")]
    proc = subprocess.Popen(cmd, cwd=ROOT, env=_env(root, TMPDIR=str(tmpdir)), stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 300  # hang bound
    while not list(root.glob(cache.TMP_PREFIX + "*")) and time.monotonic() < deadline and proc.poll() is None:
        time.sleep(0.05)
    time.sleep(1.0)  # the builder is compiling now
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=300)  # hang bound
    assert proc.returncode == 130, err[-2000:]
    assert "Traceback" not in err
    assert cache._inspect(root, aot.key()).state == "missing", "the run waited for the build to end"
    assert not list(root.glob(cache.TMP_PREFIX + "*")) and list(tmpdir.iterdir()) == []
    assert _processes_mentioning(str(root)) == []


def test_concurrent_first_runs_one_build_none_waits(tmp_path):
    """Three first runs at once on an empty cache, as terminals or a cluster's workers: the one that asks
    for nothing runs on the NumPy engine at once and says so in one line, the two that ask for the compiled
    engine wait for the single build (a lock: the builders after the first find the module built); nothing
    is left in ``$TMPDIR`` or the cache but the build;
    the next run loads the module, quietly."""
    root, tmpdir = tmp_path / "cache", tmp_path / "tmpdir"
    root.mkdir(mode=0o700)
    tmpdir.mkdir()
    env = _env(root, TMPDIR=str(tmpdir), BRDFLAB_AOT_BUILD="1")
    code = PROBE + "import time; time.sleep(0.5)\n"  # both alive together
    procs = [subprocess.Popen([sys.executable, "-c", code], cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                              text=True, env={**env, **extra})
             for extra in ({}, {"BRDFLAB_ENGINE": "numba"}, {"BRDFLAB_ENGINE": "numba"})]
    (auto_out, auto_err), *strict = (p.communicate(timeout=900) for p in procs)  # hang bound
    assert auto_out.split() == ["numpy", "-", "False"], auto_err[-2000:]
    lines = _warnings(auto_err)
    assert len(lines) == 1 and "this run uses the NumPy engine" in lines[0], auto_err
    for out, err in strict:  # like two workers of a cluster, told the compiled engine by their client
        assert out.split() == ["numba", "aot", "True"], err[-2000:]
    aot.wait_for_build(root)
    assert sorted(p.name for p in root.iterdir()) == sorted([".build.lock", aot.key(), cache.LOG])
    assert len((root / cache.LOG).read_text().splitlines()) == 1  # one build
    assert list(tmpdir.iterdir()) == []
    again = _probe(root, BRDFLAB_AOT_BUILD="1")
    assert again.stdout.split() == ["numba", "aot", "True"] and again.stderr == "", again.stderr[-2000:]


@pytest.mark.parametrize("args", [
    ["chi2", "--bsdf", "roughconductor", "--alpha", "0.3", "--theta", "30", "-n", "2000", "--effort", "quick"],
    ["plot", "--bsdf", "roughconductor", "--views", "polar", "--effort", "quick"],
    ["api"],
], ids=["chi2", "plot", "api"])
def test_every_entry_point_runs_without_waiting_for_the_build(tmp_path, args):
    """Not only render: a command or the API on an empty cache runs on the NumPy engine at once (no module is
    built while it runs: none exists afterwards) and says so in one line."""
    root = tmp_path / "cache"
    root.mkdir(mode=0o700)
    if args == ["api"]:
        code = ("import brdflab as bl; s = bl.load_scene('scenes/cbox/cbox_diffuse.xml', width=16, height=12); "
                "print(bl.render(s, spp=1).shape)")
        cmd = [sys.executable, "-c", code]
    else:
        cmd = [sys.executable, "-m", "brdflab.cli.main", *args, "-o", str(tmp_path / "out")]
    r = subprocess.run(cmd, cwd=ROOT, env=_env(root), capture_output=True, text=True, timeout=600)  # hang bound
    assert r.returncode == 0, r.stderr[-2000:]
    lines = [ln for ln in _warnings(r.stderr) if "compiled kernels not built yet" in ln]
    assert len(lines) == 1 and "this run uses the NumPy engine" in lines[0], r.stderr[-2000:]
    assert not list(root.glob("*/" + cache.MANIFEST))


def test_editing_a_kernel_source_rebuilds(tmp_path, monkeypatch):
    """Issue 40: a stale module keyed wrongly would run the old kernels forever (prebuilt ≠ JIT). The key hashes
    every kernel source, so an edited source has another key, whose module is not built yet: the next run builds
    it instead of loading the old one. Negative control: a key of the file names alone does not change."""
    import shutil

    from brdflab.kernels import aot

    src = tmp_path / "kernels"
    shutil.copytree(aot.HERE, src, ignore=shutil.ignore_patterns("__pycache__"))
    monkeypatch.setattr(cache, "HERE", src)  # where cache.sources_hash reads the sources
    before = aot.key()
    target = src / "bsdf.py"
    target.write_text(target.read_text() + "\n# an edit\n")
    after = aot.key()
    assert after != before
    built = aot.lookup(before).state  # whatever the session's cache holds for the old sources
    assert aot.lookup(after).state == "missing" or built != "built"

    def names_only() -> str:  # the planted bug: sources not hashed
        return "|".join(p.name for p in sorted(src.glob("*.py")))

    planted = names_only()
    target.write_text(target.read_text() + "\n# another edit\n")
    assert names_only() == planted  # such a key would load the stale module ...
    assert aot.key() != after  # ... brdflab's does not


def test_editing_an_inlined_helper_recompiles_the_jit(tmp_path):
    """numba's own disk cache is keyed by each function's file: after an edit of ``scalar.beckmann_d`` (a helper
    inlined into ``bsdf.py``'s kernels) it loaded the old machine code of the kernels — and so did the
    ahead-of-time build, which compiles through the JIT (a mutation of that line survived the kernel tests).
    The JIT's cache folder is named by the hash of every kernel source: the edit must show in f, twice the
    Beckmann D giving twice the conductor's f."""
    pkg = tmp_path / "src"
    shutil.copytree(ROOT / "brdflab", pkg / "brdflab", ignore=shutil.ignore_patterns("__pycache__"))
    code = ("from brdflab import kernels, RoughConductor; import numpy as np\n"
            "f = RoughConductor(alpha=0.3).eval(np.array([[0, 0, 1.0]]), np.array([[0, 0.6, 0.8]]))[0, 0]\n"
            "print(repr(float(f)), kernels.engine(), kernels.backend())\n")

    def probe() -> list[str]:
        r = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, capture_output=True, text=True, timeout=600,
                           env=_env(tmp_path / "cache", PYTHONPATH=str(pkg), BRDFLAB_AOT="0", BRDFLAB_ENGINE="numba",
                                    PYTHONDONTWRITEBYTECODE="1"))
        assert r.returncode == 0, r.stderr[-2000:]
        return r.stdout.split()

    (tmp_path / "cache").mkdir(mode=0o700)
    first = probe()
    assert first[1:] == ["numba", "jit"]
    scalar = pkg / "brdflab" / "kernels" / "scalar.py"
    text = scalar.read_text()
    assert text.count("    return d if math.isfinite(d) else 0.0\n") == 1
    scalar.write_text(text.replace("    return d if math.isfinite(d) else 0.0\n",
                                   "    return 2.0 * d if math.isfinite(d) else 0.0\n"))
    second = probe()
    assert float(second[0]) == pytest.approx(2 * float(first[0]), rel=1e-12)
    assert len(list((tmp_path / "cache" / "jit").iterdir())) == 2  # one folder per version of the sources


def test_the_builder_compiles_the_sources_of_the_process_that_started_it(tmp_path, monkeypatch):
    """``python -m`` puts the working folder first on sys.path: started from a folder holding another brdflab
    (a second clone), the builder compiled that one's kernels under this process's key, and this process then
    loaded them (found by rendering the start commit with PYTHONPATH from inside a clone). The builder now runs
    from the folder above its own brdflab, and refuses a key that is not its sources' (a failed build). A decoy
    brdflab in the working folder writes a marker if it is imported; the key asked for is not the sources'."""
    from brdflab.kernels import aot

    decoy = tmp_path / "clone" / "brdflab" / "kernels"
    decoy.mkdir(parents=True)
    marker = tmp_path / "decoy-ran"
    (decoy.parent / "__init__.py").write_text("")
    (decoy / "__init__.py").write_text("")
    (decoy / "aot.py").write_text(f"open({str(marker)!r}, 'w').close()\n")
    root = tmp_path / "cache"
    root.mkdir(mode=0o700)
    monkeypatch.chdir(decoy.parent.parent)
    wrong = "0" * 20
    assert wrong != aot.key()
    proc = aot.start(root, wrong, background=False)
    assert proc.wait(timeout=300) == 0
    assert not marker.exists(), "the builder imported the brdflab of its working folder"
    entry = cache._inspect(root, wrong)
    assert entry.state == "failed" and "are not those of key" in entry.message, entry
