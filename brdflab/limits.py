"""Resource limits: input files and memory, checked before anything is read or allocated.

Two documented limits protect a run from inputs that would hang it or exhaust the machine. Both can be
raised by the user through an environment variable:

=============================  ==================================  ===========================================
variable                       default                             what it bounds
=============================  ==================================  ===========================================
``BRDFLAB_MAX_INPUT_MB``       2048 (2 GiB)                        size of any input file (scene, OBJ, EXR)
``BRDFLAB_MEMORY_LIMIT_GB``    half of the physical memory         estimated memory of the film, the
                               (at most 16)                        environment map tables and the workers
``BRDFLAB_MAX_HOURS``          24                                  estimated least duration of a run without
                                                                   a time limit (:func:`check_work`)
=============================  ==================================  ===========================================

:func:`read_input` is the one way brdflab opens a user's file for reading: it refuses what is not a
regular file (a FIFO would block forever, ``/dev/zero`` would never end, a directory cannot be read) and
says which kind of file it is, and it refuses files above the size limit before reading a byte (a 20 GB
sparse file). :func:`check_input` does the same checks for readers that open the path themselves
(OpenEXR). :func:`check_memory` compares an estimate with the memory limit and raises
:class:`~brdflab.errors.ResourceError` ("would need 3.0 GiB for …") instead of letting an allocation end
in ``MemoryError`` or the kernel's OOM killer. :func:`check_work` does the same for time: a render of
2^40 spp is refused before it starts ("would take at least 27 years"), unless a time limit bounds it.
"""

from __future__ import annotations

import errno
import os
import stat
from pathlib import Path

from brdflab.errors import BrdflabError, ResourceError, clean

INPUT_ENV = "BRDFLAB_MAX_INPUT_MB"
MEMORY_ENV = "BRDFLAB_MEMORY_LIMIT_GB"
DEFAULT_INPUT_MB = 2048
WORK_ENV = "BRDFLAB_MAX_HOURS"
DEFAULT_MAX_HOURS = 24.0
#: Samples per second per worker assumed by :func:`check_work`: about 4× the fastest rate brdflab has been
#: measured at (2.5 M samples/s on an idle core, README "Benchmarks"), so an estimate is a lower bound.
OPTIMISTIC_RATE = 10e6
#: Smallest roughness α the validators and views accept: below it the microfacet D = 1/(π α²) … and its
#: quadrature lose float64 precision (measured: brdflab's own correct roughconductor fails the chi-square
#: test at α = 10⁻⁸, and one albedo quadrature takes 10 s at 10⁻⁷ against 0.2 s at 10⁻⁶); such a
#: surface is a mirror at every resolution brdflab draws.
MIN_ALPHA = 1e-6
#: Sample counts are 64-bit: samples per pixel (and seeds of passes) beyond this cannot be counted.
MAX_SPP = 2**63 - 1
#: Resident memory a forked render worker needs besides what it shares with the parent (its batch
#: temporaries and interpreter pages that copy-on-write duplicates), used by the worker estimate.
WORKER_BYTES = 96 * 2**20

_KINDS = ((stat.S_ISDIR, "a directory"), (stat.S_ISFIFO, "a FIFO (named pipe)"),
          (stat.S_ISCHR, "a character device"), (stat.S_ISBLK, "a block device"), (stat.S_ISSOCK, "a socket"))


def _env_number(name: str, default: float) -> float:
    text = os.environ.get(name)
    if text is None or not text.strip():
        return default
    try:
        value = float(text)
    except ValueError:
        value = float("nan")
    if not (value > 0 and value < float("inf")):
        raise BrdflabError(f"environment variable {name} must be a positive number, got '{clean(text)}'")
    return value


def max_input_bytes() -> int:
    """The input-file size limit in bytes (``BRDFLAB_MAX_INPUT_MB``, default 2048)."""
    return int(_env_number(INPUT_ENV, DEFAULT_INPUT_MB) * 2**20)


def memory_limit_bytes() -> int:
    """The memory limit in bytes (``BRDFLAB_MEMORY_LIMIT_GB``, default half of physical memory, ≤ 16 GiB)."""
    try:
        physical = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (ValueError, OSError, AttributeError):
        physical = 16 * 2**30
    default = min(16.0, physical / 2 / 2**30)
    return int(_env_number(MEMORY_ENV, default) * 2**30)


def gib(nbytes: float) -> str:
    """``"3.0 GiB"`` (or MiB below one GiB)."""
    return f"{nbytes / 2**30:.1f} GiB" if nbytes >= 2**30 else f"{nbytes / 2**20:.0f} MiB"


def check_memory(nbytes: float, what: str) -> None:
    """Raise :class:`ResourceError` when ``nbytes`` (an estimate) exceeds :func:`memory_limit_bytes`.

    ``what`` completes "would need … for": e.g. ``"the 16384×8192 environment map"``.
    """
    limit = memory_limit_bytes()
    if nbytes > limit:
        raise ResourceError(f"would need {gib(nbytes)} for {what}, more than the memory limit of {gib(limit)} "
                            f"(raise it with {MEMORY_ENV}=<GiB>)")


def duration(seconds: float) -> str:
    """``"3.2 hours"``, ``"27 years"``: a rough duration for messages."""
    for unit, size in (("years", 365.25 * 86400), ("days", 86400), ("hours", 3600), ("minutes", 60)):
        if seconds >= size:
            n = seconds / size
            return f"{n:.3g} {unit}" if n < 1000 else (f"{n:,.0f} {unit}" if n < 1e9 else f"{n:.1e} {unit}")
    return f"{seconds:.0f} seconds"


def max_local_workers() -> int:
    """Most workers of a ``local:N`` Dask cluster: 4 per core (``BRDFLAB_MAX_LOCAL_WORKERS`` overrides)."""
    return int(_env_number("BRDFLAB_MAX_LOCAL_WORKERS", 4 * (os.cpu_count() or 1)))


def check_alpha(alpha: object, what: str = "alpha") -> None:
    """Raise :class:`BrdflabError` unless ``alpha`` is a finite roughness ≥ :data:`MIN_ALPHA`."""
    try:
        a = float(alpha)
    except (TypeError, ValueError):
        raise BrdflabError(f"{what} must be a number, got {clean(alpha, 30)}") from None
    if not (a >= MIN_ALPHA and a < float("inf")):
        raise BrdflabError(f"{what} must be a finite roughness ≥ {MIN_ALPHA:g} (below, the microfacet "
                           f"formulas lose float64 precision and the surface is a mirror), got {clean(alpha, 30)}")


def check_test_arguments(theta: object, samples: object, threshold: object = None,
                         two_sided: bool = False) -> tuple[float | None, int, float | None]:
    """The arguments of a test, checked like the command line's options: θ_i a finite angle in [0°, 90°)
    (None: no angle; [0°, 180°) for a ``two_sided`` BSDF, ω_i inside beyond 90°), ``samples`` an integer ≥ 1,
    ``threshold`` in (0, 1) or None.

    Raises
    ------
    BrdflabError
        Naming the argument (a test at θ_i = 90° or −10° would otherwise test nothing, or the wrong side,
        and report a pass).
    """
    import math
    import numbers

    if theta is not None:
        try:
            t = float(theta)
        except (TypeError, ValueError):
            raise BrdflabError(f"theta must be a number of degrees, got {clean(repr(theta), 30)}") from None
        top = 180.0 if two_sided else 90.0
        if not (math.isfinite(t) and 0.0 <= t < top):
            raise BrdflabError(f"theta must be in [0, {top:g}) degrees (ω_i above the surface"
                               + (" or, beyond 90, inside" if two_sided else "") + f"), got {clean(theta, 30)}")
        theta = t
    if isinstance(samples, bool) or not isinstance(samples, numbers.Integral) or samples < 1:
        raise BrdflabError(f"samples must be an integer ≥ 1, got {clean(repr(samples), 30)}")
    if threshold is not None:
        try:
            ok = 0.0 < float(threshold) < 1.0
        except (TypeError, ValueError):
            ok = False
        if not ok:
            raise BrdflabError(f"threshold must be a probability in (0, 1), got {clean(repr(threshold), 30)}")
        threshold = float(threshold)
    return theta, int(samples), threshold


def check_spp(spp: object, what: str = "spp") -> int:
    """``spp`` as an int in [1, 2^63): anything else (a float, 10**30, a negative count) is a
    :class:`BrdflabError`."""
    import numbers

    if isinstance(spp, bool) or not isinstance(spp, numbers.Integral):
        raise BrdflabError(f"{what} must be an integer, got {clean(repr(spp), 30)}")
    spp = int(spp)
    if not 1 <= spp <= MAX_SPP:
        raise BrdflabError(f"{what} must be between 1 and 2^63 − 1, got {clean(spp, 30)}")
    return spp


def check_work(samples: float, workers: int, what: str, time_limit: float | None = None,
               limit_option: str | None = "--time-limit") -> None:
    """Raise :class:`ResourceError` when ``samples`` (camera samples, BSDF evaluations …) on ``workers``
    would take longer than ``BRDFLAB_MAX_HOURS`` even at :data:`OPTIMISTIC_RATE`, before the work starts.

    A ``time_limit`` (seconds) bounds the run: nothing is refused when it is within the limit (a time limit
    of 10³⁰⁰ s bounds nothing). ``limit_option`` is the option that sets one (None: the command has none).
    """
    seconds = float(samples) / (OPTIMISTIC_RATE * max(int(workers), 1))
    limit = _env_number(WORK_ENV, DEFAULT_MAX_HOURS) * 3600
    if min(seconds, time_limit if time_limit is not None else float("inf")) > limit:
        bound = f", pass {limit_option} SECONDS" if limit_option else ""
        raise ResourceError(f"{what} would take at least {duration(seconds)} ({float(samples):.3g} samples at "
                            f"{OPTIMISTIC_RATE / 1e6:.0f} M/s per worker); lower the sample count{bound} or raise "
                            f"{WORK_ENV}=<hours>")


def check_input(path: str | Path, what: str = "input file", error: type[BrdflabError] = BrdflabError) -> int:
    """Check that ``path`` is a readable regular file within the size limit; return its size in bytes.

    Raises ``error`` (a :class:`BrdflabError` subclass) naming the file: not found, not a regular file
    (saying what it is instead), too long a name, or larger than ``BRDFLAB_MAX_INPUT_MB``.
    """
    try:
        st = os.stat(path)
    except FileNotFoundError:
        raise error(f"{what} not found", path) from None
    except OSError as exc:
        reason = "file name too long" if exc.errno == errno.ENAMETOOLONG else (exc.strerror or str(exc))
        raise error(f"cannot read {what}: {reason}", path) from None
    if not stat.S_ISREG(st.st_mode):
        kind = next((name for test, name in _KINDS if test(st.st_mode)), "not a regular file")
        raise error(f"{what} is {kind}, not a regular file", path)
    limit = max_input_bytes()
    if st.st_size > limit:
        raise error(f"{what} is {gib(st.st_size)}, larger than the input limit of {gib(limit)} "
                    f"(raise it with {INPUT_ENV}=<MiB>)", path)
    return st.st_size


def read_input(path: str | Path, what: str = "input file", error: type[BrdflabError] = BrdflabError,
               size: int | None = None) -> bytes:
    """Read a whole input file after :func:`check_input`; never blocks on a FIFO or reads past the limit.

    ``size``: the exact size the format requires (a MERL table): any other size is refused from the file's
    metadata, before a byte is read (a sparse file of gigabytes costs nothing).
    """
    actual = check_input(path, what, error)
    if size is not None and actual != size:
        raise error(f"{what} has {actual} bytes, expected {size}", path)
    try:
        # O_NONBLOCK: if the path was swapped for a FIFO after the check, open() must not wait for a writer.
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0))
    except OSError as exc:
        raise error(f"cannot read {what}: {exc.strerror}", path) from None
    with os.fdopen(fd, "rb") as f:
        if not stat.S_ISREG(os.fstat(f.fileno()).st_mode):
            raise error(f"{what} is not a regular file", path)
        try:
            data = f.read() if size is None else f.read(size + 1)
        except OSError as exc:
            raise error(f"cannot read {what}: {exc.strerror}", path) from None
    if len(data) > max_input_bytes():
        raise error(f"{what} grew beyond the input limit while it was read (raise it with {INPUT_ENV})", path)
    return data
