"""``solve(scene)``: mesh → bulk forms → contact pairs (only if declared) → load steps → outputs.

The scene runner is a client of the library API: it builds the UFL forms of the scene's
bodies and loads (:mod:`.bulk`), one :class:`~.contact.pair.ContactPair` per declared pair
from the mesh's named groups, and drives a :class:`~.problem.ContactProblem` through the
load steps with step cutting (:func:`.solver.run_load_steps`), writing the outputs.
"""
from __future__ import annotations

import contextlib
import dataclasses
import json
import os
import signal
import sys
import threading
import time
import weakref
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, TypeVar

from mpi4py import MPI

from . import _dolfinx as dx
from . import checkpoint, guards, output
from .contact import output as interface_output
from .bulk import Bulk, StressOutput, build_bulk
from .meshing import Domain, build_domain
from .parallel import BrokenOutput, RankOSError, RunError, agree, on_rank0
from .scene import Scene, SceneError
from .solver import StepResult, Timings, run_load_steps

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


def phase() -> str:
    """What solve() is doing (for the message of a signal outside the load steps)."""
    return _PHASE[0]


def _enter(what: str) -> None:
    _PHASE[0] = what


def solve(scene: Scene, out: str | Path | None = None, comm: MPI.Comm = MPI.COMM_WORLD,
          log: Callable[[str], None] | None = None, restart: bool = False,
          on_step: Callable[[dict, "Result"], None] | None = None) -> Result:
    """Run a scene. With ``out``, write summary.json, solution.xdmf, plots and a checkpoint
    there after every converged step, so a run that fails or is interrupted (SIGINT,
    SIGTERM) keeps what converged; ``restart=True`` continues from ``out``'s checkpoint.
    ``on_step(record, state)`` is called after every converged step with the step's record
    and a Result holding the current state (for pictures or custom output of each step).

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
    saved = None
    if restart:
        if out is None or not (out / checkpoint.FILE).is_file():
            raise SceneError(f"restart: {out}/{checkpoint.FILE} does not exist (no converged "
                             "step to continue from)")
        saved = checkpoint.read(out, comm, scene_to_json(scene))
    elif out is not None:
        on_rank0(comm, lambda: output.prepare_out(out))
    rank0 = comm.rank == 0
    log = log or (_log_line if rank0 else (lambda s: None))
    timings = Timings()
    t_start = time.perf_counter()

    # the title is the user's text: control characters (escapes, CR) would drive the terminal
    title = "".join(c if c.isprintable() else " " for c in scene.title or "scene")
    log(f"fenicsx_mortar: {title}")
    for e in scene.effects():
        log(f"  effect: {e}")

    _enter("meshing")
    with timings("mesh"):
        dom = build_domain(scene, comm)
    _enter("compiling the forms (JIT)")
    with timings("jit"), _jit_cache_kept_whole():
        bulk = build_bulk(scene, dom)
        stress = StressOutput(bulk, scene)
    _enter("setting up the contact pairs and the solver")
    pairs = scene_pairs(scene, dom, bulk.V) if scene.contacts else []
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
    with timings("jit"), _jit_cache_kept_whole():
        from .problem import ContactProblem
        problem = ContactProblem(bulk.residual, bulk.u, bulk.bcs, pairs, bulk.jacobian,
                                 settings=scene.solver, timings=timings,
                                 should_stop=stop.requested)
        solver = problem.solver
        # (a proxy: a guard holding the solver it is held by would keep both, with the
        # PETSc objects, until the cycle collector ran)
        solver.check_solution = guards.StepGuard(scene, bulk, weakref.proxy(solver))
    ndofs = dx.dof_count(bulk.V)
    log(f"  dofs: {ndofs}, ranks: {comm.size}")

    summary = {"title": scene.title, "converged": False, "message": "running",
               "effects": scene.effects(), "dofs": ndofs, "ranks": comm.size,
               "steps": steps, "timings": timings, "warnings": []}
    writer = None
    kept = {"checkpoint.npz": k0, "summary.json": k0}
    if out is not None:
        if not restart:
            cleared = on_rank0(comm, lambda: output.clear_previous(out))
            if cleared:
                log(f"  removed {cleared} files of a previous run in {out}")
            _write(out, comm, kept, lambda: output.write_atomic(out / "scene.json",
                                                                scene_to_json(scene)),
                   rank0_only=True)
        with timings("output"):
            if scene.output.xdmf:
                # a restart continues in its own file: XDMF cannot be reopened for appending
                name = f"solution_from_step_{k0}.xdmf" if restart else "solution.xdmf"
                writer = _xdmf(out, kept, lambda: dx.XDMFWriter(comm, str(out / name),
                                                                 dom.mesh))
                stress.update()
                _xdmf(out, kept, lambda: writer.write([bulk.u, stress.sigma], t0))
    warned: set[str] = set()

    def record_step(k: int, t: float, res: StepResult, cuts: int) -> None:
        b = solver.unconstrained_residual()
        record = {"step": k, "time": t, "load_factor": t, "newton_iterations": res.iterations,
                  "augmentations": res.augmentations, "cuts": cuts,
                  "residuals": res.residuals, "reactions": bulk.reactions(b)}
        for p in pairs:
            record.setdefault("contact", {}).update(p.record())
        steps.append(record)
        for p, c in zip(pairs, scene.contacts):
            warning = guards.penetration_warning(p, k) if c.enforcement.type == "penalty" \
                else None
            if warning and p.name not in warned:
                warned.add(p.name)
                summary["warnings"].append(warning)
                log(f"  warning: {warning}")
        with timings("output"):
            stress.update()
            if writer is not None:
                _xdmf(out, kept, lambda: writer.write([bulk.u, stress.sigma], t))
            if out is not None:
                _write(out, comm, kept, lambda: checkpoint.save(
                    out, comm, bulk.u, pairs, t, k, steps, fingerprints), "checkpoint.npz", k)
                _write(out, comm, kept, lambda: [interface_output.write_interface(p, out, k)
                                                 for p in pairs], rank0_only=True)
                # last: a summary.json that lists step k means all of step k's files exist
                _write(out, comm, kept, lambda: output.write_summary(out, summary),
                       "summary.json", k, rank0_only=True)
        log(_step_line(k, t, res, cuts))
        if on_step is not None:
            on_step(record, Result(scene, False, "running", steps, dict(timings), dom, bulk,
                                   stress, pairs, summary))

    live = _progress_printer() if rank0 else (lambda s: None)

    def progress(s: str) -> None:
        # why an increment failed belongs in the log (a batch run's only record of it);
        # "step k t=… ..." is a live status line only
        if s.startswith(("cut:", "retrying", "MUMPS")):
            log(f"  {s}")
        else:
            live(s)
    _enter("in the load steps")
    try:
        with stop:
            completed, message = run_load_steps(
                solver, scene.steps, bulk.set_time, record_step, progress,
                max(c.enforcement.max_augmentations for c in scene.contacts)
                if scene.contacts else 0,
                t_start=t0, k_start=k0, should_stop=stop.requested)
    except RunError as e:
        # no "FAILED" log line: the caller says it (the CLI: one line on stderr); under Open
        # MPI 5 a stdout line written just before it was seen merged into mpirun's stderr
        # (tests/hostile mpi_disk_full). After a failed XDMF write no rank closes the file:
        # the close is collective, and the rank whose write failed does not take part
        if writer is not None and not isinstance(e, BrokenOutput):
            try:
                writer.close()
            except OSError:
                pass             # the error being raised says what went wrong first
        raise
    timings["total"] = time.perf_counter() - t_start
    _enter("writing the final outputs")
    with timings("output"):
        if writer is not None:
            _xdmf(out, kept, writer.close)
        summary.update(converged=completed, message=message, steps=steps, timings=dict(timings))
        if out is not None:
            _write(out, comm, kept, lambda: _final_outputs(out, scene, summary, steps, pairs),
                   rank0_only=True)
    summary["timings"] = dict(timings)
    _enter("reading the scene")
    log(("done: " if completed else "FAILED: ") + message)
    problem.close()   # its PETSc objects now, on every rank alike
    return Result(scene, completed, message, steps, dict(timings), dom, bulk, stress, pairs,
                  summary)


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
            interface_output.plot_pressure(p, out)


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
    from .contact.pair import ContactPair
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
                friction=c.friction.law, mu=c.friction.mu, E=moduli,
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
