"""How PETSc drives the condensed system: the SNES's KSP (a Python KSP doing one condensed
solve), the Jacobian over [u, λ] as a Python matrix, the Eisenstat–Walker forcing
terms that set a Krylov inner solve's tolerance, and when a Krylov solve rebuilds its
preconditioner.
"""
from __future__ import annotations

import math
import weakref
from typing import TYPE_CHECKING

import numpy as np
from mpi4py import MPI  # noqa: F401  (before petsc4py: the PyPI wheel needs it)
from petsc4py import PETSc

if TYPE_CHECKING:
    from .system import CondensedSystem


class Forcing:
    """Eisenstat–Walker forcing terms (their choice 2, γ = 0.9, α = (1 + √5)/2 as PETSc's
    default; α = 2 over-solved: Hertz at 2M took 8 V-cycles for a residual the next
    Newton iteration's quadratic term was 15× above, 6 with this α; with the usual
    safeguard): the inner solve's relative tolerance from the ratio of the last two
    residual norms, so that early Newton steps are solved loosely and the last ones
    tightly (quadratic convergence kept), at most ``eta_max``; never tighter than needed to
    reach a tenth of the Newton solve's ``atol`` from the current residual.

    Args:
        atol: The Newton solve's absolute tolerance (SolverSettings.atol).
    """

    gamma, alpha, eta0, eta_max, eta_min = 0.9, (1 + 5 ** 0.5) / 2, 1e-2, 1e-2, 1e-12

    def __init__(self, atol: float = 0.0):
        self.atol = atol
        self._last: tuple[float, float] | None = None

    def rtol(self, fnorm: float, iteration: int) -> float:
        """The relative tolerance of a Newton iteration's linear solve.

        Args:
            fnorm: The norm of its right-hand side (the residual).
            iteration: The Newton iteration (0: the load step's first, ``eta0``).

        Returns:
            The inner KSP's relative tolerance.
        """
        if iteration == 0 or self._last is None:
            eta = self.eta0
        else:
            f_prev, eta_prev = self._last
            eta = self.gamma * (fnorm / f_prev) ** self.alpha
            safe = self.gamma * eta_prev ** self.alpha
            if safe > 0.1:
                eta = max(eta, safe)
        floor = 0.1 * self.atol / fnorm if fnorm > 0 else self.eta_max
        eta = min(max(eta, self.eta_min, floor), self.eta_max)
        self._last = (fnorm, eta)
        return eta


class Lag:
    """When a Krylov solve rebuilds its preconditioner (an AMG set-up costs about as much as
    the iterations it saves between Newton iterations, where Kc changes little): kept while
    the solve's convergence rate, in decades per Krylov iteration, stays above ``keep`` ×
    that of the solve that built it; rebuilt after a slower or failed solve, when Kc's
    pattern grew, and (``moved``) when the constrained multipliers (:meth:`constrained`)
    differ from those of the Kc it was built on by more than that fraction of them. A
    geometric multigrid's exact coarse solve holds the body the contact holds, but not
    with a coarse operator built before the contact set took hold (Hertz at 2M dofs: 41
    V-cycles in 7 Newton iterations on the first iteration's hierarchy, 25 with it rebuilt
    at the second and fourth). GAMG's aggregates miss that mode either way: rebuilt so, it
    took as many iterations, each set-up extra (500k: 0.96 against 0.86 s a Newton
    iteration). A solve with a kept preconditioner is stopped at 1/``keep`` times the
    iterations a fresh one would take (:meth:`budget`) and done again with a fresh one: a stale
    preconditioner (a moving contact set) costs at most that. A fresh preconditioner slower
    than ``slow`` decades per iteration, or failing, makes the record :attr:`weak` (its
    solve stopped at that rate's budget): a direct solve serves better (:func:`direct_ksp`).
    The decisions read global norms only, so every rank takes the same.

    Args:
        keep: The fraction of the fresh rate below which the preconditioner is rebuilt.
        slow: The fresh rate below which the preconditioner is weak (0: never).
        moved: The fraction of the constrained multipliers (of the larger of the two sets)
            that may differ from the build's (None: they do not decide).
    """

    def __init__(self, keep: float = 0.5, slow: float = 0.1, moved: float | None = None):
        self.keep, self.slow, self.moved = keep, slow, moved
        self._built_on = self._now = np.zeros(0, dtype=np.int64)
        self._rate0 = 0.0
        self.reuse = False
        self.weak = False
        self.last_rate = math.inf

    @staticmethod
    def rate(start: float, end: float, its: int) -> float:
        """Decades of residual reduction per iteration."""
        if its <= 0 or start <= 0.0:
            return math.inf
        return math.log10(start / max(end, 1e-300)) / its

    def budget(self, rtol: float, fresh: bool) -> float:
        """Iterations allowed to a solve to ``rtol``: at ``keep`` × the fresh rate with the
        kept preconditioner, at ``slow`` with a fresh one."""
        rate = self.slow if fresh else self.keep * self._rate0
        return math.inf if rate <= 0 else int(math.ceil(math.log10(1.0 / rtol) / rate)) + 5

    def update(self, start: float, end: float, its: int, failed: bool, fresh: bool) -> None:
        """Record a solve: residual norms at its start and end, iterations, failure, and
        whether it built its preconditioner."""
        r = self.last_rate = self.rate(start, end, its)
        if fresh:
            self._rate0, self._built_on = r, self._now
        self.reuse = not failed and r >= self.keep * self._rate0
        self.weak = self.slow > 0 and fresh and (failed or r < self.slow)

    def constrained(self, multipliers: np.ndarray) -> None:
        """The multipliers the next Kc is condensed with through displacement rows (active,
        sticking; global numbers, the same on every rank).

        Args:
            multipliers: Their sorted indices.
        """
        self._now = np.asarray(multipliers, dtype=np.int64)
        if self.moved is None:
            return
        changed = np.setxor1d(self._built_on, self._now, assume_unique=True).size
        if changed > self.moved * max(self._built_on.size, self._now.size):
            self.reuse = False

    def rebuild(self) -> None:
        """The next solve builds its preconditioner anew (Kc is a new matrix)."""
        self.reuse = False


def direct_ksp(like: PETSc.KSP) -> tuple[PETSc.KSP, Lag]:
    """A direct solve of ``like``'s operator to its tolerance: GMRES preconditioned by a
    MUMPS factorization, kept while a solve converges within its budget (a factorization of
    the last Newton iteration's Kc solves this one's in a few iterations), with ``like``'s
    options prefix (MUMPS's options) and tolerances.

    Args:
        like: The KSP it replaces.

    Returns:
        The KSP and its record.
    """
    A, _ = like.getOperators()
    ksp = PETSc.KSP().create(A.getComm())
    ksp.setOptionsPrefix(like.getOptionsPrefix())
    ksp.setOperators(A)
    ksp.setType(PETSc.KSP.Type.GMRES)
    ksp.setGMRESRestart(50)
    ksp.setPCSide(PETSc.PC.Side.RIGHT)
    ksp.setNormType(PETSc.KSP.NormType.UNPRECONDITIONED)
    rtol, atol, divtol, max_it = like.getTolerances()
    ksp.setTolerances(rtol=rtol, atol=atol, divtol=divtol, max_it=max_it)
    pc = ksp.getPC()
    pc.setType(PETSc.PC.Type.LU)
    pc.setFactorSolverType("mumps")
    # kept while it gains a decade an iteration or so: a stale factorization either solves
    # in a few iterations or, after an active-set change, barely gains (sliding, 1e5 dofs)
    return ksp, Lag(keep=0.1, slow=0.0)


def solve_lagged(ksp: PETSc.KSP, lag: Lag | None, f: PETSc.Vec, y: PETSc.Vec) -> tuple[int, int]:
    """y = A⁻¹ f by ``ksp`` from a zero guess, keeping its preconditioner while ``lag``
    says it serves; a kept one stopped at its budget is replaced by a fresh one (a fresh
    one stopped at its budget leaves ``lag.weak``).

    Args:
        ksp: The KSP (its operator may have changed since its last solve).
        lag: The preconditioner's record, or None: always rebuilt when A changed.
        f: The right-hand side.
        y: The solution (overwritten).

    Returns:
        The Krylov iterations of both attempts, and the KSP's converged reason.
    """
    if lag is None:
        y.set(0.0)
        ksp.solve(f, y)
        return ksp.getIterationNumber(), ksp.getConvergedReason()
    rtol, _, _, max_it = ksp.getTolerances()
    start, its = f.norm(), 0
    for fresh in ((False, True) if lag.reuse else (True,)):
        ksp.getPC().setReusePreconditioner(not fresh)
        ksp.setTolerances(max_it=int(min(max_it, lag.budget(rtol, fresh))))
        y.set(0.0)
        ksp.solve(f, y)
        its += ksp.getIterationNumber()
        reason = ksp.getConvergedReason()
        if reason >= 0:
            break
    ksp.setTolerances(max_it=max_it)
    lag.update(start, ksp.getResidualNorm(), ksp.getIterationNumber(), reason < 0, fresh)
    return its, reason


class CondensedKSP:
    """The SNES's KSP (type python): one condensed solve (CondensedSystem.solve). The
    methods are PETSc's Python-KSP protocol.

    Args:
        system: The condensed system (held weakly: it owns the SNES).
        snes: The SNES whose KSP this is (its iteration number sets the forcing).
    """

    def __init__(self, system: CondensedSystem, snes: PETSc.SNES):
        self._system = weakref.ref(system)
        self._snes = weakref.ref(snes)

    @property
    def inner(self) -> PETSc.KSP | None:
        """The KSP on Kc (petsc_options.solver_ksp reads its failure from it)."""
        s = self._system()
        return None if s is None else s.inner

    def setUp(self, ksp) -> None:
        pass

    def reset(self, ksp) -> None:
        s = self._system()
        if s is None:
            return
        if s.inner.getPC().getType() in (PETSc.PC.Type.LU, PETSc.PC.Type.CHOLESKY):
            # a failed factorization is forgotten (newton._reset_linear_solver); KSPReset
            # drops the operators too. Not a multigrid's: reset, its levels keep the old
            # coarse sizes and its next set-up fails ("Cannot change local size of Amat")
            s.inner.reset()
            s.inner.setOperators(s.Kc)

    def solve(self, ksp, b, x) -> None:
        s, snes = self._system(), self._snes()
        it = snes.getIterationNumber() if snes is not None else 0
        its, reason = s.solve(b, x, it)
        ksp.setIterationNumber(its)
        ksp.setConvergedReason(reason if reason < 0
                               else PETSc.KSP.ConvergedReason.CONVERGED_RTOL)


class SaddleOperator:
    """The Jacobian over [u, λ] as a Python matrix (CondensedSystem.mult), for the line
    search and the tests. ``mult`` is PETSc's Python-matrix protocol.

    Args:
        system: The condensed system (held weakly).
    """

    def __init__(self, system: CondensedSystem):
        self._system = weakref.ref(system)

    def mult(self, mat, x, y) -> None:
        self._system().mult(x, y)
