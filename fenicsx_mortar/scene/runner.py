"""``solve(scene)``: mesh → bulk forms → contact pairs (only if declared) → load steps → outputs.

The scene runner is a client of the library API: it builds the UFL forms of the scene's
bodies and loads (:mod:`.bulk`), one :class:`~.contact.pair.ContactPair` per declared pair
from the mesh's named groups, and drives a :class:`~.problem.ContactProblem` through the
load steps with a :class:`~.stepping.LoadStepper`, writing the outputs.
"""
from __future__ import annotations

import contextlib
import dataclasses
import itertools
import json
import os
import signal
import sys
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, TypeVar

from mpi4py import MPI

from .. import _dolfinx as dx
from ..io import checkpoint, output
from ..io import interface as interface_files
from . import guards
from .bulk import Bulk, StressOutput, build_bulk
from .meshing import Domain, build_domain
from .parallel import BrokenOutput, RankOSError, RunError, agree, on_rank0
from .model import Scene, SceneError
from ..newton import StepResult
from ..stepping import Cut, Event, LoadStepper, Retried, StepDone, StepStarted
from ..timings import Timings

T = TypeVar("T")


@dataclass
class Result:
    """What a run produced. ``u`` and ``stress`` hold the last converged state."""
    scene: Scene
    converged: bool
    message: str
    steps: list[dict]
    timings: dict[str, float]
    domain: Domain
    bulk: Bulk
    stress: StressOutput
    pairs: list = field(default_factory=list)
    summary: dict = field(default_factory=dict)

    @property
    def u(self):
        return self.bulk.u


_PHASE = ["reading the scene"]
#: the runs' own PETSc options prefixes
_PREFIXES = itertools.count()


def phase() -> str:
    """What solve() is doing (for the message of a signal outside the load steps)."""
    return _PHASE[0]


def _enter(what: str) -> None:
    _PHASE[0] = what


def solve(scene: Scene, out: str | Path | None = None, comm: MPI.Comm = MPI.COMM_WORLD,
          log: Callable[[str], None] | None = None, restart: bool = False,
          on_step: Callable[[dict, "Result"], None] | None = None) -> Result:
    """Run a scene: build (mesh, forms, pairs) → :class:`~.problem.ContactProblem` →
    :class:`~.stepping.LoadStepper`, with the step records and the outputs as observers of
    the converged steps.

    With ``out``, write summary.json, solution.xdmf, plots and a checkpoint there after every
    converged step, so a run that fails or is interrupted (SIGINT, SIGTERM) keeps what
    converged; ``restart=True`` continues from ``out``'s checkpoint. ``on_step(record,
    state)`` is called after every converged step with the step's record and a Result
    holding the current state (for pictures or custom output of each step).

    Bad input raises SceneError on every rank, before meshing where it can be told without
    the mesh (the scene, the PETSc options, the output directory, the checkpoint) and
    before anything is written otherwise; a write that fails (a full disk) stops the run
    with RunError naming the disk, keeping the last good summary.json and checkpoint. A
    failed XDMF write (inside HDF5, collective) raises BrokenOutput (a RunError) on the
    ranks where it failed only — the others may wait in the collective call: under MPI
    the caller must end every rank (the command line calls MPI_Abort)."""
    _enter("checking the inputs")
    scene.validate()
    guards.check_petsc_options(scene.solver)
    out = Path(out) if out is not None else None
    saved = _open_out(scene, out, comm, restart)
    log = log or (_log_line if comm.rank == 0 else (lambda s: None))
    timings = Timings()
    t_start = time.perf_counter()
    # the title is the user's text: control characters (escapes, CR) would drive the terminal
    title = "".join(c if c.isprintable() else " " for c in scene.title or "scene")
    log(f"fenicsx_mortar: {title}")
    for e in scene.effects():
        log(f"  effect: {e}")

    dom, bulk, stress, pairs = build(scene, comm, timings)
    for w in dom.warnings:
        log(f"  warning: {w}")
    fingerprints = (checkpoint.scene_fingerprint(scene_to_json(scene)),
                    checkpoint.mesh_fingerprint(dom, comm))
    t0, k0, steps = 0.0, 0, []
    if restart:
        t0, k0, steps = checkpoint.load(out, comm, bulk.u, pairs, saved, fingerprints[1])
        # the pairs' state at the restored solution, as after that step in the first run:
        # the next step starts from it (its master curve, the crossing check)
        for p in pairs:
            p.update(bulk.u)
        log(f"  restart from step {k0} at pseudo-time {t0:.6g}")
    else:
        guards.check_tolerance(scene, bulk)
    stop = _StopRequest(comm)
    problem = _problem(scene, dom, bulk, pairs, timings, stop)
    ndofs = dx.dof_count(bulk.V)
    solver = problem.newton.settings.linear_solver        # "auto" resolved by size
    log(f"  dofs: {ndofs}, ranks: {comm.size}, linear solver: {solver}"
        + (" (auto)" if scene.solver.linear_solver == "auto" else ""))

    summary = {"title": scene.title, "converged": False, "message": "running",
               "effects": scene.effects(), "dofs": ndofs, "ranks": comm.size,
               "linear_solver": solver,
               "steps": steps, "timings": timings, "warnings": list(dom.warnings)}
    outputs = _Outputs(scene, out, comm, bulk, stress, pairs, fingerprints, (k0, t0), restart,
                       timings, log) if out is not None else None
    recorder = _StepRecorder(scene, dom, bulk, stress, pairs, problem, steps, summary,
                             outputs, timings, log, on_step)
    _enter("in the load steps")
    try:
        with stop:
            ended = LoadStepper(problem, bulk.set_time, scene.steps.targets(),
                                max_cuts=scene.steps.max_cuts,
                                min_increment=scene.steps.floor(), on_step=recorder,
                                on_event=_progress(log, comm), start=(k0, t0)).run()
    except RunError as e:
        if outputs is not None:
            outputs.abandon(e)
        raise
    completed, message = ended.completed, ended.message
    if message.startswith("interrupted"):
        message += "; continue with: fenicsx-mortar run --restart DIR"
    timings["total"] = time.perf_counter() - t_start
    _enter("writing the final outputs")
    summary.update(converged=completed, message=message, steps=steps)
    if outputs is not None:
        outputs.finish(summary, steps)
    summary["timings"] = dict(timings)
    problem.close()
    _enter("reading the scene")
    log(("done: " if completed else "FAILED: ") + message)
    return Result(scene, completed, message, steps, dict(timings), dom, bulk, stress, pairs,
                  summary)


def build(scene: Scene, comm: MPI.Comm, timings: Timings):
    """The scene's mesh, bulk forms, stress output and contact pairs (the slow parts of the
    set-up, each timed: meshing, the forms' JIT compilation)."""
    _enter("meshing")
    with timings("mesh"):
        dom = build_domain(scene, comm)
    _enter("compiling the forms (JIT)")
    with timings("jit"), _jit_cache_kept_whole():
        bulk = build_bulk(scene, dom)
        stress = StressOutput(bulk, scene)
    _enter("setting up the contact pairs and the solver")
    pairs = scene_pairs(scene, dom, bulk.V) if scene.contacts else []
    return dom, bulk, stress, pairs


def _problem(scene: Scene, dom: Domain, bulk: Bulk, pairs: list, timings: Timings,
             stop: "_StopRequest"):
    """The scene's :class:`~.problem.ContactProblem` (its acceptance checks compile)."""
    from ..problem import ContactProblem
    with timings("jit"), _jit_cache_kept_whole():
        # a prefix of its own: no option of the environment reaches the scene's solver
        return ContactProblem(
            bulk.residual, bulk.u, bulk.bcs, pairs, bulk.jacobian,
            petsc_options_prefix=f"fm{next(_PREFIXES)}_", settings=scene.solver,
            max_augmentations=max((c.enforcement.max_augmentations for c in scene.contacts),
                                  default=0),
            cell_tags=dom.cell_tags,
            body_names={dom.cell_groups[b.group]: b.name for b in scene.bodies},
            timings=timings, should_stop=stop.requested, coarse_meshes=dom.coarse_meshes)


def _open_out(scene: Scene, out: Path | None, comm: MPI.Comm, restart: bool):
    """The checkpoint to restart from (read and checked), or ``out`` made ready; None."""
    if restart:
        if out is None or not (out / checkpoint.FILE).is_file():
            raise SceneError(f"restart: {out}/{checkpoint.FILE} does not exist (no converged "
                             "step to continue from)")
        return checkpoint.read(out, comm, scene_to_json(scene))
    if out is not None:
        on_rank0(comm, lambda: output.prepare_out(out))
    return None


def _progress(log: Callable[[str], None], comm: MPI.Comm) -> Callable[[Event], None]:
    """The stepper's events in the run's log: why an increment failed belongs there (a
    batch run's only record of it); an attempt is a live status line only."""
    live = _progress_printer() if comm.rank == 0 else (lambda s: None)

    def progress(e: Event) -> None:
        if isinstance(e, StepStarted):
            live(f"step {e.step} t={e.time:.6g} ...")
        elif isinstance(e, Cut):
            log(f"  cut: {e.reason}; retrying with increment {e.increment:.3g}")
        elif isinstance(e, Retried) and e.how == "workspace":
            log(f"  MUMPS workspace too small: retrying with ICNTL(14) = {e.value}")
        elif isinstance(e, Retried):
            log(f"  retrying with {e.how}: {e.reason}")
    return progress


class _StepRecorder:
    """The stepper's ``on_step``: a converged step's record (reactions, contact records),
    penalty warnings, the stress, the outputs, the log line, the user's callback."""

    def __init__(self, scene, dom, bulk, stress, pairs, problem, steps: list, summary: dict,
                 outputs: "_Outputs | None", timings: Timings, log, on_step):
        self.scene, self.dom, self.bulk, self.stress, self.pairs = scene, dom, bulk, stress, pairs
        self.problem, self.steps, self.summary, self.outputs = problem, steps, summary, outputs
        self.timings, self.log, self.on_step = timings, log, on_step
        self.warned: set[str] = set()

    def __call__(self, done: StepDone) -> None:
        k, t, res, cuts = done.step, done.time, done.result, done.cuts
        b = self.problem.newton.unconstrained_residual()
        record = {"step": k, "time": t, "load_factor": t, "newton_iterations": res.iterations,
                  "augmentations": res.augmentations, "cuts": cuts,
                  "residuals": res.residuals, "reactions": self.bulk.reactions(b)}
        b.destroy()
        for p in self.pairs:
            record.setdefault("contact", {}).update(p.record())
        self.steps.append(record)
        for p, c in zip(self.pairs, self.scene.contacts):
            warning = guards.penetration_warning(p, k) if c.enforcement.type == "penalty" \
                else None
            if warning and p.name not in self.warned:
                self.warned.add(p.name)
                self.summary["warnings"].append(warning)
                self.log(f"  warning: {warning}")
        with self.timings("output"):
            self.stress.update()
            if self.outputs is not None:
                self.outputs.step(k, t, self.steps, self.summary)
        self.log(_step_line(k, t, res, cuts))
        if self.on_step is not None:
            self.on_step(record, Result(self.scene, False, "running", self.steps,
                                        dict(self.timings), self.dom, self.bulk, self.stress,
                                        self.pairs, self.summary))


class _Outputs:
    """The files of a run in ``out``, written after every converged step so that a run that
    stops keeps what converged: solution.xdmf (u and the stress), checkpoint.npz, the
    interface CSVs, and summary.json last (a summary that lists step k means all of step
    k's files exist)."""

    def __init__(self, scene, out: Path, comm: MPI.Comm, bulk, stress, pairs, fingerprints,
                 start: tuple[int, float], restart: bool, timings: Timings, log):
        self.scene, self.out, self.comm = scene, out, comm
        self.bulk, self.stress, self.pairs, self.fingerprints = bulk, stress, pairs, fingerprints
        self.timings = timings
        k0, t0 = start
        #: what each file holds, for the message of a failed write
        self.kept = {"checkpoint.npz": k0, "summary.json": k0}
        self.writer = None
        if not restart:
            cleared = on_rank0(comm, lambda: output.clear_previous(out))
            if cleared:
                log(f"  removed {cleared} files of a previous run in {out}")
            _write(out, comm, self.kept, lambda: output.write_file(
                out, "scene.json", scene_to_json(scene)), rank0_only=True)
        with timings("output"):
            if scene.output.xdmf:
                # a restart continues in its own file: XDMF cannot be reopened for appending
                name = f"solution_from_step_{k0}.xdmf" if restart else "solution.xdmf"
                self.writer = _xdmf(out, self.kept, lambda: dx.XDMFWriter(
                    comm, str(output.path_for(out, name)), bulk.domain.mesh))
                stress.update()
                _xdmf(out, self.kept, lambda: self.writer.write([bulk.u, stress.sigma], t0))

    def step(self, k: int, t: float, steps: list, summary: dict) -> None:
        out, comm, kept = self.out, self.comm, self.kept
        if self.writer is not None:
            _xdmf(out, kept, lambda: self.writer.write([self.bulk.u, self.stress.sigma], t))
        _write(out, comm, kept, lambda: checkpoint.save(
            out, comm, self.bulk.u, self.pairs, t, k, steps, self.fingerprints),
            "checkpoint.npz", k)
        _write(out, comm, kept, lambda: [interface_files.write_interface(p, out, k)
                                         for p in self.pairs], rank0_only=True)
        _write(out, comm, kept, lambda: output.write_summary(out, summary), "summary.json",
               k, rank0_only=True)

    def finish(self, summary: dict, steps: list) -> None:
        with self.timings("output"):
            if self.writer is not None:
                _xdmf(self.out, self.kept, self.writer.close)
            summary["timings"] = dict(self.timings)
            _write(self.out, self.comm, self.kept, lambda: _final_outputs(
                self.out, self.scene, summary, steps, self.pairs), rank0_only=True)

    def abandon(self, e: RunError) -> None:
        """The run stops with ``e``. No "FAILED" log line: the caller says it (the CLI: one
        line on stderr); under Open MPI 5 a stdout line written just before it was seen
        merged into mpirun's stderr (tests/hostile mpi_disk_full). After a failed XDMF
        write no rank closes the file: the close is collective, and the rank whose write
        failed does not take part."""
        if self.writer is not None and not isinstance(e, BrokenOutput):
            try:
                self.writer.close()
            except OSError:
                pass             # the error being raised says what went wrong first


@contextlib.contextmanager
def _jit_cache_kept_whole():
    """If compiling is interrupted (a signal raises in the middle), leave no C file without
    its module in the JIT cache: FFCx clears its own on an Exception, except when the
    signal lands just after it created the file, and a stale one makes every later run
    wait for it and fail (TimeoutError). Renamed as FFCx itself does (``.c.failed``)."""
    cache = Path(dx.jit_cache_dir())
    before = set(cache.glob("*.c")) if cache.is_dir() else set()
    try:
        yield
    except BaseException:
        for c in set(cache.glob("*.c")) - before:
            if not c.with_suffix(".c.cached").exists():
                with contextlib.suppress(OSError):
                    os.replace(c, c.with_suffix(".c.failed"))
        raise


def _final_outputs(out: Path, scene: Scene, summary: dict, steps: list, pairs: list) -> None:
    output.write_summary(out, summary)
    if scene.output.plots:
        output.plot_reactions(out, steps)
        output.plot_convergence(out, steps)
        for p in pairs:
            interface_files.plot_pressure(p, out)


def _write(out: Path, comm: MPI.Comm, kept: dict, write: Callable[[], object],
           name: str | None = None, step: int = 0, rank0_only: bool = False) -> None:
    """Run an output write (``rank0_only``: on rank 0, the others hear how it went); a
    failure stops the run on every rank with RunError naming the file and the disk and
    what is kept. ``kept[name] = step`` once ``name`` holds ``step``."""
    try:
        on_rank0(comm, write) if rank0_only else agree(comm, write)
    except (OSError, RankOSError) as e:
        raise RunError(output.write_failure(out, e, _kept(kept))) from None
    if name is not None:
        kept[name] = step


def _xdmf(out: Path, kept: dict, call: Callable[[], T]) -> T:
    """An XDMF (HDF5, collective) operation. Its failure is raised on the ranks where it
    failed only: the others may be waiting inside the collective HDF5 call, so the ranks
    cannot agree on it (the command line ends them all, cli.py)."""
    try:
        return call()
    except OSError as e:
        raise BrokenOutput(output.write_failure(out, e, _kept(kept))) from None


def _kept(kept: dict) -> str:
    return "kept " + ", ".join(f"{n} of step {k}" for n, k in kept.items() if k) \
        if any(kept.values()) else "no step was saved"


def scene_pairs(scene: Scene, dom: Domain, V) -> list:
    """One :class:`~.contact.pair.ContactPair` per contact of the scene, from the mesh's named
    groups (a scene without contact never imports the contact package)."""
    from ..contact.pair import ContactPair
    moduli = {dom.cell_groups[b.group]: b.material.E for b in scene.bodies}
    pairs = []
    for i, c in enumerate(scene.contacts):
        def tags(groups):
            return [dom.facet_groups[g] for g in ([groups] if isinstance(groups, str) else groups)]
        try:
            pairs.append(ContactPair(
                V, dom.facet_tags, tags(c.slave), tags(c.master), name=c.name,
                method=c.method, smoothing=c.smoothing, enforcement=c.enforcement.type,
                epsilon=c.enforcement.epsilon, tolerance=c.enforcement.tolerance,
                friction=c.friction.law,
                mu=c.friction.mu if c.friction.law != "none" else None, E=moduli,
                cell_tags=dom.cell_tags, n_gauss=c.n_gauss, search_radius=c.search_radius,
                basis=c.basis, slave_smoothing=c.slave_smoothing))
        except ValueError as e:
            raise SceneError(f"contacts[{i}]: {e}") from None
    return pairs


class _StopRequest:
    """SIGINT/SIGTERM set a flag; the solver checks it (collectively) and stops cleanly."""

    def __init__(self, comm: MPI.Comm):
        self.comm, self.signal, self._old = comm, None, {}

    def __enter__(self):
        if threading.current_thread() is threading.main_thread():
            for sig in (signal.SIGINT, signal.SIGTERM):
                self._old[sig] = signal.signal(sig, self._handle)
        return self

    def __exit__(self, *exc):
        for sig, old in self._old.items():
            signal.signal(sig, old)

    def _handle(self, signum, frame):
        self.signal = signal.Signals(signum).name

    def requested(self) -> str | None:
        names = self.comm.allgather(self.signal)
        return next((n for n in names if n), None)


def scene_to_json(scene: Scene) -> str:
    """The scene as JSON (same keys as the TOML), kept beside the outputs for restarts."""
    def drop_none(v):  # TOML has no null: an absent key means "default"
        if isinstance(v, dict):
            return {k: drop_none(x) for k, x in v.items() if x is not None}
        if isinstance(v, list):
            return [drop_none(x) for x in v]
        return v
    return json.dumps(drop_none(dataclasses.asdict(scene)), indent=1) + "\n"


def _step_line(k: int, t: float, res: StepResult, cuts: int) -> str:
    r = res.residuals[-1] if res.residuals else float("nan")
    aug = f", {res.augmentations} augmentations" if res.augmentations else ""
    cut = f", {cuts} cuts" if cuts else ""
    return f"  step {k:3d}  t = {t:<10.6g} Newton {res.iterations:3d}{aug}{cut}  |R| = {r:.2e}"


def _on_terminal() -> bool:
    # Open MPI gives every rank's stdout a pty of its own (also under mpirun -n 1): not the
    # user's terminal, and the half-written status line would end up in front of the
    # rank's last stderr line, or as escape codes in a redirected output
    return (sys.stdout.isatty() and MPI.COMM_WORLD.size == 1
            and not any(k in os.environ for k in ("OMPI_COMM_WORLD_SIZE", "PMI_SIZE")))


def _log_line(s: str) -> None:
    # on a terminal, first wipe the live progress line
    print(("\r\033[K" if _on_terminal() else "") + s, flush=True)


def _progress_printer() -> Callable[[str], None]:
    """A live status line on a terminal; nothing when output goes to a file."""
    if not _on_terminal():
        return lambda s: None

    def show(s: str) -> None:
        sys.stdout.write("\r\033[K" + s)
        sys.stdout.flush()
    return show
