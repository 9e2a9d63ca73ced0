"""EXR and PNG input/output (OpenEXR for EXR, Pillow for PNG; spec §1).

EXR files are written as Nori writes them: scanline, three 32-bit float channels R, G, B, ZIP
compression, a ``comments`` attribute. PNG files are 8-bit sRGB with Nori's transfer curve and
truncating quantisation: byte = ⌊clamp(255·s(c), 0, 255)⌋ with s the sRGB OETF (IEC 61966-2-1).
All writes are atomic: a temporary file in the same folder is renamed
into place, so an interrupted run never leaves a half-written image; an EXR + PNG pair is replaced
together or not at all (:func:`write_images`, :func:`write_files`). Input files go through
:func:`brdflab.limits.check_input` (regular file, size limit) first.

PNG goes through Pillow directly (matplotlib's writer wraps it, and importing matplotlib took ~0.4 s of
every render's run time) with zlib level 1: 800×600 renders encode 3–5× faster than at the default level 6
(table 0.20 → 0.04 s CPU) for files within ±17 % of the size. :func:`write_images` writes the EXR and the
PNG at the same time (zlib and the sRGB conversion release the GIL).
"""

from __future__ import annotations

import os
import tempfile
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path

import numpy as np

from brdflab.errors import ImageError, clean
from brdflab.limits import check_input, check_memory

#: Temporary files being written right now; a second signal removes them before the process exits.
_TEMPORARIES: set[str] = set()
#: Guards the writer jobs' start and end (an RLock inside: a signal handler on the main thread may take it).
_GATE = threading.Condition()
#: The writer jobs running now, and whether :func:`remove_temporaries` closed the gate (no job starts after).
_JOBS = {"running": 0, "closed": False}
#: Longest wait of :func:`remove_temporaries` for the running writers (an encoder stuck on a dead network disk).
WRITER_WAIT = 30.0


def remove_temporaries() -> None:
    """Delete the temporary files of writes in progress; for a process about to exit (a run aborted by a second
    signal): no write starts after it.

    The running encoders are waited for first (at most :data:`WRITER_WAIT` seconds): OpenEXR and Pillow open
    their temporary by name, so one that opened it after the removal would create it again and the exit would
    leave it behind. A writer thread that had not begun its job when the gate closed never begins it.
    """
    with _GATE:
        _JOBS["closed"] = True
        _GATE.wait_for(lambda: _JOBS["running"] == 0, timeout=WRITER_WAIT)
    for tmp in list(_TEMPORARIES):
        try:
            os.unlink(tmp)
        except OSError:
            pass
        _TEMPORARIES.discard(tmp)


@contextmanager
def _job(cancelled: list[bool], mine: list[int]) -> Iterator[bool]:
    """Run one writer job through the gate: yields False (do nothing) once the gate is closed or the call
    ``cancelled``; counts the job in ``mine`` (the call's) and the module's running jobs while it runs."""
    with _GATE:
        go = not (_JOBS["closed"] or cancelled[0])
        if go:
            _JOBS["running"] += 1
            mine[0] += 1
    if not go:
        yield False
        return
    try:
        yield True
    finally:
        with _GATE:
            _JOBS["running"] -= 1
            mine[0] -= 1
            _GATE.notify_all()


def _write_error(path: Path, exc: BaseException) -> ImageError:
    reason = exc.strerror if isinstance(exc, OSError) and exc.strerror else str(exc) or type(exc).__name__
    return ImageError(f"cannot write image: {clean(reason, 120)}", path)


@contextmanager
def output_lock(folder: str | Path) -> Iterator[None]:
    """Hold an exclusive advisory lock on ``folder`` (``flock`` of the directory itself, so no lock file is
    left behind): concurrent brdflab runs writing into the same folder replace their files one after
    the other, never interleaved."""
    try:
        import fcntl
    except ImportError:  # not POSIX: no locking
        yield
        return
    try:
        fd = os.open(folder, os.O_RDONLY)
    except OSError:
        yield
        return
    try:
        fcntl.flock(fd, fcntl.LOCK_EX)
        yield
    finally:
        os.close(fd)  # releases the lock


@contextmanager
def _signals_held() -> Iterator[None]:
    """Hold SIGINT/SIGTERM/SIGHUP back for a few system calls (a temporary's creation and registration, the
    renames of a pair), so that a signal can never fall between them; they are handled right after, in order.

    Python runs signal handlers in the main thread whichever thread the system delivers a signal to, so a
    signal mask of the main thread would not hold them (another thread takes the signal and the handler runs
    at once): the handlers are swapped for a recorder instead, and the recorded signals passed to the handlers
    that were in place (the system's default action for ``SIG_DFL``, nothing for ``SIG_IGN``).
    """
    import signal

    if threading.current_thread() is not threading.main_thread():
        yield
        return
    held: list[int] = []
    sigs = [getattr(signal, n) for n in ("SIGINT", "SIGTERM", "SIGHUP") if hasattr(signal, n)]
    previous = {sig: signal.signal(sig, lambda signum, frame: held.append(signum)) for sig in sigs}
    try:
        yield
    finally:
        for sig, prev in previous.items():
            signal.signal(sig, signal.SIG_DFL if prev is None else prev)
        for signum in held:
            prev = previous[signum]
            if callable(prev):
                prev(signum, None)
            elif prev in (None, signal.SIG_DFL):
                os.kill(os.getpid(), signum)


def _temporary(path: Path) -> str:
    # An ASCII name (the final name may hold bytes that are not UTF-8, which OpenEXR cannot take). Signals are
    # held back from the file's creation to its registration, so that an abort cannot fall in between.
    with _signals_held():
        fd, tmp = tempfile.mkstemp(prefix=".brdflab-",
                                   suffix=".tmp" + path.suffix.encode("ascii", "replace").decode(), dir=path.parent)
        os.close(fd)
        _TEMPORARIES.add(tmp)
    return tmp


def write_files(items: list[tuple[str | Path, Callable[[str], None]]]) -> list[float]:
    """Write several files so that they are replaced together or not at all; return each writer's seconds.

    Every ``writer(temporary_path)`` runs first, into temporaries beside the targets (each on a thread of its
    own, all at the same time, while this thread waits, so that an abort by a signal can wait for them:
    :func:`remove_temporaries`); only when all succeeded are the
    targets replaced, by renames under :func:`output_lock` of their folder with SIGINT/SIGTERM/SIGHUP held
    back (:func:`_signals_held`). If a rename fails, the files already replaced get their previous contents
    back. On any failure
    the temporaries are removed, the old files are untouched and :class:`ImageError` says why (a full
    disk is "No space left on device").
    """
    paths = [Path(p) for p, _ in items]
    temps: list[str] = []
    took = [0.0] * len(items)
    errors: list[ImageError | None] = [None] * len(items)
    umask = os.umask(0o022)  # read (and restore) once, before any thread starts
    os.umask(umask)

    cancelled, mine = [False], [0]

    def job(i: int) -> None:
        t0 = time.perf_counter()
        with _job(cancelled, mine) as go:
            if not go:
                errors[i] = ImageError("write cancelled", paths[i])
                return
            try:
                items[i][1](temps[i])
                os.chmod(temps[i], 0o666 & ~umask)  # mkstemp creates 0600; give the image the usual permissions
            except Exception as exc:  # OpenEXR raises RuntimeError, Pillow OSError/ValueError
                errors[i] = _write_error(paths[i], exc)
        took[i] = time.perf_counter() - t0

    for path in paths:
        if path.is_dir():
            raise ImageError("is a folder; expected an image file name", path)
    try:
        for path in paths:
            try:
                path.parent.mkdir(parents=True, exist_ok=True)
                temps.append(_temporary(path))
            except OSError as exc:
                raise _write_error(path, exc) from None
        threads = [threading.Thread(target=job, args=(i,), name="brdflab-write") for i in range(len(items))]
        try:
            for th in threads:
                th.start()
            for th in threads:
                th.join()
        finally:
            # Interrupted (a signal's exception): jobs that have not begun never will; wait for the running ones
            # before the temporaries are removed below.
            with _GATE:
                cancelled[0] = True
                _GATE.wait_for(lambda: mine[0] == 0, timeout=WRITER_WAIT)
        failed = next((e for e in errors if e is not None), None)
        if failed is not None:
            raise failed
        with output_lock(paths[0].parent), _signals_held():
            # [target, its previous contents moved aside (or None), whether the new file is in place]
            done: list[list] = []
            try:
                for path, tmp in list(zip(paths, temps, strict=True)):
                    entry = [path, None, False]
                    if len(paths) > 1 and os.path.lexists(path):
                        entry[1] = _temporary(path)
                        temps.append(entry[1])  # removed in the end if it is still there
                        os.replace(path, entry[1])
                    done.append(entry)
                    os.replace(tmp, path)
                    entry[2] = True
            except OSError as exc:
                # Undo: every target gets its previous contents back, or disappears if it had none.
                for old, backup, placed in reversed(done):
                    if backup is not None:
                        os.replace(backup, old)
                    elif placed:
                        os.unlink(old)
                raise _write_error(path, exc) from None
            for _, backup, _ in done:
                if backup is not None:
                    os.unlink(backup)
                    _TEMPORARIES.discard(backup)
    finally:
        for tmp in temps:
            if os.path.exists(tmp):
                os.unlink(tmp)
            _TEMPORARIES.discard(tmp)
    return took


def _atomic_write(path: str | Path, writer: Callable[[str], None]) -> None:
    write_files([(path, writer)])


def read_exr(path: str | Path) -> np.ndarray:
    """Read the R, G, B channels of an OpenEXR file (half or float, any compression).

    Returns
    -------
    numpy.ndarray
        Float32 array of shape (H, W, 3), row 0 at the top.
    """
    import OpenEXR

    path = Path(path)
    width, height = exr_size(path)
    check_memory(width * height * 4 * 4 * 3, f"decoding the {width}×{height} EXR image {clean(path.name)}")
    try:
        f = OpenEXR.File(str(path))
        channels = {name: ch.pixels for name, ch in f.channels().items()}
    except Exception as exc:  # OpenEXR raises plain exceptions for corrupt files
        raise ImageError(f"cannot read EXR file ({clean(exc, 100)})", path) from None
    if "RGB" in channels:
        rgb = channels["RGB"]
    elif "RGBA" in channels:
        rgb = channels["RGBA"][..., :3]
    elif all(c in channels for c in "RGB"):
        rgb = np.stack([channels[c] for c in "RGB"], axis=-1)
    elif "Y" in channels:
        rgb = np.repeat(channels["Y"][..., None], 3, axis=-1)
    else:
        raise ImageError(f"EXR file has no R, G, B (or Y) channels; it has {clean(sorted(channels))}", path)
    return np.ascontiguousarray(rgb, dtype=np.float32)


def read_exr_header(path: str | Path) -> dict:
    """Return the header attributes of an EXR file as a dict (the pixels are not decoded)."""
    import OpenEXR

    check_input(path, "EXR file", ImageError)
    try:
        return dict(OpenEXR.File(str(path), header_only=True).header())
    except Exception as exc:
        raise ImageError(f"cannot read EXR file ({clean(exc, 100)})", path) from None


def exr_size(path: str | Path) -> tuple[int, int]:
    """(width, height) of an EXR file's data window, read from its header only."""
    header = read_exr_header(path)
    try:
        lo, hi = header["dataWindow"]
        width, height = int(hi[0]) - int(lo[0]) + 1, int(hi[1]) - int(lo[1]) + 1
    except (KeyError, TypeError, ValueError, IndexError):
        raise ImageError("EXR header has no valid dataWindow", path) from None
    if width < 1 or height < 1:
        raise ImageError(f"EXR data window is empty ({width}×{height})", path)
    return width, height


def write_exr(path: str | Path, rgb: np.ndarray, comments: str = "Generated by brdflab",
              extra: dict[str, str] | None = None) -> None:
    """Write a (H, W, 3) linear image as a 32-bit float RGB EXR, atomically."""
    _atomic_write(path, _exr_writer(rgb, comments, extra))


def _exr_writer(rgb: np.ndarray, comments: str = "Generated by brdflab",
                extra: dict[str, str] | None = None) -> Callable[[str], None]:
    import OpenEXR

    rgb = np.ascontiguousarray(rgb, dtype=np.float32)
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage, "comments": comments}
    if extra:
        header.update(extra)

    def writer(tmp: str) -> None:
        OpenEXR.File(header, {"RGB": rgb}).write(tmp)

    return writer


def _png_writer(rgb: np.ndarray) -> Callable[[str], None]:
    from PIL import Image
    from PIL.PngImagePlugin import PngInfo

    info = PngInfo()
    info.add_text("Software", "brdflab")  # brdflab.outputs.made_by_brdflab: a later run may replace it
    # The sRGB conversion runs in the writer (on its thread, beside the EXR's encoder), not before it.
    return lambda tmp: Image.fromarray(srgb_bytes(rgb), "RGB").save(tmp, format="PNG",
                                                                    compress_level=PNG_COMPRESS_LEVEL, pnginfo=info)


def srgb_bytes(rgb: np.ndarray) -> np.ndarray:
    """Convert linear RGB to 8-bit sRGB exactly as Nori does (OETF, then truncation)."""
    c = np.clip(np.nan_to_num(np.asarray(rgb, dtype=np.float64), nan=0.0, posinf=1.0, neginf=0.0), 0.0, None)
    # Spec §1 (the IEC 61966-2-1 OETF): s = 12.92 c for c ≤ 0.0031308, else 1.055 c^(1/2.4) − 0.055; then
    # ⌊clip(255 s, 0, 255)⌋. Evaluated as written, c = 1 gives 1.055 − 0.055 = 0.9999999999999999 and byte 254
    # (float32 arithmetic rounds that difference below 1 too); above 1 the clip gives 255.
    s = np.where(c <= 0.0031308, 12.92 * c, 1.055 * np.power(c, 1.0 / 2.4) - 0.055)
    return np.floor(np.clip(255.0 * s, 0.0, 255.0)).astype(np.uint8)


#: zlib level of the PNG previews (see the module docstring).
PNG_COMPRESS_LEVEL = 1


def write_png(path: str | Path, rgb: np.ndarray) -> None:
    """Write a (H, W, 3) linear image as an 8-bit sRGB PNG, atomically."""
    _atomic_write(path, _png_writer(rgb))


def write_images(exr: str | Path, png: str | Path, rgb: np.ndarray, extra: dict[str, str] | None = None,
                 comments: str = "Generated by brdflab") -> tuple[float, float]:
    """Write ``rgb`` as the EXR ``exr`` and its PNG preview ``png`` so that both are replaced together or
    neither is (:func:`write_files`: a full disk or a concurrent run never leaves a mismatched or
    half-replaced pair). The two encodings run at the same time (the PNG on a second thread; zlib and the
    sRGB conversion release the GIL); returns the seconds each took."""
    took = write_files([(exr, _exr_writer(rgb, comments, extra)), (png, _png_writer(rgb))])
    return took[0], took[1]


def read_png(path: str | Path) -> np.ndarray:
    """Read a PNG as uint8 (H, W, 3)."""
    from PIL import Image

    with Image.open(path) as im:
        return np.asarray(im.convert("RGB"), dtype=np.uint8)
