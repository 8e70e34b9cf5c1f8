"""PETSc SNES Newton driver with load stepping, step cutting and contact hooks.

A Newton solve counts as converged only when the residual norm is below ``atol`` AND below
``rtol`` times the reference residual — the largest first residual of a load step seen so
far, so that a cut (small) increment does not make the relative test unreachable — (or that
reference was already below ``atol``): a huge first residual makes a relative decrease
alone meaningless (docs/design.md §5). A load step is converged when, after such a solve, no
hook asks for another one (``augment``: the ALM's KKT residual is below its tolerance,
the penalty's ε has reached its target). The active sets are watched for cycles
(:class:`ActiveSetMonitor`).
"""
from __future__ import annotations

import math
import time
import weakref
from dataclasses import dataclass, field
from typing import Callable, Protocol

import numpy as np
from mpi4py import MPI  # noqa: F401  (before petsc4py: the PyPI wheel needs it, _dolfinx.py)
from petsc4py import PETSc

from . import _dolfinx as dx
from . import guards
from .linesearch import FullStepOrSecant
from .scene import SolverSettings, Steps
from .system import DisplacementSystem, MultiplierSystem


class Hook(Protocol):
    """What a contact pair plugs into the Newton loop (all methods collective)."""

    def update(self, u) -> None: ...              # new iterate: kinematics, active set
    def add_residual(self, b, bc_dofs) -> None: ...
    def add_jacobian(self, A, bc_dofs) -> None: ...
    def decision(self) -> np.ndarray | None: ...  # per-node active / stick-slip decision
    def augment(self) -> bool: ...                # between Newton solves; True → solve again
    def begin_step(self) -> None: ...
    def accept_step(self) -> None: ...
    def reject_step(self) -> None: ...
    def record(self) -> dict: ...
    name: str
    path_dependent: bool                          # history (friction): the path matters
    unknowns: int                                 # own unknowns per slave node (multipliers)


class ActiveSetMonitor:
    """Watches the hooks' per-node decisions over one Newton solve: a decision vector that
    reappears after a different one (period ≥ 2) while the residual has not even halved
    since its first appearance means Newton is going round in circles (a repeat with
    progress, e.g. an edge node opening and closing again on the way to the answer, is no
    cycle)."""

    def __init__(self, hooks):
        self.hooks = hooks
        self._seen: list[list] = [[] for _ in hooks]

    def begin_solve(self) -> None:
        self._seen = [[] for _ in self.hooks]

    def cycling(self, fnorm: float) -> str | None:
        """A description of the first cycle found, or None."""
        for h, seen in zip(self.hooks, self._seen):
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
                                f"(was {r_old:.3e}); slave nodes {flip[:10].tolist()} flip")
        return None


class Timings(dict):
    """Seconds by phase; ``with timings('phase'):`` adds to it."""

    def __call__(self, phase: str):
        timings = self

        class _T:
            def __enter__(self):
                self.t0 = time.perf_counter()

            def __exit__(self, *exc):
                timings[phase] = timings.get(phase, 0.0) + time.perf_counter() - self.t0
        return _T()


@dataclass
class StepResult:
    converged: bool
    iterations: int = 0
    residuals: list[float] = field(default_factory=list)
    augmentations: int = 0
    reason: str = ""
    #: the factorization ran out of workspace (MUMPS): a larger one, not a cut, is the cure
    workspace: bool = False


_REASONS = {v: k for k, v in vars(PETSc.SNES.ConvergedReason).items() if isinstance(v, int)}


class NewtonSolver:
    """PETSc SNES (newtonls + line search, LU by default) on a residual and Jacobian form
    (compiled) of ``u``, with Dirichlet conditions ``bcs`` and hooks (contact pairs) that
    add their terms at every iterate. ``matrix``: a Jacobian matrix with the hooks'
    couplings preallocated (default: the form's own sparsity).

    The SNES calls back through weak references (:func:`weak_callback`), so the solver
    and its PETSc objects go as soon as the last reference does; :meth:`close` (or a
    ``with`` block) destroys them at once."""

    def __init__(self, residual, jacobian, u, bcs, settings: SolverSettings, hooks: list[Hook],
                 timings: Timings, matrix=None,
                 should_stop: Callable[[], str | None] = lambda: None,
                 prefix: str | None = None):
        self.should_stop = should_stop
        self.residual_form, self.jacobian_form, self.bcs = residual, jacobian, bcs
        self.settings, self.hooks, self.timings = settings, hooks, timings
        self.u = u
        kind = MultiplierSystem if any(h.unknowns for h in hooks) else DisplacementSystem
        #: the unknowns and their PETSc layout (system.py)
        self.system = kind(residual, jacobian, u, bcs, hooks, matrix)
        self.b, self.A, self.x = self.system.b, self.system.A, self.system.x
        self.bc_dofs = self.system.bc_dofs
        self.monitor = ActiveSetMonitor(hooks)
        self._callback_time = 0.0
        self.history: list[float] = []
        self._r0 = None
        self._r_ref = 0.0
        self._cycle = None
        #: a converged step's last check (guards.StepGuard): a reason it is not, or None
        self.check_solution: Callable[[], str | None] = lambda: None
        comm = u.function_space.mesh.comm
        self.snes = PETSc.SNES().create(comm)
        self._prefix = prefix = prefix or f"fm{id(self)}_"
        self.snes.setOptionsPrefix(prefix)
        user = {k.lstrip("-"): v for k, v in settings.petsc.items()}
        #: the line search in use (a full-Newton retry switches to "basic" and back to it)
        self.line_search = str(user.get("snes_linesearch_type", settings.line_search))
        snes = self.snes
        self._full_first = FullStepOrSecant(
            weak_callback(self._evaluate), snes.getFunctionNorm,
            fail=lambda: snes.setConvergedReason(
                PETSc.SNES.ConvergedReason.DIVERGED_LINE_SEARCH))
        options = {"snes_type": "newtonls", **_line_search_options(settings.line_search),
                   "snes_max_it": settings.max_iterations, "snes_max_funcs": 100000}
        options.update(_linear_solver_options(settings.linear_solver))
        options.update({k: "" if v is True else ("false" if v is False else v)
                        for k, v in user.items()})
        opts = PETSc.Options()
        for k, v in options.items():
            opts[prefix + k] = v
        self.snes.setFunction(weak_callback(self._residual), self.b)
        self.snes.setJacobian(weak_callback(self._jacobian), self.A)
        self.snes.setConvergenceTest(weak_callback(self._converged))
        self.snes.setFromOptions()
        self.snes.getKSP().setFromOptions()
        # registered once, switched on and off (_set_precheck): PETSc ignores a NULL
        # precheck, and petsc4py's setLineSearchPreCheck(None) then leaves a dangling
        # context (a crash, seen)
        self.snes.setLineSearchPreCheck(weak_callback(self._full_first.precheck))
        self._set_precheck(self.line_search)
        # PETSc's options database is global and holds at most 512 entries: drop ours once
        # applied, or a process that builds many solvers (a study, a test session) runs out.
        # MUMPS reads its options at each new factorization (the first, and after a reset):
        # those stay while the solver lives
        self._factor_options = [prefix + k for k in options if k.startswith(FACTOR_OPTIONS)]
        for k in options:
            if prefix + k not in self._factor_options:
                opts.delValue(prefix + k)
        self._token = object()
        for k in self._factor_options:
            _OWNER[k] = self._token
        # (grow_workspace adds to the option list; the finalizer sees it)
        self._release = weakref.finalize(self, _release, self.snes, self.system,
                                         self._full_first, self._factor_options, self._token)
        self._release.atexit = False   # at exit PETSc's own finalization does it, as before

    @property
    def closed(self) -> bool:
        return not self._release.alive

    def close(self) -> None:
        """Destroy the PETSc objects (SNES, matrices, vectors) and drop the solver's
        options now, as DOLFINx 0.10's ``NonlinearProblem`` does; u keeps its values.
        Without it that happens when the last reference to the solver goes. Collective,
        idempotent; the solver cannot solve afterwards."""
        if self.closed:
            return
        _, _, args, _ = self._release.detach()
        _release(*args, collective=True)
        self._collect_garbage()

    def _collect_garbage(self) -> None:
        """Destroy the PETSc objects Python let go of on u's communicator (a saved state, a
        reactions vector): petsc4py >= 3.18 parks them until this collective call, with
        PETSc's communicator as the key (not mpi4py's), for ever if nobody calls it."""
        PETSc.garbage_cleanup(dx.function_vector(self.u).comm)

    def __enter__(self) -> "NewtonSolver":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    # -- SNES callbacks -------------------------------------------------------------
    def _set_iterate(self, x) -> None:
        self.system.push(x)
        for h in self.hooks:
            h.update(self.u)

    def _timed_bulk(self, assemble) -> None:
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

    def _evaluate(self, x, b) -> None:
        t0 = time.perf_counter()
        self._set_iterate(x)
        self._timed_bulk(lambda: self.system.assemble_residual(
            x, b, self._add_hook_residuals if self.hooks else None))
        self._callback_time += time.perf_counter() - t0

    def _add_hook_residuals(self, b) -> None:
        with self.timings("contact"):
            for h in self.hooks:
                h.add_residual(b, self.bc_dofs)

    def _jacobian(self, snes, x, A, P) -> None:
        t0 = time.perf_counter()
        self._timed_bulk(lambda: self.system.assemble_jacobian(
            A, self._add_hook_jacobians if self.hooks else None))
        self._callback_time += time.perf_counter() - t0

    def _add_hook_jacobians(self, A) -> None:
        with self.timings("contact"):
            for h in self.hooks:
                h.add_jacobian(A, self.bc_dofs)

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
            return PETSc.SNES.ConvergedReason.DIVERGED_INNER  # no DIVERGED_USER in petsc4py 3.18
        small = fnorm <= s.atol and (fnorm <= s.rtol * self._r0 or self._r0 <= s.atol)
        if small:
            return PETSc.SNES.ConvergedReason.CONVERGED_FNORM_ABS
        # cycling guard: an active set (or stick/slip state) that comes back is a loop Newton
        # will not leave; stop now and let the step be cut, saying which nodes flip
        self._cycle = self.monitor.cycling(fnorm)
        if self._cycle:
            return PETSc.SNES.ConvergedReason.DIVERGED_INNER
        if it >= s.max_iterations:
            return PETSc.SNES.ConvergedReason.DIVERGED_MAX_IT
        return PETSc.SNES.ConvergedReason.ITERATING

    # -- one load step ----------------------------------------------------------------
    def solve_step(self, max_augmentations: int = 50) -> StepResult:
        """Newton solves (one per augmentation) from the current state at the current load."""
        if self.closed:
            raise RuntimeError("NewtonSolver: closed (its PETSc objects are destroyed); "
                               "make a new one")
        self._collect_garbage()
        res = StepResult(converged=False)
        self._r0 = None
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
                res.reason = guards.petsc_failure(self.snes, e)
                res.workspace = guards.out_of_workspace(self.snes)
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
                if reason == PETSc.SNES.ConvergedReason.DIVERGED_LINEAR_SOLVE:
                    res.reason += "; " + guards.linear_failure(self.snes)
                    res.workspace = guards.out_of_workspace(self.snes)
                    self._reset_linear_solver()
                return res
            self._set_iterate(self.x)
            if not any([h.augment() for h in self.hooks]):
                res.reason = self.check_solution() or ""
                res.converged, res.augmentations = not res.reason, aug
                return res
        res.reason = f"augmented Lagrangian: KKT not reached in {max_augmentations} augmentations"
        return res

    def grow_workspace(self) -> int | None:
        """After MUMPS ran out of workspace (INFOG(1) = −8, −9, …): double ICNTL(14), its
        workspace margin in per cent, for the next factorization (the KSP is reset);
        None when it is at MAX_WORKSPACE already."""
        key = self._prefix + "mat_mumps_icntl_14"
        opts = PETSc.Options()
        now = opts.getInt(key, DEFAULT_WORKSPACE)
        if now >= MAX_WORKSPACE:
            return None
        opts[key] = new = min(2 * max(now, 10), MAX_WORKSPACE)
        _OWNER[key] = self._token
        if key not in self._factor_options:
            self._factor_options.append(key)
        self._reset_linear_solver()
        return new

    def _reset_linear_solver(self) -> None:
        """Forget the factorization after a failed one: PETSc would otherwise go on with
        MUMPS's failed instance, and every later attempt (a cut step's) fails at once with
        INFOG(1) = -3 (B3 with a finer master: a singular iterate at t = 1.6 ended the run
        after 8 cuts that never factorized)."""
        self.snes.getKSP().reset()

    def set_line_search(self, kind: str) -> None:
        """Switch SNES's line search (petsc4py 3.18 has no line-search object: through the
        options database, dropped again once applied)."""
        opts = PETSc.Options()
        keys = _line_search_options(kind)
        for k, v in keys.items():
            opts[self._prefix + k] = v
        self.snes.setFromOptions()
        for k in keys:
            opts.delValue(self._prefix + k)
        self._set_precheck(kind)

    def _set_precheck(self, kind: str) -> None:
        self._full_first.enabled = kind == "l2-full"
        self._full_first.forget()

    def save_state(self) -> PETSc.Vec:
        return self.x.copy()

    def restore_state(self, saved: PETSc.Vec) -> None:
        saved.copy(self.x)
        self._set_iterate(self.x)

    def unconstrained_residual(self) -> PETSc.Vec:
        """F(u) without Dirichlet modification (contact included): reactions live here."""
        b = self.system.unconstrained()
        dx.assemble_unconstrained_residual(b, self.residual_form)
        for h in self.hooks:
            h.add_residual(b, np.zeros(0, dtype=np.int32))
        return b


#: options read at a factorization, not at set-up: kept in the database (see __init__)
FACTOR_OPTIONS = ("mat_mumps_",)
#: MUMPS's ICNTL(14) (workspace margin, per cent): its default, and how far
#: :meth:`NewtonSolver.grow_workspace` raises it
DEFAULT_WORKSPACE, MAX_WORKSPACE = 20, 160


#: which live solver set a kept option last: two solvers under one user prefix share
#: the keys, and a dead one must not take the live one's options with it
_OWNER: dict[str, object] = {}


def _release(snes, system, full_first, keys: list[str], token: object,
             collective: bool = False) -> None:
    """Drop a solver's options and destroy its PETSc objects: on ``close()`` (collective),
    or when its last reference went in a serial run. Under MPI that may have been a garbage
    collection on one rank only (rank 0's plots leave cycles), where a destroy, collective
    in MUMPS, would hang: the objects go to petsc4py's garbage, which a collective cleanup
    empties (the next solve on the communicator, PETSc's finalization). Left to petsc4py
    in serial too, they would wait there with their MUMPS communicators."""
    if collective or snes.comm.size == 1:
        for obj in (snes, system.A, system.b, system.x, getattr(system, "b_u", None),
                    getattr(system, "_lgmap", None), full_first._w, full_first._f):
            if obj is not None:
                obj.destroy()
    _drop_options(keys, token)


def _drop_options(keys: list[str], token: object) -> None:
    opts = PETSc.Options()
    for k in keys:
        if _OWNER.get(k) is token:
            opts.delValue(k)
            del _OWNER[k]


def _petsc_line_search(kind: str) -> str:
    """PETSc's line-search type for ours: ``l2-full`` is ``basic`` with a precheck; ``l2``
    is PETSc's secant search, whatever this PETSc calls it."""
    return "basic" if kind == "l2-full" else (dx.LINE_SEARCH_SECANT if kind == "l2" else kind)


def _line_search_options(kind: str) -> dict:
    """PETSc options of our line search ``kind``."""
    petsc = _petsc_line_search(kind)
    return {"snes_linesearch_type": petsc,
            **(dx.LINE_SEARCH_SECANT_OPTIONS if petsc == dx.LINE_SEARCH_SECANT else {})}


def weak_callback(method: Callable) -> Callable:
    """A plain function calling the bound ``method`` through a weak reference to its
    object. Given to a SNES, a bound method makes a cycle (solver → SNES → method →
    solver) that refcounting never frees, and petsc4py keeps callbacks where Python's
    cycle collector does not look: every solver ever made, with its SNES, matrix and MPI
    communicator, stayed (MPICH allows 2048 communicators a process).

    Args:
        method: a bound method.

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


def _linear_solver_options(name: str) -> dict:
    if name == "gmres-hypre":
        return {"ksp_type": "gmres", "pc_type": "hypre", "ksp_rtol": 1e-12}
    return {"ksp_type": "preonly", "pc_type": "lu", "pc_factor_mat_solver_type": name}


def run_load_steps(solver: NewtonSolver, steps: Steps, set_time: Callable[[float], None],
                   on_step: Callable[[int, float, StepResult, int], None],
                   on_progress: Callable[[str], None] = lambda s: None,
                   max_augmentations: int = 50, t_start: float = 0.0, k_start: int = 0,
                   should_stop: Callable[[], str | None] = lambda: None) -> tuple[bool, str]:
    """Advance pseudo-time through ``steps`` from ``t_start`` (``set_time(t)`` scales the
    loads and prescribed displacements to pseudo-time t); halve a failed increment, at
    most ``max_cuts`` times in a row and not below the floor, and double it again after each
    converged step (never past the next target). A failed increment is tried once more with
    full Newton steps (no line search) before it is cut; with path-dependent hooks
    (friction) only when it cannot be cut any more. Returns (completed, message)."""
    t = t_start
    k = k_start
    line_search = solver.line_search
    fallback = line_search != "basic"
    history = any(h.path_dependent for h in solver.hooks)
    for target in steps.targets():
        if _reached(t, target):
            continue
        dt = target - t
        cuts = 0
        while not _reached(t, target):
            sig = should_stop()
            if sig:
                set_time(t)
                return False, (f"interrupted by {sig} at pseudo-time {t:.6g} (last converged "
                               f"step {k}); continue with: fenicsx-mortar run --restart DIR")
            t_try = min(t + dt, target)
            saved = solver.save_state()
            on_progress(f"step {k + 1} t={t_try:.6g} ...")
            res = _attempt(solver, set_time, t_try, max_augmentations)
            while not res.converged and res.workspace and not should_stop():
                # a smaller increment would not need less: grow MUMPS's workspace instead
                grown = solver.grow_workspace()
                if grown is None:
                    break
                _undo(solver, saved)
                on_progress(f"MUMPS workspace too small: retrying with ICNTL(14) = {grown}")
                res = _attempt(solver, set_time, t_try, max_augmentations)
            # would a failure of this increment end the run?
            below_floor, out_of_cuts = dt * 0.5 < steps.floor(), cuts >= steps.max_cuts
            retry = fallback and (below_floor or out_of_cuts or not history)
            if not res.converged and retry and not should_stop():
                # the active set makes the residual only semismooth: a line search can stall
                # on its kinks where full Newton steps go through (Hertz, mortar, penalty
                # 10 E/h at h = a/2). With friction only before giving up: another attempt
                # sequence is another (equally valid) load path
                _undo(solver, saved)
                on_progress(f"retrying with full Newton steps: {res.reason}")
                solver.set_line_search("basic")
                full = _attempt(solver, set_time, t_try, max_augmentations)
                solver.set_line_search(line_search)
                if not full.converged:
                    full.reason = f"{res.reason}; with full Newton steps: {full.reason}"
                res = full
            if res.converged:
                for h in solver.hooks:
                    h.accept_step()
                t = t_try
                k += 1
                on_step(k, t, res, cuts)
                dt *= 2.0  # after a cut, grow back towards the scene's increment
                cuts = 0
                continue
            _undo(solver, saved)
            set_time(t)
            if should_stop():
                continue  # reported at the top of the loop
            cuts += 1
            if below_floor:
                return False, (f"stopped at pseudo-time {t:.6g} (last converged step {k}): the "
                               f"increment would fall below the floor {steps.floor():.3g} "
                               f"(steps.min_increment); {res.reason}")
            if out_of_cuts:
                return False, (f"stopped at pseudo-time {t:.6g} (last converged step {k}): the "
                               f"increment to {t_try:.6g} failed after {steps.max_cuts} cuts; "
                               f"{res.reason}")
            dt *= 0.5
            on_progress(f"cut: {res.reason}; retrying with increment {dt:.3g}")
    return True, f"completed {k} steps up to pseudo-time {t:.6g}"


def _reached(t: float, target: float) -> bool:
    """t is at ``target`` up to round-off, relative to their size: a scene on pseudo-times of
    1e-15 is run, not skipped as if at 0."""
    return t >= target - 1e-14 * max(abs(t), abs(target))


def _undo(solver: NewtonSolver, saved: PETSc.Vec) -> None:
    """Back to the state before a failed attempt (iterate and the hooks' step history)."""
    for h in solver.hooks:
        h.reject_step()
    solver.restore_state(saved)


def _attempt(solver: NewtonSolver, set_time, t_try: float, max_augmentations: int
             ) -> StepResult:
    set_time(t_try)
    for h in solver.hooks:
        h.begin_step()
    return solver.solve_step(max_augmentations)
