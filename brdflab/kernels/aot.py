"""Ahead-of-time build of the kernels: one extension module, loaded without importing numba.

Importing numba and loading the JIT's cached machine code costs about 0.5 s per process (numba's own
import, its typing registries, and SciPy's linear algebra, which numba probes for BLAS), as much as the
compiled kernels save in a short render. So the first process that needs the kernels builds them, once,
into a Python extension module with ``numba.pycc`` (every kernel exported under
:func:`~brdflab.kernels.jit.export_name`, through a trampoline that calls the ``numba.jit`` kernel so that
its compile options — NumPy's error model, no fast-math — hold), and every later process imports that
module in a few milliseconds.

* **Where**: ``$BRDFLAB_KERNEL_CACHE`` if set, else ``brdflab/kernels/__pycache__/aot`` when writable,
  else ``~/.cache/brdflab/kernels`` (``$XDG_CACHE_HOME``). One folder per :func:`key`; what is trusted
  there (owner, permissions, the module's hash in a manifest, checked before it is loaded) is
  :mod:`brdflab.kernels.cache`.
* **Key**: the sources in ``brdflab/kernels/``, the installed numba, llvmlite and NumPy, the Python, and the CPU
  (the code is compiled for the host CPU, as the JIT's is): an edit, an upgrade or another machine of a
  cluster on a shared disk builds its own.
* **Build**: by a builder process (``python -m brdflab.kernels.aot build ROOT KEY …``, 15–60 s of one
  core), into a temporary folder renamed into place, so that no process ever sees half a module; builders
  starting together wait on a lock and the second finds the module built. When no engine was asked for,
  the process that finds no module starts the builder **in the background** (detached, at a low
  priority) and runs on the NumPy engine; the next process loads the module (:mod:`brdflab.kernels`).
  A process that asked for the compiled engine (``--engine numba``, a cluster's worker told so by its
  client) waits for the builder; a signal while it waits stops the builder at once.
* **Fallback**: when the build fails (no C compiler, numba broken, a full disk), the error is kept in the
  folder (``build-failed.txt``; delete it to try again), the next process says so in one warning line and
  processes run on the NumPy engine (numba's JIT when the compiled engine was asked for).
  ``BRDFLAB_AOT=0`` asks for the JIT; ``BRDFLAB_AOT_BUILD=0`` starts no background build (a cache built
  beforehand, e.g. by ``brdflab --engine numba`` or the test suite's first step).

Both backends compile the same functions with the same options; ``tests/test_kernels_aot.py`` checks that
they agree bit for bit (``tests/test_kernels.py``: each against the NumPy code to 1e-12).
"""

from __future__ import annotations

import contextlib
import errno
import hashlib
import importlib.util
import os
import platform
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import time
import traceback
from pathlib import Path
from types import ModuleType

from brdflab.kernels import cache
from brdflab.kernels.cache import FAILED, HERE, NAME


def enabled() -> bool:
    """False when ``BRDFLAB_AOT=0`` asks for the JIT."""
    return os.environ.get("BRDFLAB_AOT", "1").strip() != "0"


def _cpu() -> str:
    try:
        with open("/proc/cpuinfo", encoding="utf-8", errors="replace") as f:
            lines = [ln for ln in f if ln.startswith(("model name", "flags", "Features"))]
        return "".join(sorted(set(lines)))
    except OSError:
        return platform.processor()


def key() -> str:
    """The build's key: a hash of the kernel sources, of what compiles them (numba, llvmlite, NumPy: each
    package's ``__init__.py``, path, size and modification time, which an upgrade or a reinstall changes;
    cheaper than reading their metadata) and of the Python and the CPU."""
    h = hashlib.sha256(cache.sources_hash().encode())
    for name in ("numba", "llvmlite", "numpy"):
        spec = importlib.util.find_spec(name)
        origin = spec.origin if spec is not None else None
        st = os.stat(origin) if origin else None
        h.update(f"{origin}|{st.st_size if st else 0}|{st.st_mtime_ns if st else 0}".encode())
    h.update(f"{sys.version}|{platform.machine()}|{_cpu()}".encode())
    return h.hexdigest()[:20]


def lookup(k: str | None = None) -> cache.Entry:
    """What the cache holds for this key (:func:`brdflab.kernels.cache.lookup`)."""
    return cache.lookup(k or key())


def load_module(path: Path) -> ModuleType:
    """Import the built extension module at ``path`` (verified by :func:`brdflab.kernels.cache.verify`)."""
    spec = importlib.util.spec_from_file_location(NAME, path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def _child_env() -> dict[str, str]:
    """The builder's environment: brdflab importable from where this process found it, numba's JIT."""
    path = [str(HERE.parent.parent)] + [p for p in os.environ.get("PYTHONPATH", "").split(os.pathsep) if p]
    return {**os.environ, "PYTHONPATH": os.pathsep.join(path), "BRDFLAB_AOT": "0", "BRDFLAB_JIT_CACHE": "0"}


#: Builders started in the background by this process (kept so that they are not reported as leaked).
_DETACHED: list[subprocess.Popen] = []


def start(root: Path, k: str, background: bool) -> subprocess.Popen:
    """Start the builder ``python -m brdflab.kernels.aot build ROOT KEY`` in a session of its own (a
    terminal's Ctrl-C does not reach it or its C compiler). ``background``: detached and at a low priority,
    it outlives this process (the next process picks up the module); otherwise it dies with this process."""
    cmd = [sys.executable, "-m", "brdflab.kernels.aot", "build", str(root), k,
           "background" if background else str(os.getpid())]
    # cwd: ``python -m`` puts the working folder first on sys.path, before PYTHONPATH: run from a clone holding
    # other brdflab sources, the builder compiled those under this process's key (this process then loaded
    # kernels that were not its own). From the folder above this brdflab, the builder imports this one.
    proc = subprocess.Popen(cmd, env=_child_env(), cwd=str(HERE.parent.parent), stdin=subprocess.DEVNULL,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True,
                            close_fds=True)
    if background:
        _DETACHED.append(proc)
    return proc


def build_in_background(k: str | None = None) -> tuple[bool, str]:
    """Start a detached build unless one is running: (True, "") when one was started, (False, "") when
    another process is building, (False, why) when there is no safe folder to build in or
    ``BRDFLAB_AOT_BUILD=0`` (a pre-built or read-only cache) forbids starting one."""
    if os.environ.get("BRDFLAB_AOT_BUILD", "1").strip() == "0":
        return False, "BRDFLAB_AOT_BUILD=0: no build is started"
    root, why = cache.writable_root()
    if root is None:
        return False, why
    with cache.locked(root, wait=False) as free:
        if not free:
            return False, ""
    start(root, k or key(), background=True)
    return True, ""


def build(k: str | None = None, timeout: float = 900.0) -> cache.Entry:
    """Build the module for this key and wait for it (a builder child process; processes that start at once
    — a pool, a cluster's workers — wait on the lock for the first one's build instead of repeating it).
    A signal (KeyboardInterrupt, :class:`brdflab.errors.Interrupted`) while waiting stops the builder at once
    and is raised; nothing of the stopped build is left."""
    k = k or key()
    root, why = cache.writable_root()
    if root is None:
        return cache.Entry("failed", message=why)
    proc = start(root, k, background=False)
    deadline = time.monotonic() + timeout
    try:
        while proc.poll() is None:
            if time.monotonic() > deadline:
                raise TimeoutError(f"the build took more than {timeout:.0f} s")
            time.sleep(0.05)
    except BaseException as e:
        stop(proc, root)
        if isinstance(e, TimeoutError):
            return cache.Entry("failed", root, message=str(e))
        raise
    entry = cache.lookup(k)
    if entry.state in ("built", "failed"):
        return entry
    if proc.returncode < 0:
        return cache.Entry("failed", root, message=f"the build was stopped by signal {-proc.returncode}")
    return cache.Entry("failed", root, message=entry.message or f"the build ended with status {proc.returncode}")


def stop(proc: subprocess.Popen, root: Path) -> None:
    """Stop a builder now: SIGTERM to its process group (it removes its folder), SIGKILL after 2 s; then,
    if no other build holds the lock, remove what a killed builder left."""
    for sig, wait in ((signal.SIGTERM, 2.0), (signal.SIGKILL, 5.0)):
        with contextlib.suppress(OSError):
            os.killpg(proc.pid, sig)
        try:
            proc.wait(wait)
            break
        except subprocess.TimeoutExpired:
            continue
    with contextlib.suppress(OSError), cache.locked(root, wait=False) as free:
        if free:
            cache.remove_temporaries(root)


def wait_for_build(root: Path) -> None:
    """Return when no build holds ``root``'s lock (tests, and tools that want the module)."""
    with cache.locked(root):
        pass


class _Stopped(BaseException):
    """A signal stopped the builder: not a broken build (nothing is recorded; the next process retries)."""


def _stopped(signum, frame) -> None:
    raise _Stopped(signum)


def run_build(root: Path, k: str, compile_into=None) -> int:
    """The builder (``python -m brdflab.kernels.aot build ROOT KEY``): under the lock, unless the key is
    built (or failed) already, compile every kernel into ``ROOT/.tmp-KEY-*`` (the C compiler's temporaries
    there too, not in ``$TMPDIR``), write the manifest, rename into place. A build that raises records
    its error (``build-failed.txt``, naming the folder when the disk is full); a signal records nothing."""
    compile_into = compile_into or _compile_into
    with cache.locked(root):
        entry = cache._inspect(root, k)
        if entry.state in ("built", "failed"):
            return 0
        cache.remove_temporaries(root)
        tmp = Path(tempfile.mkdtemp(prefix=f"{cache.TMP_PREFIX}{k}-", dir=root))
        scratch = tmp / "tmp"
        scratch.mkdir()
        saved = os.environ.get("TMPDIR"), tempfile.tempdir
        os.environ["TMPDIR"] = str(scratch)
        tempfile.tempdir = None  # the compiler's temporary files go to the build folder
        try:
            try:
                compile_into(str(tmp))
                if not (tmp / cache.module_name()).is_file():
                    raise RuntimeError("the build wrote no module")
                shutil.rmtree(scratch)
                cache.write_manifest(tmp, k)
            except (Exception, SystemExit) as e:
                for p in tmp.iterdir():  # first free the space (a full disk), then record the error
                    shutil.rmtree(p) if p.is_dir() else p.unlink()
                (tmp / FAILED).write_text(_failure(e, root))
            cache.install(tmp, root / k)
            with contextlib.suppress(OSError), open(root / cache.LOG, "a", encoding="utf-8") as log:
                log.write(f"{time.strftime('%Y-%m-%dT%H:%M:%SZ', time.gmtime())} {k} "
                          f"{'failed' if (root / k / FAILED).exists() else 'built'} by pid {os.getpid()}\n")
        finally:
            shutil.rmtree(tmp, ignore_errors=True)
            if saved[0] is None:  # as it was (run_build may run inside another process: the tests)
                os.environ.pop("TMPDIR", None)
            else:
                os.environ["TMPDIR"] = saved[0]
            tempfile.tempdir = saved[1]
    return 0


def _failure(e: BaseException, root: Path) -> str:
    """The text of ``build-failed.txt``: the traceback, then one line saying what went wrong."""
    if isinstance(e, OSError) and e.errno == errno.ENOSPC:
        line = f"OSError: no space left on device in {root} (free some space, or set BRDFLAB_KERNEL_CACHE)"
    else:
        line = f"{type(e).__name__}: {e}"
    return "".join(traceback.format_exception(e)) + line + "\n"


def summary(error: str) -> str:
    """The line of a build's error output that says what went wrong (its last ``…Error: …`` line)."""
    lines = [ln.strip() for ln in error.splitlines() if ln.strip()]
    named = [ln for ln in lines if re.match(r"^[A-Za-z_.]*(Error|Exception)\b", ln)]
    return (named or lines or ["unknown error"])[-1]


def _compile_into(folder: str) -> None:
    """The child process of :func:`build`: compile every kernel into ``folder``/``NAME``."""
    import warnings

    warnings.simplefilter("ignore")  # numba.pycc announces its own future replacement
    from numba import types
    from numba.pycc import CC

    from brdflab.kernels import MODULES, jit

    for name in MODULES:
        importlib.import_module(f"brdflab.kernels.{name}")
    cc = CC(NAME)
    cc.output_dir = folder
    cc.target_cpu = "host"
    for export, disp, argtypes in jit.KERNELS:
        # A trampoline, so that the exported function's own (default) compile flags do no arithmetic: the
        # kernel it calls keeps OPTIONS (NumPy's error model, no fast-math).
        args = ", ".join(f"a{i}" for i in range(len(argtypes)))
        ns = {"_kernel": disp}
        exec(f"def {export}({args}):\n    _kernel({args})\n", ns)  # noqa: S102 (fixed text, no input)
        cc.export(export, types.void(*(a.numba_type() for a in argtypes)))(ns[export])
    cc.compile()


def main(argv: list[str]) -> int:
    """``build ROOT KEY background|PARENT_PID``: :func:`run_build`, at a low priority in the background, or
    dying with its parent (``PR_SET_PDEATHSIG``) when a process waits for it."""
    _, root, k, mode = argv
    for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP, signal.SIGALRM):
        signal.signal(sig, _stopped)
    signal.alarm(1800)  # a builder that hangs holds the lock: it ends itself
    if mode == "background":
        with contextlib.suppress(OSError):
            os.nice(10)  # the run that started it (and the user's other work) come first
    else:
        from brdflab.processes import die_with_parent

        die_with_parent()
        if os.getppid() != int(mode):  # the parent died before the prctl call
            return 1
    try:
        own = key()
        if k != own:  # never store kernels compiled from other sources under this key: a failed build instead
            return run_build(Path(root), k, _foreign(k, own))
        return run_build(Path(root), k)
    except _Stopped:
        return 1


def _foreign(k: str, own: str):
    """A ``compile_into`` that fails: the builder's sources (``own`` key) are not those of the key ``k``."""
    def refuse(folder: str) -> None:
        raise RuntimeError(f"the builder's kernel sources ({HERE}, key {own}) are not those of key {k}")
    return refuse


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
