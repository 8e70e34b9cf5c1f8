"""``solve(scene)``: mesh → bulk forms → contact pairs (only if declared) → load steps → outputs.

The scene runner is a client of the library API: it builds the UFL forms of the scene's
bodies and loads (:mod:`.bulk`), one :class:`~.contact.pair.ContactPair` per declared pair
from the mesh's named groups, and drives a :class:`~.problem.ContactProblem` through the
load steps with step cutting (:func:`.solver.run_load_steps`), writing the outputs.
"""
from __future__ import annotations

import dataclasses
import json
import signal
import sys
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

from mpi4py import MPI

from . import _dolfinx as dx
from . import checkpoint, output
from .contact import output as interface_output
from .bulk import Bulk, StressOutput, build_bulk
from .meshing import Domain, build_domain
from .scene import Scene, SceneError
from .solver import StepResult, Timings, run_load_steps


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


def solve(scene: Scene, out: str | Path | None = None, comm: MPI.Comm = MPI.COMM_WORLD,
          log: Callable[[str], None] | None = None, restart: bool = False,
          on_step: Callable[[dict, "Result"], None] | None = None) -> Result:
    """Run a scene. With ``out``, write summary.json, solution.xdmf, plots and a checkpoint
    there after every converged step, so a run that fails or is interrupted (SIGINT,
    SIGTERM) keeps what converged; ``restart=True`` continues from ``out``'s checkpoint.
    ``on_step(record, state)`` is called after every converged step with the step's record
    and a Result holding the current state (for pictures or custom output of each step)."""
    scene.validate()
    if restart and (out is None or not (Path(out) / checkpoint.FILE).is_file()):
        raise SceneError(f"restart: {out}/{checkpoint.FILE} does not exist (no converged step "
                         "to continue from)")
    rank0 = comm.rank == 0
    log = log or (_log_line if rank0 else (lambda s: None))
    timings = Timings()
    t_start = time.perf_counter()
    out = Path(out) if out is not None else None

    log(f"fenicsx_mortar: {scene.title or 'scene'}")
    for e in scene.effects():
        log(f"  effect: {e}")

    with timings("mesh"):
        dom = build_domain(scene, comm)
    with timings("jit"):
        bulk = build_bulk(scene, dom)
        stress = StressOutput(bulk, scene)
    pairs = scene_pairs(scene, dom, bulk.V) if scene.contacts else []
    t0, k0, steps = 0.0, 0, []
    if restart:
        t0, k0, steps = checkpoint.load(Path(out), comm, bulk.u, pairs)
        log(f"  restart from step {k0} at pseudo-time {t0:.6g}")
    stop = _StopRequest(comm)
    with timings("jit"):
        from .problem import ContactProblem
        problem = ContactProblem(bulk.residual, bulk.u, bulk.bcs, pairs, bulk.jacobian,
                                 settings=scene.solver, timings=timings,
                                 should_stop=stop.requested)
    solver = problem.solver
    ndofs = dx.dof_count(bulk.V)
    log(f"  dofs: {ndofs}, ranks: {comm.size}")

    summary = {"title": scene.title, "converged": False, "message": "running",
               "effects": scene.effects(), "dofs": ndofs, "ranks": comm.size,
               "steps": steps, "timings": timings}
    writer = None
    if out is not None:
        if rank0:
            out.mkdir(parents=True, exist_ok=True)
            if not restart:
                output.write_atomic(out / "scene.json", scene_to_json(scene))
        comm.barrier()
        with timings("output"):
            if scene.output.xdmf:
                # a restart continues in its own file: XDMF cannot be reopened for appending
                name = f"solution_from_step_{k0}.xdmf" if restart else "solution.xdmf"
                writer = dx.XDMFWriter(comm, str(out / name), dom.mesh)
                stress.update()
                writer.write([bulk.u, stress.sigma], t0)

    def record_step(k: int, t: float, res: StepResult, cuts: int) -> None:
        b = solver.unconstrained_residual()
        record = {"step": k, "time": t, "load_factor": t, "newton_iterations": res.iterations,
                  "augmentations": res.augmentations, "cuts": cuts,
                  "residuals": res.residuals, "reactions": bulk.reactions(b)}
        for p in pairs:
            record.setdefault("contact", {}).update(p.record())
        steps.append(record)
        with timings("output"):
            stress.update()
            if writer is not None:
                writer.write([bulk.u, stress.sigma], t)
            if out is not None:
                checkpoint.save(out, comm, bulk.u, pairs, t, k, steps)
                if rank0:
                    output.write_summary(out, summary)
                    for p in pairs:
                        interface_output.write_interface(p, out, k)
        log(_step_line(k, t, res, cuts))
        if on_step is not None:
            on_step(record, Result(scene, False, "running", steps, dict(timings), dom, bulk,
                                   stress, pairs, summary))

    progress = _progress_printer() if rank0 else (lambda s: None)
    with stop:
        completed, message = run_load_steps(
            solver, scene.steps, bulk.set_time, record_step, progress,
            max(c.enforcement.max_augmentations for c in scene.contacts) if scene.contacts else 0,
            t_start=t0, k_start=k0, should_stop=stop.requested)
    timings["total"] = time.perf_counter() - t_start
    with timings("output"):
        if writer is not None:
            writer.close()
        summary.update(converged=completed, message=message, steps=steps, timings=dict(timings))
        if out is not None and rank0:
            output.write_summary(out, summary)
            if scene.output.plots:
                output.plot_reactions(out, steps)
                output.plot_convergence(out, steps)
                for p in pairs:
                    interface_output.plot_pressure(p, out)
    summary["timings"] = dict(timings)
    log(("done: " if completed else "FAILED: ") + message)
    return Result(scene, completed, message, steps, dict(timings), dom, bulk, stress, pairs,
                  summary)


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


def _log_line(s: str) -> None:
    # on a terminal, first wipe the live progress line
    print(("\r\033[K" if sys.stdout.isatty() else "") + s, flush=True)


def _progress_printer() -> Callable[[str], None]:
    """A live status line on a terminal; nothing when output goes to a file."""
    if not sys.stdout.isatty():
        return lambda s: None

    def show(s: str) -> None:
        sys.stdout.write("\r\033[K" + s)
        sys.stdout.flush()
    return show
