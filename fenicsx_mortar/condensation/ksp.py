"""How PETSc drives the condensed system: the SNES's KSP (a Python KSP doing one condensed
solve), the Jacobian over [u, λ] as a Python matrix, and the Eisenstat–Walker forcing
terms that set a Krylov inner solve's tolerance.
"""
from __future__ import annotations

import weakref
from typing import TYPE_CHECKING

from mpi4py import MPI  # noqa: F401  (before petsc4py: the PyPI wheel needs it)
from petsc4py import PETSc

if TYPE_CHECKING:
    from .system import CondensedSystem


class Forcing:
    """Eisenstat–Walker forcing terms (their choice 2, γ = 0.9, α = 2, with the usual
    safeguard): the inner solve's relative tolerance from the ratio of the last two
    residual norms, so that early Newton steps are solved loosely and the last ones
    tightly (quadratic convergence kept), at most ``eta_max``; never tighter than needed to
    reach a tenth of the Newton solve's ``atol`` from the current residual.

    Args:
        atol: The Newton solve's absolute tolerance (SolverSettings.atol).
    """

    gamma, alpha, eta0, eta_max, eta_min = 0.9, 2.0, 1e-2, 1e-2, 1e-12

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
