"""The command line's one-line error and its warnings (stderr)."""

from __future__ import annotations

import sys


class CliError(Exception):
    """A one-line error for the user."""


def warn(message: str) -> None:
    print(f"warning: {message}", file=sys.stderr)
