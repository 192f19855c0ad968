"""One progress fraction over the phases of a long tool (analysis, advice): never decreasing, 0 to 1."""

from __future__ import annotations

from collections.abc import Callable


class Progress:
    """Reports ``lo + (hi - lo) * fraction`` to ``report`` (which may be None), never less than
    before: phases whose estimates overlap (a pass of an analysis re-rendering rows an earlier
    pass rendered) hold the bar instead of moving it back."""

    def __init__(self, report: Callable[[float], None] | None, lo: float = 0.0, hi: float = 1.0) -> None:
        self.report, self.lo, self.hi = report, float(lo), float(hi)
        self.last = self.lo

    def __call__(self, fraction: float) -> None:
        value = self.lo + (self.hi - self.lo) * min(max(float(fraction), 0.0), 1.0)
        if self.report is not None and value >= self.last:
            self.last = value
            self.report(value)

    def part(self, a: float, b: float) -> Callable[[float], None]:
        """The reporter of a phase spanning fractions ``[a, b]`` of this one."""
        return lambda fraction: self(a + (b - a) * min(max(float(fraction), 0.0), 1.0))

    def sub(self, a: float, b: float) -> Progress:
        """A :class:`Progress` over fractions ``[a, b]`` of this one (sharing its last value)."""
        inner = Progress(self, a, b)
        inner.last = a
        return inner
