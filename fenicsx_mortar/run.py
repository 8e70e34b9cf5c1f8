"""``solve(scene)``: mesh → bulk forms → contact pairs (only if declared) → load steps → outputs."""
from __future__ import annotations

import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np
from mpi4py import MPI

from . import _dolfinx as dx
from . import output
from .bulk import Bulk, StressOutput, build_bulk
from .meshing import Domain, build_domain
from .scene import Scene
from .solver import NewtonSolver, StepResult, Timings, run_load_steps


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
    hooks: list = field(default_factory=list)
    summary: dict = field(default_factory=dict)

    @property
    def u(self):
        return self.bulk.u


def solve(scene: Scene, out: str | Path | None = None, comm: MPI.Comm = MPI.COMM_WORLD,
          log: Callable[[str], None] | None = None) -> Result:
    """Run a scene. With ``out``, write summary.json, solution.xdmf and plots there
    (after every converged step, so a failed run keeps what converged)."""
    scene.validate()
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
        hooks, matrix = [], None
        if scene.contacts:
            from .contact.pair import build_contact  # only a scene with contact loads it
            hooks, matrix = build_contact(scene, dom, bulk, timings)
        solver = NewtonSolver(bulk, scene.solver, hooks, timings, matrix)
    V = bulk.V
    ndofs = V.dofmap.index_map.size_global * V.dofmap.index_map_bs
    log(f"  dofs: {ndofs}, ranks: {comm.size}")

    summary = {"title": scene.title, "converged": False, "message": "running",
               "effects": scene.effects(), "dofs": ndofs, "ranks": comm.size,
               "steps": [], "timings": timings}
    steps: list[dict] = []
    writer = None
    if out is not None:
        if rank0:
            out.mkdir(parents=True, exist_ok=True)
        comm.barrier()
        with timings("output"):
            if scene.output.xdmf:
                writer = dx.XDMFWriter(comm, str(out / "solution.xdmf"), dom.mesh)
                stress.update()
                writer.write([bulk.u, stress.sigma], 0.0)

    def on_step(k: int, t: float, res: StepResult, cuts: int) -> None:
        b = solver.unconstrained_residual()
        record = {"step": k, "time": t, "load_factor": t, "newton_iterations": res.iterations,
                  "augmentations": res.augmentations, "cuts": cuts,
                  "residuals": res.residuals, "reactions": bulk.reactions(b)}
        for h in hooks:
            record.setdefault("contact", {}).update(h.record())
        steps.append(record)
        with timings("output"):
            stress.update()
            if writer is not None:
                writer.write([bulk.u, stress.sigma], t)
            if out is not None and rank0:
                summary["steps"] = steps
                output.write_summary(out, summary)
                for h in hooks:
                    h.write_interface(out, k)
        log(_step_line(k, t, res, cuts))

    progress = _progress_printer() if rank0 else (lambda s: None)
    completed, message = run_load_steps(solver, scene.steps, on_step, progress,
                                        max(c.enforcement.max_augmentations for c in scene.contacts)
                                        if scene.contacts else 0)
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
                for h in hooks:
                    h.plot(out, steps)
    summary["timings"] = dict(timings)
    log(("done: " if completed else "FAILED: ") + message)
    return Result(scene, completed, message, steps, dict(timings), dom, bulk, stress, hooks,
                  summary)


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
