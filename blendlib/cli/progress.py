"""A progress bar on the terminal for long CLI work (frames, large renders), from tqdm.

Drawn on stderr only when stderr is a terminal: pipes, logs and farm managers see nothing
of it. Without tqdm installed the work runs without a bar.
"""

from __future__ import annotations

import sys
from typing import Any

BAR_FORMAT = "{desc}{percentage:3.0f}%|{bar}| {n:.1f}/{total:g} {unit} [{elapsed}<{remaining}]"


class Progress:
    """``set(value)`` moves the bar to ``value`` of ``total``; ``write(line)`` prints a stdout line
    without breaking the bar; ``close()`` removes it. A no-op when disabled."""

    def __init__(self, total: float, unit: str, description: str = "", enabled: bool | None = None):
        if enabled is None:
            enabled = bool(getattr(sys.stderr, "isatty", lambda: False)())
        self._bar: Any = None
        if enabled:
            try:
                from tqdm import tqdm
            except ImportError:
                return
            self._bar = tqdm(total=total, unit=unit, desc=description or None, file=sys.stderr, leave=False,
                             dynamic_ncols=True, bar_format=BAR_FORMAT)

    @property
    def enabled(self) -> bool:
        return self._bar is not None

    def set(self, value: float) -> None:
        if self._bar is not None:
            self._bar.n = value
            self._bar.refresh()

    def write(self, line: str) -> None:
        if self._bar is not None:
            self._bar.write(line, file=sys.stdout)
        else:
            print(line, flush=True)

    def close(self) -> None:
        if self._bar is not None:
            self._bar.close()
            self._bar = None

    def __enter__(self) -> Progress:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
