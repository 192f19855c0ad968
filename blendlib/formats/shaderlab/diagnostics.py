"""What the importer tells the user: one positioned error, or warnings with their positions.

Every module of the package reports through these two: :class:`ShaderLabError` stops the import
(nothing is returned), a :class:`SourceWarning` is collected and the import goes on. Both carry
the 1-based line and column of the text they are about.
"""

from __future__ import annotations

from typing import NamedTuple, Protocol

#: A warning with the same text (position aside) is listed this often, then summed up as "and N more".
MAX_REPEATED_WARNINGS = 10


#: A word longer than this is shortened in messages (a 10 MB bad token made a 10 MB error line).
MAX_WORD = 60


def shortened(message: str) -> str:
    """``message`` on one line, each word longer than :data:`MAX_WORD` cut to its start, "…" and
    its length."""
    return " ".join(w if len(w) <= MAX_WORD else f"{w[:MAX_WORD - 20]}…({len(w)} characters)"
                    for w in str(message).split())


class ShaderLabError(ValueError):
    """A ShaderLab parse error at a position; ``str()`` is one line ``FILE:LINE:COL: message``."""

    def __init__(self, message: str, line: int, column: int, filename: str = "<string>") -> None:
        self.message = shortened(message)
        self.line = int(line)
        self.column = int(column)
        self.filename = filename
        super().__init__(str(self))

    def __str__(self) -> str:
        return f"{self.filename}:{self.line}:{self.column}: {self.message}"


class Positioned(Protocol):
    """Anything with a 1-based ``line`` and ``column`` (a token)."""

    line: int
    column: int


class SourceWarning(NamedTuple):
    """A warning about the text at ``line``:``column``; ``str()`` is ``LINE:COL: message``."""

    line: int
    column: int
    message: str

    @classmethod
    def at(cls, where: Positioned, message: str) -> SourceWarning:
        return cls(where.line, where.column, shortened(message))

    def __str__(self) -> str:
        return f"{self.line}:{self.column}: {self.message}"


class WarningList(list):
    """Warnings ``"LINE:COL: message"``; a message repeated more than :data:`MAX_REPEATED_WARNINGS` times
    is listed that often, then one line at the first left-out position says how many more there are."""

    def __init__(self) -> None:
        super().__init__()
        self._counts: dict[str, int] = {}
        self._summary: dict[str, tuple[int, str]] = {}  # message -> (index of its summary line, position)

    def append(self, text: str) -> None:
        position, _, message = text.partition(": ")
        n = self._counts[message] = self._counts.get(message, 0) + 1
        if n <= MAX_REPEATED_WARNINGS:
            super().append(text)
            return
        if n == MAX_REPEATED_WARNINGS + 1:
            self._summary[message] = (len(self), position)
            super().append("")
        index, first = self._summary[message]
        self[index] = f"{first}: {message} (and {n - MAX_REPEATED_WARNINGS - 1} more like this left out)" \
            if n > MAX_REPEATED_WARNINGS + 1 else f"{first}: {message}"
