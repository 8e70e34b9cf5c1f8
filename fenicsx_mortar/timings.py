"""Wall-clock seconds by phase (bulk assembly, contact, linear solve, output ...)."""
from __future__ import annotations

import time


class Timings(dict):
    """Seconds by phase; ``with timings("phase"):`` adds the block's time to it."""

    def __call__(self, phase: str) -> "_Phase":
        return _Phase(self, phase)


class _Phase:
    def __init__(self, timings: Timings, phase: str):
        self.timings, self.phase = timings, phase

    def __enter__(self) -> "_Phase":
        self.t0 = time.perf_counter()
        return self

    def __exit__(self, *exc) -> None:
        t = self.timings
        t[self.phase] = t.get(self.phase, 0.0) + time.perf_counter() - self.t0
