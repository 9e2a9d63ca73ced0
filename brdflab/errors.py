"""User-facing errors.

Every problem caused by the user's input (scene files, meshes, images, command-line values) is raised as
:class:`BrdflabError` or a subclass. The CLI prints them as one short message and exits non-zero, with no
traceback. Anything else is a bug in brdflab.
"""

from __future__ import annotations

import re
from pathlib import Path

#: Echoed values (a token from a file, an attribute, a command-line value) are cut to this many characters.
ECHO_CHARS = 60
#: A whole error or warning line is cut to this many characters.
MESSAGE_CHARS = 300
#: Exit statuses of the ``brdflab`` command (see the README, "Exit status").
EXIT_OK, EXIT_CHECK_FAILED, EXIT_USAGE = 0, 1, 2

_CONTROL = re.compile(r"[\x00-\x1f\x7f-\x9f\u2028\u2029\ud800-\udfff]")


def _escape_char(m: re.Match) -> str:
    c = m.group(0)
    o = ord(c)
    if 0xDC80 <= o <= 0xDCFF:  # a byte that was not valid UTF-8 (surrogateescape, e.g. in a file name)
        return f"\\x{o - 0xDC00:02x}"
    return {"\n": "\\n", "\t": "\\t", "\r": "\\r"}.get(c, f"\\x{o:02x}" if o < 0x100 else f"\\u{o:04x}")


def clean(text: object, limit: int = ECHO_CHARS) -> str:
    """Return ``text`` made safe to show in a one-line message.

    Control characters (ESC, BEL, NUL, newlines, …) and undecodable bytes are escaped (``\\x1b``) and the
    result is cut to ``limit`` characters followed by "…". Only the first ``4 · limit`` characters of
    ``text`` are ever looked at, so a value of hundreds of megabytes costs nothing.

    Every message that echoes user input (an XML attribute, an OBJ token, an EXR header, a command-line
    value, a path) passes it through this function.
    """
    s = text if isinstance(text, str) else str(text)
    long = len(s) > limit
    s = _CONTROL.sub(_escape_char, s[: 4 * limit + 1])
    if long or len(s) > limit:
        return s[: max(limit - 1, 1)] + "…"
    return s


def ascii_int(text: str, signed: bool = False) -> int | None:
    """``text`` as an integer when it is written in ASCII digits (an optional sign with ``signed``), else None.

    Python's ``str.isdigit`` is True for '²' (which ``int`` refuses) and ``int`` itself accepts other scripts'
    digits ('١٢'); a number typed in a scene file, an address or an option is ASCII, so every parser of counts
    and indices uses this one rule.

    Examples
    --------
    >>> ascii_int("12"), ascii_int("²"), ascii_int("\u0661"), ascii_int("-3"), ascii_int("-3", signed=True)
    (12, None, None, None, -3)
    """
    t = text.strip() if isinstance(text, str) else ""
    if re.fullmatch(r"[+-]?[0-9]{1,30}" if signed else r"[0-9]{1,30}", t):
        return int(t)
    return None


def quoted(text: object, limit: int = ECHO_CHARS) -> str:
    """``'value'`` as :func:`clean` makes it, in single quotes (the form messages use for echoed input)."""
    return f"'{clean(text, limit)}'"


class BrdflabError(Exception):
    """An error caused by user input, reported without a traceback.

    Parameters
    ----------
    message
        What was wrong and what was expected.
    file
        The file the problem is in, if any.
    line
        1-based line number inside ``file``, if known.
    column
        1-based column number, if known.
    """

    def __init__(
        self,
        message: str,
        file: str | Path | None = None,
        line: int | None = None,
        column: int | None = None,
    ) -> None:
        self.message = message
        self.file = str(file) if file is not None else None
        self.line = line
        self.column = column
        super().__init__(self.__str__())

    def location(self) -> str:
        """Return ``file:line:column`` (as much of it as is known), or an empty string."""
        if self.file is None:
            return ""
        loc = self.file
        if self.line is not None:
            loc += f":{self.line}"
            if self.column is not None:
                loc += f":{self.column}"
        return loc

    def __str__(self) -> str:
        loc = clean(self.location(), 120)
        return clean(f"{loc}: {self.message}" if loc else self.message, MESSAGE_CHARS)


class ResourceError(BrdflabError):
    """A run would need more memory (or other resources) than the configured limit."""


class Interrupted(KeyboardInterrupt):
    """The run was stopped by a signal (SIGINT, SIGTERM or SIGHUP); the exit status is 128 + signal number."""

    def __init__(self, signum: int, message: str = "interrupted") -> None:
        super().__init__(message)
        self.signum = signum
        self.message = message


class SceneError(BrdflabError):
    """A scene description (XML) is malformed, incomplete or inconsistent."""


class MeshError(BrdflabError):
    """An OBJ mesh cannot be read or is invalid."""


class ImageError(BrdflabError):
    """An image (EXR/PNG) cannot be read or written, or images do not match."""


def first_line(exc: BaseException, n: int = 160) -> str:
    """``Type: first line of the message`` of an exception, cleaned and cut for a one-line error."""
    lines = str(exc).strip().splitlines()
    return clean(f"{type(exc).__name__}: {lines[0] if lines else ''}", n)


def code_location(exc: BaseException) -> str:
    """`` (at FILE:LINE)`` of the innermost traceback frame outside brdflab itself — a plugin's own line — or
    of a SyntaxError; empty when the error has no such frame."""
    import traceback

    def tail(name: str, n: int = 50) -> str:  # the end of a long path: its file name and line stay readable
        name = clean(name, 10_000)
        return name if len(name) <= n else "…" + name[-(n - 1):]

    if isinstance(exc, SyntaxError) and exc.filename:
        return f" (at {tail(exc.filename)}:{exc.lineno})"
    own = str(Path(__file__).resolve().parent)
    frames = [f for f in traceback.extract_tb(exc.__traceback__)
              if not str(Path(f.filename).resolve()).startswith(own) and "importlib" not in f.filename]
    if not frames:
        return ""
    f = frames[-1]
    return f" (at {tail(f.filename)}:{f.lineno})"
