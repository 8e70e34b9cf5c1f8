"""The line search ``"l2-full"``: Newton's full step whenever it reduces the residual norm
enough, PETSc's ``l2`` secant step otherwise (docs/newton_cost.md, "What made the difference").

PETSc's ``l2`` evaluates F three times per Newton iteration (at λ = 1/2 and 1, then at the
secant minimizer λ* of ‖F(x − λy)‖²), also in the quadratic tail, where λ* ≈ 1. Here the
full step is tried first and kept when ‖F(x − y)‖ < θ ‖F(x)‖: one evaluation, which
SNES's ``basic`` line search then takes from the cache instead of assembling again.
Otherwise the step is l2's, from the same three points and the same formula, so away from
the tail the iterates are l2's.
"""
from __future__ import annotations

import math
from typing import Callable

from mpi4py import MPI  # noqa: F401  (before petsc4py: the PyPI wheel needs it)
from petsc4py import PETSc

#: the full step is kept when it divides the residual norm by 4 at least (with 2: Hertz
#: a/20 takes one iteration more, B3 and B4 two and nine)
ACCEPT = 0.25
#: smallest and largest step lengths (PETSc's defaults for l2)
STEPTOL, MAXSTEP = 1e-12, 1e8


class FullStepOrSecant:
    """A precheck for SNES's ``basic`` line search. ``evaluate(w, f)`` assembles F(w) into
    f (and leaves the problem's state at w); ``fnorm()`` is ‖F(x)‖ at the current iterate;
    ``fail()`` tells SNES the line search failed (as l2's FAILED_REDUCT: no step length
    down to STEPTOL gives a finite F)."""

    def __init__(self, evaluate: Callable[[PETSc.Vec, PETSc.Vec], None],
                 fnorm: Callable[[], float], accept: float = ACCEPT,
                 fail: Callable[[], None] = lambda: None):
        self.evaluate, self.fnorm, self.accept, self.fail = evaluate, fnorm, accept, fail
        #: off: the step is left as it is (SNES's line search alone decides)
        self.enabled = True
        self._w = self._f = None
        self._cached = False

    def _norm_at(self, x: PETSc.Vec, y: PETSc.Vec, lam: float) -> float:
        self._w.waxpy(-lam, y, x)
        self.evaluate(self._w, self._f)
        return self._f.norm()

    def precheck(self, x: PETSc.Vec, y: PETSc.Vec) -> bool:
        """Scale the Newton step y (x_new = x − y) in place; True when it was changed."""
        self._cached = False
        if not self.enabled:
            return False
        if self._w is None:
            self._w, self._f = x.duplicate(), x.duplicate()
        f0 = self.fnorm()
        lam = 1.0
        f1 = self._norm_at(x, y, lam)
        if math.isfinite(f1) and f1 < self.accept * f0:
            self._cached = True  # basic evaluates F at exactly this w next
            return False
        maxstep = MAXSTEP
        while not math.isfinite(f1):  # as l2: halve until F is defined, never step back there
            maxstep = 0.95 * lam
            lam *= 0.5
            if lam <= STEPTOL:
                y.scale(lam)
                self.fail()
                return True
            f1 = self._norm_at(x, y, lam)
        fmid = self._norm_at(x, y, 0.5 * lam)
        # l2 with one secant iteration, on ‖F‖², from λ = 0, λ/2, λ (petsc linesearchl2.c)
        g0, gm, g1 = f0 * f0, fmid * fmid, f1 * f1
        d1 = (3.0 * g1 - 4.0 * gm + g0) / lam
        d0 = (-3.0 * g0 + 4.0 * gm - g1) / lam
        d2 = (d1 - d0) / lam
        new = lam
        if d2 > 0.0:
            new = lam - d1 / d2
        elif d2 < 0.0:
            new = lam + d1 / d2
        if new < STEPTOL:
            new = 0.5 * lam
        if not math.isfinite(new) or new > maxstep:
            new = lam
        y.scale(new)
        return True

    def forget(self) -> None:
        """Drop the cached F (a new solve, another line search: it may not be asked for)."""
        self._cached = False

    def take(self, x: PETSc.Vec, f: PETSc.Vec) -> bool:
        """F(x) from the precheck's full-step evaluation if x is that point (then True)."""
        if not self._cached:
            return False
        self._cached = False
        if not x.equal(self._w):
            return False
        self._f.copy(f)
        return True
