"""Load stepping: pseudo-time from one target to the next, with recovery from failed
increments — a larger MUMPS workspace, full Newton steps, a cut increment — and growth
after cuts.

``set_load(t)`` puts the loads and prescribed displacements of pseudo-time t on the
problem; :class:`LoadStepper` solves at each target time, cutting a failed increment in
half (at most ``max_cuts`` times in a row, not below ``min_increment``) and doubling it
again after each converged step that needed no cut (one that did is repeated at its size
first), never past the next target. What happens is told as
typed events (:class:`StepStarted`, :class:`Retried`, :class:`Cut`, :class:`StepDone`):
``on_step`` gets every converged step, ``on_event`` every event (default: a progress line
per step on rank 0).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Callable, Sequence

from mpi4py import MPI

from .newton import StepResult
from .settings import check_number

if TYPE_CHECKING:
    from .problem import ContactProblem


@dataclass(frozen=True)
class StepStarted:
    """An increment is tried.

    Attributes:
        step: The step it would be.
        time: Its target pseudo-time.
    """
    step: int
    time: float


@dataclass(frozen=True)
class Retried:
    """The failed increment is tried again another way.

    Attributes:
        step: The step it would be.
        time: Its target pseudo-time.
        how: ``"workspace"`` (MUMPS's ICNTL(14) raised to ``value``) or
            ``"full Newton steps"``.
        reason: Why the last attempt failed.
        value: The new workspace margin (per cent), for ``"workspace"``.
    """
    step: int
    time: float
    how: str
    reason: str
    value: float | None = None


@dataclass(frozen=True)
class Cut:
    """An increment failed and is cut.

    Attributes:
        step: The step it would have been.
        time: The pseudo-time it aimed at.
        increment: The next, halved increment.
        reason: Why it failed.
    """
    step: int
    time: float
    increment: float
    reason: str


@dataclass(frozen=True)
class StepDone:
    """A load step converged (and is committed).

    Attributes:
        step: Its number (from 1, or from the restart's step).
        time: Its pseudo-time.
        result: The Newton solve's result.
        cuts: Cuts of its increment before it converged.
    """
    step: int
    time: float
    result: StepResult
    cuts: int


Event = StepStarted | Retried | Cut | StepDone


@dataclass(frozen=True)
class SteppingResult:
    """How a :meth:`LoadStepper.run` ended.

    Attributes:
        completed: Every target reached.
        message: What happened (where it stopped, and why).
        step: The last converged step.
        time: Its pseudo-time.
    """
    completed: bool
    message: str
    step: int
    time: float


def print_progress(event: Event) -> None:
    """The default ``on_event``: one line per converged step, retry and cut, on rank 0.

    Args:
        event: What the stepper did.
    """
    if MPI.COMM_WORLD.rank != 0:
        return
    if isinstance(event, StepDone):
        r = event.result
        print(f"step {event.step} t={event.time:.6g}: {r.iterations} Newton iterations"
              + (f", {r.augmentations} augmentations" if r.augmentations else "")
              + (f", {event.cuts} cuts" if event.cuts else ""), flush=True)
    elif isinstance(event, Cut):
        print(f"  cut: {event.reason}; retrying with increment {event.increment:.3g}",
              flush=True)
    elif isinstance(event, Retried):
        print(f"  retrying with {event.how}: {event.reason}", flush=True)


class LoadStepper:
    """Solves a :class:`~fenicsx_mortar.ContactProblem` along a load path.

    Args:
        problem: The problem (its pairs' history is committed step by step).
        set_load: ``set_load(t)`` sets the loads of pseudo-time ``t`` (DOLFINx Constants,
            Functions of prescribed displacements, ...).
        times: Increasing pseudo-times to reach (the load steps).
        max_cuts: Cuts of one increment in a row before giving up.
        min_increment: The smallest increment a cut may give (default 1e-4 × the last time).
        max_augmentations: Of each solve (ALM updates, penalty continuation).
        on_step: Called with :class:`StepDone` after every converged step.
        on_event: Called with every event (default :func:`print_progress`; None: quiet).
        start: (step, time) already reached (a restart).
    """

    def __init__(self, problem: "ContactProblem", set_load: Callable[[float], None],
                 times: Sequence[float], *, max_cuts: int = 6,
                 min_increment: float | None = None, max_augmentations: int = 30,
                 on_step: Callable[[StepDone], None] | None = None,
                 on_event: Callable[[Event], None] | None = print_progress,
                 start: tuple[int, float] = (0, 0.0)):
        times = [float(t) for t in times]
        if not times or not all(math.isfinite(t) and t > 0 for t in times) \
                or any(b <= a for a, b in zip(times, times[1:])):
            raise ValueError(f"times = {times[:5]}{' ...' if len(times) > 5 else ''}: a "
                             "non-empty, strictly increasing list of positive pseudo-times")
        check_number("load_steps", len(times), "len(times)")
        check_number("max_cuts", max_cuts)
        check_number("max_augmentations", max_augmentations)
        if min_increment is not None:
            check_number("min_increment", min_increment)
        if not callable(set_load):
            raise ValueError("set_load: a function of the pseudo-time t that sets the loads")
        self.problem, self.set_load, self.times = problem, set_load, times
        self.max_cuts, self.max_augmentations = int(max_cuts), int(max_augmentations)
        self.min_increment = min_increment if min_increment is not None else 1e-4 * times[-1]
        self.on_step, self.on_event = on_step, on_event or (lambda e: None)
        self.step, self.time = start
        #: how a failed increment is tried again before it is cut, in order
        self.recoveries: list[Callable[[_Increment, StepResult], StepResult]] = [
            grow_workspace, full_newton_steps]

    def run(self) -> SteppingResult:
        """Step through the target times from where the stepper is.

        Returns:
            Whether every target was reached, and a message.
        """
        newton = self.problem.newton
        stop = newton.should_stop
        for target in self.times:
            if _reached(self.time, target):
                continue
            dt = target - self.time
            cuts = 0
            while not _reached(self.time, target):
                sig = stop()
                if sig:
                    self.set_load(self.time)
                    return self._ended(False, f"interrupted by {sig} at pseudo-time "
                                       f"{self.time:.6g} (last converged step {self.step})")
                t_try = min(self.time + dt, target)
                inc = _Increment(self, t_try, below_floor=dt * 0.5 < self.min_increment,
                                 out_of_cuts=cuts >= self.max_cuts)
                self.on_event(StepStarted(self.step + 1, t_try))
                res = inc.attempt()
                for recover in self.recoveries:
                    if not res.converged and not stop():
                        res = recover(inc, res)
                if res.converged:
                    self.step += 1
                    self.time = t_try
                    done = StepDone(self.step, t_try, res, cuts)
                    if self.on_step is not None:
                        self.on_step(done)
                    self.on_event(done)
                    # after a cut, grow back towards the scene's increment, but only
                    # from the second converged increment on: doubled at once it is the
                    # one that just failed (large sliding at 2M dofs: every step of the
                    # press was followed by a failed attempt of twice its size)
                    if cuts == 0:
                        dt *= 2.0
                    cuts = 0
                    continue
                self.set_load(self.time)
                if stop():
                    continue  # reported at the top of the loop
                cuts += 1
                where = f"stopped at pseudo-time {self.time:.6g} (last converged step " \
                        f"{self.step}): "
                if inc.below_floor:
                    return self._ended(False, where + "the increment would fall below the "
                                       f"floor {self.min_increment:.3g} (steps.min_increment)"
                                       f"; {res.reason}")
                if inc.out_of_cuts:
                    return self._ended(False, where + f"the increment to {t_try:.6g} failed "
                                       f"after {self.max_cuts} cuts; {res.reason}")
                dt *= 0.5
                self.on_event(Cut(self.step + 1, t_try, dt, res.reason))
        return self._ended(True, f"completed {self.step} steps up to pseudo-time "
                           f"{self.time:.6g}")

    def _ended(self, completed: bool, message: str) -> SteppingResult:
        return SteppingResult(completed, message, self.step, self.time)


class _Increment:
    """One increment being tried: its target time and whether a failure would end the run."""

    def __init__(self, stepper: LoadStepper, time: float, below_floor: bool,
                 out_of_cuts: bool):
        self.stepper, self.time = stepper, time
        self.below_floor, self.out_of_cuts = below_floor, out_of_cuts

    def attempt(self) -> StepResult:
        """Solve at the increment's load from the last converged state (a failed solve
        puts the state back there)."""
        self.stepper.set_load(self.time)
        return self.stepper.problem.solve(self.stepper.max_augmentations)

    def retried(self, how: str, reason: str, value: float | None = None) -> None:
        s = self.stepper
        s.on_event(Retried(s.step + 1, self.time, how, reason, value))


def grow_workspace(inc: _Increment, res: StepResult) -> StepResult:
    """A recovery: MUMPS ran out of workspace, and a smaller increment would not need less,
    so raise its workspace (ICNTL(14)) and try again, until it is at its maximum.

    Args:
        inc: The increment being tried.
        res: Its failed result.

    Returns:
        The result of the last attempt (or ``res``).
    """
    newton = inc.stepper.problem.newton
    while not res.converged and res.workspace and not newton.should_stop():
        grown = newton.grow_workspace()
        if grown is None:
            break
        inc.retried("workspace", res.reason, grown)
        res = inc.attempt()
    return res


def full_newton_steps(inc: _Increment, res: StepResult) -> StepResult:
    """Try the increment once more with full Newton steps (no line search): the active set
    makes the residual only semismooth, and a line search can stall on its kinks where full
    steps go through (Hertz, mortar, penalty 10 E/h at h = a/2). So only after a stall
    (StepResult.stalled); not after a residual that was not finite (full steps go further
    where F is undefined), a converged state that was rejected, a cycling active set or a
    failed linear solve: over the test suite not one of 44 such retries converged, and on
    large sliding (docs/benchmarks.md B3 at 0.5M dofs) they were a third of the failed
    Newton iterations. With path-dependent pairs (friction) only when the increment cannot
    be cut any more: another attempt sequence is another (equally valid) load path.

    Args:
        inc: The increment being tried.
        res: Its failed result.

    Returns:
        The result with full steps (or ``res`` when not tried).
    """
    newton = inc.stepper.problem.newton
    line_search = newton.line_search
    if line_search == "basic" or not res.stalled:
        return res
    history = any(p.path_dependent for p in newton.pairs)
    if history and not (inc.below_floor or inc.out_of_cuts):
        return res
    inc.retried("full Newton steps", res.reason)
    newton.set_line_search("basic")
    full = inc.attempt()
    newton.set_line_search(line_search)
    if not full.converged:
        full.reason = f"{res.reason}; with full Newton steps: {full.reason}"
    return full


def _reached(t: float, target: float) -> bool:
    """t is at ``target`` up to round-off, relative to their size: a scene on pseudo-times of
    1e-15 is run, not skipped as if at 0."""
    return t >= target - 1e-14 * max(abs(t), abs(target))
