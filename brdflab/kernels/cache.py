"""The prebuilt kernels' cache: where it is, what in it is trusted, and how a build is installed.

A module in the cache is native code that every brdflab process of the user loads, so nothing is loaded
that this user did not build (issue 41):

* **Folders and files** (the cache root, the build's folder, the module and its manifest) must be owned by
  the user (or root) and writable by nobody else (no group or other write bit), and the build's folder and
  files must not be symbolic links. A cache folder shared with other users is refused: each user builds
  their own (a cluster's shared disk included: one folder per user, e.g. under ``~/.cache``).
* **Manifest**: the build records the module's size and SHA-256 in ``manifest.json`` beside it (written
  last, atomically: a build is complete when its manifest exists). The module is loaded only when its
  bytes match, checked **before** ``dlopen`` (a truncated module would otherwise kill the process with
  SIGBUS when the loader touches the missing pages).
* **Layout**: ``ROOT/<key>/`` holds ``brdflab_kernels<suffix>`` and ``manifest.json``, or
  ``build-failed.txt`` (the error of a build that failed; delete it to try again). Builds happen in
  ``ROOT/.tmp-<key>-*`` (the compiler's temporaries included: nothing is left in ``$TMPDIR``) under the lock
  ``ROOT/.build.lock``, and are renamed into place (and logged in ``ROOT/builds.log``); anything else in
  ``ROOT`` (a stray file, an old key) is ignored, and whatever sits at ``ROOT/<key>`` without a valid build
  (a stray file, a damaged module) is replaced by the next build.
"""

from __future__ import annotations

import contextlib
import hashlib
import importlib.machinery
import json
import os
import shutil
import stat
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

HERE = Path(__file__).resolve().parent
NAME = "brdflab_kernels"
MANIFEST = "manifest.json"
FAILED = "build-failed.txt"
#: Beside ``FAILED`` once a process has reported the failure (it is said once, not in every run).
REPORTED = "build-failed.reported"
LOCK = ".build.lock"
#: One line per build (date, key, built or failed, the builder's pid): what was built, and how often.
LOG = "builds.log"
TMP_PREFIX = ".tmp-"


class Refused(Exception):
    """A cache folder or file that must not be trusted (owner, permissions, symbolic link, bytes)."""


def module_name() -> str:
    """The extension module's file name (its init function is ``PyInit_brdflab_kernels``)."""
    return NAME + importlib.machinery.EXTENSION_SUFFIXES[0]


def sources_hash() -> str:
    """SHA-256 of every kernel source (``brdflab/kernels/*.py``, names and contents): part of the build's key
    (:func:`brdflab.kernels.aot.key`) and the name of the JIT's disk cache (:mod:`brdflab.kernels.jit`)."""
    h = hashlib.sha256()
    for path in sorted(HERE.glob("*.py")):  # the kernels, their helpers and their build
        h.update(path.name.encode() + path.read_bytes())
    return h.hexdigest()


def roots() -> list[Path]:
    """Cache folders, in the order they are tried: ``$BRDFLAB_KERNEL_CACHE`` alone if set, else
    ``brdflab/kernels/__pycache__/aot`` and ``$XDG_CACHE_HOME/brdflab/kernels`` (``~/.cache``)."""
    env = os.environ.get("BRDFLAB_KERNEL_CACHE")
    if env:
        return [Path(env)]
    user = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "brdflab" / "kernels"
    return [HERE / "__pycache__" / "aot", user]


def check_owned(path: Path, follow: bool = False) -> os.stat_result:
    """``path``'s status when it is owned by this user (or root) and not writable by group or others (and,
    unless ``follow``, not a symbolic link); else :class:`Refused`."""
    st = os.stat(path) if follow else os.lstat(path)
    if stat.S_ISLNK(st.st_mode):
        raise Refused(f"{path} is a symbolic link")
    if st.st_uid not in (os.geteuid(), 0):
        raise Refused(f"{path} belongs to another user (uid {st.st_uid})")
    if st.st_mode & 0o022:
        who = {0o022: "group and others", 0o020: "group", 0o002: "others"}[st.st_mode & 0o022]
        raise Refused(f"{path} is writable by {who}")
    return st


def sha256(path: Path) -> str:
    """The SHA-256 of a file's bytes (hex)."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


@dataclass
class Entry:
    """What the cache holds for a key: ``state`` is ``"built"`` (``path`` verified), ``"missing"``,
    ``"failed"`` (``message``: the build's error), ``"damaged"`` (something at the key's place that is not a
    valid build: rebuilt by the next build) or ``"refused"`` (``message``: why; not ours to rebuild)."""

    state: str
    root: Path | None = None
    path: Path | None = None
    message: str = ""
    reported: bool = False


def verify(folder: Path) -> Path:
    """The module of the build in ``folder``, after checking owner and permissions of the folder, the
    manifest and the module, and the module's size and hash against the manifest; else :class:`Refused`
    (or ``OSError``/``ValueError`` for an unreadable or malformed manifest)."""
    check_owned(folder)
    check_owned(folder / MANIFEST)
    manifest = json.loads((folder / MANIFEST).read_text(encoding="utf-8"))
    if not isinstance(manifest, dict) or manifest.get("module") != module_name():
        raise Refused(f"{folder / MANIFEST} does not name {module_name()}")
    module = folder / module_name()
    st = check_owned(module)
    if not stat.S_ISREG(st.st_mode) or st.st_size != manifest.get("size") or sha256(module) != manifest.get("sha256"):
        raise Refused(f"{module} does not match its manifest (damaged or replaced)")
    return module


def lookup(key: str) -> Entry:
    """What the cache holds for ``key`` (:class:`Entry`): a verified build from any root, else what the first
    root holding something for the key holds, else ``"missing"``."""
    found = [e for e in (_inspect(root, key) for root in roots()) if e.state != "missing"]
    return next((e for e in found if e.state == "built"), found[0] if found else Entry("missing"))


def _inspect(root: Path, key: str) -> Entry:
    folder = root / key
    if not os.path.lexists(folder):
        return Entry("missing")
    try:
        check_owned(root, follow=True)
    except (Refused, OSError) as e:
        return Entry("refused", root, message=f"the kernel cache folder is not safe to load from: {e}")
    try:
        return Entry("built", root, verify(folder))
    except Refused as e:
        why = str(e)
    except (OSError, ValueError):
        why = f"{folder} holds no complete build"
    try:
        check_owned(folder)
        check_owned(folder / FAILED)
        text = (folder / FAILED).read_text(errors="replace")[-2000:]
        return Entry("failed", root, message=text, reported=(folder / REPORTED).exists())
    except (OSError, Refused):
        return Entry("damaged", root, message=why)


def writable_root() -> tuple[Path | None, str]:
    """(the first cache root that exists or can be made, owned by this user (or root), writable by it and by
    nobody else — made 0755 when this process creates it —, ""), or (None, why there is none)."""
    why = []
    for root in roots():
        try:
            if not root.exists():
                root.mkdir(parents=True, exist_ok=True)
                root.chmod(0o755)  # whatever the umask (a group-writable umask would make it refused)
            check_owned(root, follow=True)
            if os.access(root, os.W_OK | os.X_OK):
                return root, ""
            why.append(f"{root} is not writable")
        except Refused as e:
            why.append(str(e))
        except OSError as e:
            why.append(f"{root}: {e.strerror or e}")
    return None, "no safe cache folder to build the compiled kernels in (" + "; ".join(why) + ")"


@contextlib.contextmanager
def locked(root: Path, wait: bool = True) -> Iterator[bool]:
    """Hold the build lock of ``root`` (``flock``); yields False when ``wait`` is False and another process
    holds it (a build in progress)."""
    import fcntl

    fd = os.open(root / LOCK, os.O_RDWR | os.O_CREAT, 0o644)
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | (0 if wait else fcntl.LOCK_NB))
        except BlockingIOError:
            yield False
            return
        yield True
    finally:
        os.close(fd)  # releases the lock


def remove_temporaries(root: Path) -> None:
    """Remove the build folders of builders that died (call with the lock held: nobody else is building)."""
    for p in root.glob(TMP_PREFIX + "*"):
        shutil.rmtree(p, ignore_errors=True)


def install(tmp: Path, folder: Path) -> None:
    """Put the finished build ``tmp`` in place at ``folder`` (with the lock held): whatever was there (a
    damaged build, a stray file) is moved aside and removed, then ``tmp`` is renamed (atomic)."""
    tmp.chmod(0o755)  # mkdtemp's 0700 would hide the build from the user's other tools; 0755, not group-writable
    if os.path.lexists(folder):
        aside = folder.with_name(f"{TMP_PREFIX}old-{folder.name}-{os.getpid()}-{time.monotonic_ns()}")
        os.rename(folder, aside)
        if aside.is_dir() and not aside.is_symlink():
            shutil.rmtree(aside, ignore_errors=True)
        else:
            aside.unlink()
    os.rename(tmp, folder)


def write_manifest(folder: Path, key: str) -> None:
    """Record the module's name, size and hash in ``folder/manifest.json`` (written to a temporary, then
    renamed: a reader sees no manifest or a whole one)."""
    module = folder / module_name()
    data = {"module": module_name(), "size": module.stat().st_size, "sha256": sha256(module), "key": key,
            "built": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())}
    part = folder / (MANIFEST + ".part")
    with open(part, "w", encoding="utf-8") as f:
        json.dump(data, f)
        f.flush()
        os.fsync(f.fileno())
    os.replace(part, folder / MANIFEST)
    module.chmod(0o755)
    (folder / MANIFEST).chmod(0o644)
