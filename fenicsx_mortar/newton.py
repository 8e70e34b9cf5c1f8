"""PETSc SNES Newton solves of the bulk residual plus the contact pairs' terms.

A Newton solve counts as converged only when the residual norm is below ``atol`` AND below
``rtol`` times the reference residual — the largest first residual of a load step seen so
far, so that a cut (small) increment does not make the relative test unreachable — (or that
reference was already below ``atol``): a huge first residual makes a relative decrease
alone meaningless (docs/design.md §5). A load step is converged when, after such a solve, no
pair asks for another one (``augment``: the ALM's KKT residual is below its tolerance, the
penalty's ε has reached its target) and the acceptance check (acceptance.py) finds the
state physical. The pairs' active sets are watched for cycles (:class:`ActiveSetMonitor`).

The SNES calls back into this object through weak references: a callback holding the
solver would make a reference cycle through the C object that the garbage collector cannot
see, and every solver would keep its communicator until the process ends (MPICH allows
2048). :meth:`NewtonSolver.close` destroys the PETSc objects at once.
"""
from __future__ import annotations

import math
import time
import weakref
from dataclasses import dataclass, field
from typing import Callable, Sequence

import numpy as np
from mpi4py import MPI  # noqa: F401  (before petsc4py: the PyPI wheel needs it, _dolfinx.py)
from petsc4py import PETSc

from . import _dolfinx as dx
from . import petsc_options as po
from .contact.assembly import reserve
from .linesearch import FullStepOrSecant
from .settings import SolverSettings
from .system import system_class
from .timings import Timings

_REASON = PETSc.SNES.ConvergedReason
_REASONS = {v: k for k, v in vars(_REASON).items() if isinstance(v, int)}
#: MUMPS's ICNTL(14) (workspace margin, per cent): its default, and how far
#: :meth:`NewtonSolver.grow_workspace` raises it
DEFAULT_WORKSPACE, MAX_WORKSPACE = 20, 160


@dataclass
class StepResult:
    """What one :meth:`NewtonSolver.solve_step` (one ``ContactProblem.solve()``) did.

    Attributes:
        converged: A converged, accepted physical state.
        iterations: Newton iterations, over all augmentations.
        residuals: Residual norms, iteration by iteration.
        augmentations: Newton solves after the first (Uzawa updates, penalty continuation).
        reason: Why it did not converge ("" if it did).
        workspace: MUMPS ran out of workspace (a larger one, not a cut, is the cure).
        stalled: Newton ran out of iterations or its line search failed (full steps may
            go through, stepping.full_newton_steps).
    """
    converged: bool
    iterations: int = 0
    residuals: list[float] = field(default_factory=list)
    augmentations: int = 0
    reason: str = ""
    workspace: bool = False
    stalled: bool = False


class ActiveSetMonitor:
    """Watches the pairs' per-node decisions over one Newton solve: a decision vector that
    reappears after a different one (period ≥ 2) while the residual has not even halved
    since its first appearance means Newton is going round in circles (a repeat with
    progress, e.g. an edge node opening and closing again on the way to the answer, is no
    cycle)."""

    def __init__(self, pairs: Sequence):
        self.pairs = pairs
        self._seen: list[list] = [[] for _ in pairs]

    def begin_solve(self) -> None:
        self._seen = [[] for _ in self.pairs]

    def cycling(self, fnorm: float) -> str | None:
        """Record the pairs' decisions of this iterate and look for a cycle.

        Args:
            fnorm: The iterate's residual norm.

        Returns:
            A description of the first cycle found, or None.
        """
        for h, seen in zip(self.pairs, self._seen):
            d = h.decision()
            if d is None:
                continue
            seen.append((d, fnorm))
            if len(seen) >= 3 and not np.array_equal(d, seen[-2][0]):
                for k, (old, r_old) in enumerate(seen[:-2]):
                    if np.array_equal(d, old) and fnorm >= 0.5 * r_old:
                        flip = np.flatnonzero(d != seen[-2][0])
                        return (f"contact {h.name}: the active/stick-slip set of iteration "
                                f"{len(seen) - 1} repeats iteration {k} (period "
                                f"{len(seen) - 1 - k}) with the residual at {fnorm:.3e} "
                                f"(was {r_old:.3e}); slave nodes {flip[:10].tolist()} flip "
                                "(a smaller load increment usually avoids it: LoadStepper "
                                "cuts the step)")
        return None


def weak_callback(method: Callable) -> Callable:
    """A plain function calling the bound ``method`` through a weak reference to its
    object. Given to a SNES, a bound method makes a cycle (solver → SNES → method →
    solver) that reference counting never frees, and petsc4py keeps callbacks where
    Python's cycle collector does not look: every solver ever made, with its SNES, matrix
    and MPI communicator, stayed (MPICH allows 2048 communicators a process).

    Args:
        method: A bound method.

    Returns:
        A function taking the method's arguments; it raises RuntimeError once the object
        is gone.
    """
    ref = weakref.WeakMethod(method)

    def call(*args):
        bound = ref()
        if bound is None:
            raise RuntimeError("called back after its solver was freed")
        return bound(*args)
    return call


def _release(snes, system, full_first, collective: bool = False) -> None:
    """Destroy a solver's PETSc objects: on ``close()`` (collective), or when its last
    reference went in a serial run. Under MPI that may have been a garbage collection on
    one rank only (rank 0's plots leave cycles), where a destroy, collective in MUMPS,
    would hang: the objects go to petsc4py's garbage, which a collective cleanup empties
    (the next solve on the communicator, PETSc's finalization)."""
    if collective or snes.comm.size == 1:
        for obj in (snes, system.A, system.b, system.x, *system.owned_objects(),
                    full_first._w, full_first._f):
            if obj is not None:
                obj.destroy()


class NewtonSolver:
    """PETSc SNES (newtonls + line search, MUMPS LU by default) on compiled residual and
    Jacobian forms of ``u`` with Dirichlet conditions ``bcs`` and contact pairs, which add
    their terms at every iterate.

    Args:
        residual: Compiled residual form F(u; v).
        jacobian: Compiled Jacobian form.
        u: The displacement Function (P1 vector).
        bcs: Dirichlet conditions.
        settings: Tolerances, line search, linear solver, extra PETSc options.
        pairs: The contact pairs.
        timings: Seconds by phase, added to.
        matrix: A Jacobian matrix with the pairs' couplings preallocated (default: the
            form's own sparsity).
        should_stop: Called at every iteration; a non-empty string stops the solve.
        prefix: PETSc options prefix of the SNES.
        petsc_options: Options set under the prefix for the set-up (normalized names).
        prolongations: A geometric multigrid's prolongations for the condensed system
            (condensation/multigrid.py), finest first.
    """

    def __init__(self, residual, jacobian, u, bcs, settings: SolverSettings,
                 pairs: Sequence, timings: Timings, matrix=None,
                 should_stop: Callable[[], str | None] = lambda: None,
                 prefix: str = "", petsc_options: dict[str, str] | None = None,
                 prolongations: Sequence = ()):
        self.should_stop = should_stop
        self.residual_form, self.jacobian_form, self.bcs = residual, jacobian, bcs
        self.settings, self.pairs, self.timings = settings, list(pairs), timings
        self.u = u
        kind = system_class(self.pairs, settings.linear_solver)
        #: the unknowns and their PETSc layout (system.py; condensation/)
        extra = {"prolongations": prolongations} if prolongations else {}
        self.system = kind(residual, jacobian, u, bcs, self.pairs, matrix, timings=timings,
                           **extra)
        self.b, self.A, self.x = self.system.b, self.system.A, self.system.x
        self.bc_dofs = self.system.bc_dofs
        self.monitor = ActiveSetMonitor(self.pairs)
        self._callback_time = 0.0
        self.history: list[float] = []
        self._r0: float | None = None
        #: the largest first residual of a load step so far (the relative test's reference)
        self._r_ref = 0.0
        self._cycle: str | None = None
        #: whether a solve may stop early for the pairs' multiplier update (update_due)
        self._inexact = False
        #: a converged state's last check (acceptance.py): a reason it is not, or None
        self.accept: Callable[[NewtonSolver], str | None] = lambda newton: None
        comm = u.function_space.mesh.comm
        self.snes = PETSc.SNES().create(comm)
        self.prefix = prefix
        self.snes.setOptionsPrefix(prefix)
        user = {**po.normalize(settings.petsc), **(petsc_options or {})}
        #: the line search in use (a full-Newton retry switches to "basic" and back to it)
        self.line_search = str(user.get("snes_linesearch_type", settings.line_search))
        self._full_first = FullStepOrSecant(
            weak_callback(self._evaluate), weak_callback(self._function_norm),
            fail=weak_callback(self._line_failed))
        self.snes.setFunction(weak_callback(self._residual), self.b)
        self.snes.setJacobian(weak_callback(self._jacobian), self.A)
        self.snes.setConvergenceTest(weak_callback(self._converged))
        self._options = po.Applied(prefix, settings, user,
                                   condensed=getattr(self.system, "condensed", False))
        self.system.configure(self.snes, self._options)
        # registered once, switched on and off (_set_precheck): PETSc ignores a NULL
        # precheck, and petsc4py's setLineSearchPreCheck(None) then leaves a dangling
        # context (a crash, seen)
        self.snes.setLineSearchPreCheck(weak_callback(self._full_first.precheck))
        self._set_precheck(self.line_search)
        self._release = weakref.finalize(self, _release, self.snes, self.system,
                                         self._full_first)
        self._release.atexit = False   # at exit PETSc's own finalization does it

    @property
    def closed(self) -> bool:
        """The PETSc objects are destroyed (:meth:`close`)."""
        return not self._release.alive

    def close(self) -> None:
        """Destroy the PETSc objects (SNES, matrices, vectors) and drop the kept options
        now, as DOLFINx 0.10's ``NonlinearProblem`` does; u keeps its values. Without it
        that happens when the last reference to the solver goes. Collective, idempotent;
        the solver cannot solve afterwards."""
        if self.closed:
            return
        _, _, args, _ = self._release.detach()
        _release(*args, collective=True)
        self._options.drop()
        self._collect_garbage()

    def _collect_garbage(self) -> None:
        """Destroy the PETSc objects Python let go of on u's communicator (a saved state, a
        reactions vector): petsc4py >= 3.18 parks them until this collective call, keyed
        by PETSc's communicator (not mpi4py's), for ever if nobody calls it."""
        PETSc.garbage_cleanup(dx.function_vector(self.u).comm)

    # -- SNES callbacks -------------------------------------------------------------
    def _function_norm(self) -> float:
        return self.snes.getFunctionNorm()

    def _line_failed(self) -> None:
        self.snes.setConvergedReason(_REASON.DIVERGED_LINE_SEARCH)

    def _set_iterate(self, x) -> None:
        self.system.push(x)
        for p in self.pairs:
            p.update(self.u)

    def _timed_bulk(self, assemble: Callable[[], None]) -> None:
        """Run an assembly; bulk_assembly gets its time less the contact part inside it."""
        c0 = self.timings.get("contact", 0.0)
        t0 = time.perf_counter()
        assemble()
        dt = time.perf_counter() - t0
        self.timings["bulk_assembly"] = (self.timings.get("bulk_assembly", 0.0) + dt
                                         - (self.timings.get("contact", 0.0) - c0))

    def _residual(self, snes, x, b) -> None:
        if self._full_first.take(x, b):  # the line search's full step, evaluated already
            return
        self._evaluate(x, b)

    def evaluate_residual(self, x: PETSc.Vec, b: PETSc.Vec) -> None:
        """b = F(x), bulk and contact (the state moves to x).

        Args:
            x: The unknowns (the system's layout).
            b: The residual, overwritten.
        """
        self._evaluate(x, b)

    def _evaluate(self, x, b) -> None:
        t0 = time.perf_counter()
        self._set_iterate(x)
        self._timed_bulk(lambda: self.system.assemble_residual(
            x, b, self._add_pair_residuals if self.pairs else None))
        self._callback_time += time.perf_counter() - t0

    def _add_pair_residuals(self, b) -> None:
        with self.timings("contact"):
            for p in self.pairs:
                p.add_residual(b, self.bc_dofs)

    def evaluate_jacobian(self, x: PETSc.Vec, A: PETSc.Mat) -> None:
        """A = dF/dx at the state of the last residual evaluation (that at x).

        Args:
            x: The unknowns of the last :meth:`evaluate_residual`.
            A: The Jacobian matrix, overwritten.
        """
        self._jacobian(None, x, A, A)

    def _jacobian(self, snes, x, A, P) -> None:
        t0 = time.perf_counter()
        add = None
        if self.pairs and not getattr(self.system, "condensed", False):  # (it takes them itself)
            # the tangents first: new couplings (sliding) grow A once, before the assembly
            with self.timings("contact"):
                tangents = [p.tangent() for p in self.pairs]
                slots = [p.new_slots(K) for p, K in zip(self.pairs, tangents)]
                if A.assembled and reserve(A, np.concatenate([r for r, _ in slots]),
                                           np.concatenate([c for _, c in slots])):
                    # a factorization of the old pattern must not be refactored in place
                    # (MUMPS through PETSc 3.22 under MPI corrupted its memory)
                    self._reset_linear_solver()

            def add(A):
                with self.timings("contact"):
                    for p, K in zip(self.pairs, tangents):
                        p.insert_tangent(A, K)
        self._timed_bulk(lambda: self.system.assemble_jacobian(A, add))
        self._callback_time += time.perf_counter() - t0

    def _converged(self, snes, it, norms):
        fnorm = norms[2]
        if self._r0 is None:  # first residual of the load step (not of each augmentation)
            # a cut increment starts with a small residual: keep the largest step start seen
            self._r_ref = max(self._r_ref, fnorm)
            self._r0 = self._r_ref
        self.history.append(float(fnorm))
        s = self.settings
        if not math.isfinite(fnorm):
            return dx.SNES_DIVERGED_NAN
        if self.should_stop():
            return _REASON.DIVERGED_INNER  # petsc4py has no DIVERGED_USER
        small = fnorm <= s.atol and (fnorm <= s.rtol * self._r0 or self._r0 <= s.atol)
        if small:
            return _REASON.CONVERGED_FNORM_ABS
        # cycling guard: an active set (or stick/slip state) that comes back is a loop Newton
        # will not leave; stop now and let the step be cut, saying which nodes flip
        self._cycle = self.monitor.cycling(fnorm)
        if self._cycle:
            return _REASON.DIVERGED_INNER
        if it > 0 and self._inexact and any(
                [p.update_due(fnorm, self.history[0]) for p in self.pairs]):
            # inexact Uzawa (enforcement.update_due): not the rule's reason, so the
            # acceptance check never takes this state for a converged one
            return _REASON.CONVERGED_FNORM_RELATIVE
        if it >= s.max_iterations:
            return _REASON.DIVERGED_MAX_IT
        return _REASON.ITERATING

    # -- one load step ----------------------------------------------------------------
    def begin_step(self) -> None:
        """A new load step (or a new attempt at one): its first residual is the relative
        test's new reference candidate."""
        self._r0 = None

    def solve_step(self, max_augmentations: int = 50) -> StepResult:
        """Newton solves (one per augmentation) from the current state at the current load,
        ended by the acceptance check :attr:`accept`.

        Args:
            max_augmentations: Newton solves after the first.

        Returns:
            What happened (the state is left where the solves ended).
        """
        if self.closed:
            raise RuntimeError("NewtonSolver: closed (its PETSc objects are destroyed); "
                               "make a new one")
        self._collect_garbage()
        res = StepResult(converged=False)
        self.begin_step()
        self._inexact = True
        for aug in range(max_augmentations + 1):
            self.history = []
            self._cycle = None
            self.monitor.begin_solve()
            self._full_first.forget()
            self._callback_time = 0.0
            t0 = time.perf_counter()
            try:
                self.snes.solve(None, self.x)
            except PETSc.Error as e:  # a failed factorization, say: the step fails
                res.reason = po.petsc_failure(self.snes, e)
                res.workspace = po.out_of_workspace(self.snes)
                self._reset_linear_solver()
                return res
            self.timings["linear_solve"] = (self.timings.get("linear_solve", 0.0)
                                            + time.perf_counter() - t0 - self._callback_time)
            reason = self.snes.getConvergedReason()
            res.iterations += self.snes.getIterationNumber()
            res.residuals.extend(self.history)
            if reason <= 0 and self._cycle:
                res.reason = f"Newton stopped by the cycling guard after " \
                             f"{self.snes.getIterationNumber()} iterations: {self._cycle}"
                return res
            if reason <= 0:
                res.reason = f"Newton failed: {_REASONS.get(reason, reason)} after " \
                             f"{self.snes.getIterationNumber()} iterations, residuals " \
                             + ", ".join(f"{r:.3e}" for r in self.history)
                res.stalled = reason in (_REASON.DIVERGED_MAX_IT, _REASON.DIVERGED_LINE_SEARCH)
                if reason == _REASON.DIVERGED_LINEAR_SOLVE:
                    res.reason += "; " + po.linear_failure(self.snes)
                    res.workspace = po.out_of_workspace(self.snes)
                    self._reset_linear_solver()
                return res
            self._set_iterate(self.x)
            if not any([p.augment() for p in self.pairs]):
                if not self.converged_by_rule():
                    # an inexact solve whose state turned out to hold the KKT conditions:
                    # the step ends only after a converged one
                    self._inexact = False
                    continue
                res.reason = self.accept(self) or ""
                res.converged, res.augmentations = not res.reason, aug
                return res
        res.reason = f"augmented Lagrangian: KKT not reached in {max_augmentations} augmentations"
        return res

    def converged_by_rule(self) -> bool:
        """The last SNES solve stopped because the convergence rule said so."""
        return self.snes.getConvergedReason() == _REASON.CONVERGED_FNORM_ABS

    def grow_workspace(self) -> int | None:
        """After MUMPS ran out of workspace (INFOG(1) = −8, −9, …): double ICNTL(14), its
        workspace margin in per cent, for the next factorization (the KSP is reset);
        None when it is at MAX_WORKSPACE already."""
        key = "mat_mumps_icntl_14"
        now = PETSc.Options().getInt(self.prefix + key, DEFAULT_WORKSPACE)
        if now >= MAX_WORKSPACE:
            return None
        new = min(2 * max(now, 10), MAX_WORKSPACE)
        self._options.set_factor_option(key, new)
        self._reset_linear_solver()
        return new

    def _reset_linear_solver(self) -> None:
        """Forget the factorization after a failed one: PETSc would otherwise go on with
        MUMPS's failed instance, and every later attempt (a cut step's) fails at once with
        INFOG(1) = -3 (B3 with a finer master: a singular iterate at t = 1.6 ended the run
        after 8 cuts that never factorized)."""
        self.snes.getKSP().reset()

    def set_line_search(self, kind: str) -> None:
        """Switch SNES's line search (through the options database, as petsc4py before 3.24
        has no line-search object; dropped again once applied).

        Args:
            kind: One of :data:`~.settings.LINE_SEARCHES`.
        """
        opts = PETSc.Options()
        keys = {self.prefix + k: v for k, v in po.line_search_options(kind).items()}
        before = {k: opts.getString(k) for k in keys if opts.hasName(k)}
        for k, v in keys.items():
            opts[k] = v
        self.snes.setFromOptions()
        for k in keys:
            if k in before:
                opts[k] = before[k]
            else:
                opts.delValue(k)
        self._set_precheck(kind)

    def _set_precheck(self, kind: str) -> None:
        self._full_first.enabled = kind == "l2-full"
        self._full_first.forget()

    def save_state(self) -> PETSc.Vec:
        """A copy of the unknowns (for :meth:`restore_state`)."""
        return self.x.copy()

    def restore_state(self, saved: PETSc.Vec) -> None:
        """Back to saved unknowns; the pairs' states follow.

        Args:
            saved: From :meth:`save_state`.
        """
        saved.copy(self.x)
        self._set_iterate(self.x)

    def unconstrained_residual(self) -> PETSc.Vec:
        """F(u) without Dirichlet modification (contact included): reactions live here."""
        b = self.system.unconstrained()
        dx.assemble_unconstrained_residual(b, self.residual_form)
        for p in self.pairs:
            p.add_residual(b, np.zeros(0, dtype=np.int32))
        return b
