"""Ahead-of-time build of the kernels: one extension module, loaded without importing numba.

Importing numba and loading the JIT's cached machine code costs about 0.5 s per process (numba's own
import, its typing registries, and SciPy's linear algebra, which numba probes for BLAS), as much as the
compiled kernels save in a short render. So the first process that needs the kernels builds them, once,
into a Python extension module with ``numba.pycc`` (every kernel exported under
:func:`~brdflab.kernels.jit.export_name`, through a trampoline that calls the ``numba.jit`` kernel so that
its compile options — NumPy's error model, no fast-math — hold), and every later process imports that
module in a few milliseconds.

* **Where**: ``$BRDFLAB_KERNEL_CACHE`` if set, else ``brdflab/kernels/__pycache__/aot`` when writable,
  else ``~/.cache/brdflab/kernels`` (``$XDG_CACHE_HOME``). One folder per :func:`key`.
* **Key**: the sources in ``brdflab/kernels/``, the installed numba, llvmlite and NumPy, the Python, and the CPU
  (the code is compiled for the host CPU, as the JIT's is): an edit, an upgrade or another machine of a
  cluster on a shared disk builds its own.
* **Build**: in a child process (``python -m brdflab.kernels.aot DIR``, a few seconds, counted as build
  time), into a temporary folder renamed into place, so that no process ever sees half a module; processes
  starting together (a pool, a cluster's workers) wait on a lock for the first one's build.
* **Fallback**: when the build fails (no C compiler, no ``numba.pycc``), the process says so in one warning
  line, leaves the error in the folder (``build-failed.txt``; delete it to try again) and it and later
  processes use the JIT (numba's disk cache) instead. ``BRDFLAB_AOT=0`` asks for the JIT.

Both backends compile the same functions with the same options; ``tests/test_kernels_aot.py`` checks that
they agree bit for bit (``tests/test_kernels.py``: each against the NumPy code to 1e-12).
"""

from __future__ import annotations

import contextlib
import hashlib
import importlib.machinery
import importlib.util
import os
import platform
import re
import shutil
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path
from types import ModuleType

HERE = Path(__file__).resolve().parent
NAME = "brdflab_kernels"
FAILED = "build-failed.txt"


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
    h = hashlib.sha256()
    for path in sorted(HERE.glob("*.py")):  # the kernels, their helpers and this build
        h.update(path.name.encode() + path.read_bytes())
    for name in ("numba", "llvmlite", "numpy"):
        spec = importlib.util.find_spec(name)
        origin = spec.origin if spec is not None else None
        st = os.stat(origin) if origin else None
        h.update(f"{origin}|{st.st_size if st else 0}|{st.st_mtime_ns if st else 0}".encode())
    h.update(f"{sys.version}|{platform.machine()}|{_cpu()}".encode())
    return h.hexdigest()[:20]


def roots() -> list[Path]:
    """Cache folders, in the order they are tried."""
    env = os.environ.get("BRDFLAB_KERNEL_CACHE")
    if env:
        return [Path(env)]
    user = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "brdflab" / "kernels"
    return [HERE / "__pycache__" / "aot", user]


def _module_file(folder: Path) -> Path | None:
    for suffix in importlib.machinery.EXTENSION_SUFFIXES:
        p = folder / f"{NAME}{suffix}"
        if p.is_file():
            return p
    return None


def find(k: str | None = None) -> tuple[Path | None, str | None]:
    """(the built module for this key, or None; the recorded build error, or None)."""
    k = k or key()
    for root in roots():
        folder = root / k
        p = _module_file(folder)
        if p is not None:
            return p, None
        try:
            return None, (folder / FAILED).read_text(errors="replace")[-2000:]
        except OSError:  # no marker (or one this user cannot read): the next root
            continue
    return None, None


def load_module(path: Path) -> ModuleType:
    """Import the built extension module at ``path``."""
    spec = importlib.util.spec_from_file_location(NAME, path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def _writable_root() -> Path | None:
    for root in roots():
        try:
            root.mkdir(parents=True, exist_ok=True)
            with tempfile.NamedTemporaryFile(dir=root):
                return root
        except OSError:
            continue
    return None


def _child_env() -> dict[str, str]:
    """The build child's environment: brdflab importable from where this process found it."""
    path = [str(HERE.parent.parent)] + [p for p in os.environ.get("PYTHONPATH", "").split(os.pathsep) if p]
    return {**os.environ, "PYTHONPATH": os.pathsep.join(path), "BRDFLAB_AOT": "0"}


def build(k: str | None = None, timeout: float = 600.0) -> tuple[Path | None, str | None]:
    """Build the module for this key in a child process; (its path, None) or (None, the error). Processes
    that start at once (a pool, a cluster's workers) wait for the first one's build instead of repeating it."""
    k = k or key()
    root = _writable_root()
    if root is None:
        return None, "no writable cache folder"
    with _locked(root / ".build.lock"):
        path, error = find(k)
        if path is not None or error is not None:  # built (or failed) while this process waited
            return path, error
        _remove_stale(root)
        tmp = Path(tempfile.mkdtemp(prefix=f".{k}-", dir=root))
        try:
            try:
                p = subprocess.run([sys.executable, "-m", "brdflab.kernels.aot", str(tmp)], capture_output=True,
                                   text=True, timeout=timeout, env=_child_env(), preexec_fn=_child_setup(),
                                   start_new_session=True)  # a terminal's Ctrl-C reaches neither it nor its C compiler
                ok = p.returncode == 0 and _module_file(tmp) is not None
                error = None if ok else (p.stderr or p.stdout or f"exit status {p.returncode}")[-2000:]
                if p.returncode < 0:  # killed by a signal: not a broken build, the next process retries
                    return None, f"the build was stopped by signal {-p.returncode}"
            except subprocess.TimeoutExpired:  # a slow machine, not a broken build: the next process retries
                return None, f"the build took more than {timeout:.0f} s"
            except OSError as e:
                ok, error = False, f"{type(e).__name__}: {e}"
            if not ok:
                (tmp / FAILED).write_text(error or "unknown error")
            tmp.chmod(0o755)  # mkdtemp's 0700 would hide the build from other users of a shared cache
            try:
                tmp.rename(root / k)  # atomic
            except OSError:
                pass
        finally:  # whatever happens (a signal included), no temporary folder is left behind
            shutil.rmtree(tmp, ignore_errors=True)
    path, recorded = find(k)
    return path, (None if path is not None else (error or recorded))


def _child_setup():
    """For the build's child (POSIX): die with the parent (``PR_SET_PDEATHSIG``). It runs in a session of
    its own, so a terminal's signals reach only the parent, which stops the run its own way."""
    if os.name != "posix":
        return None
    from brdflab.processes import die_with_parent

    return die_with_parent


def _remove_stale(root: Path, age: float = 3600.0) -> None:
    """Remove temporary build folders older than ``age`` seconds (left by a process killed mid-build)."""
    now = time.time()
    for p in root.glob(".*-*"):
        try:
            if p.is_dir() and now - p.stat().st_mtime > age:
                shutil.rmtree(p, ignore_errors=True)
        except OSError:
            continue


@contextlib.contextmanager
def _locked(path: Path) -> Iterator[None]:
    """An exclusive lock on ``path`` (``flock``; none where the platform has no ``fcntl``)."""
    try:
        import fcntl
    except ImportError:
        yield
        return
    with open(path, "a") as f:
        fcntl.flock(f, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(f, fcntl.LOCK_UN)


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


if __name__ == "__main__":
    _compile_into(sys.argv[1])
