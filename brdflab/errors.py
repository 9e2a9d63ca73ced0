"""User-facing errors.

Every problem caused by the user's input (scene files, meshes, images, command-line values) is raised as
:class:`BrdflabError` or a subclass. The CLI prints them as one short message and exits non-zero, with no
traceback. Anything else is a bug in brdflab.
"""

from __future__ import annotations

from pathlib import Path


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
        loc = self.location()
        return f"{loc}: {self.message}" if loc else self.message


class SceneError(BrdflabError):
    """A scene description (XML) is malformed, incomplete or inconsistent."""


class MeshError(BrdflabError):
    """An OBJ mesh cannot be read or is invalid."""


class ImageError(BrdflabError):
    """An image (EXR/PNG) cannot be read or written, or images do not match."""
