"""Running the study: one case in a worker process (``run_case``), a plan on the benchmarks'
process pool with its order and skip rule (``run_cases``), and the whole study with its
output files (``run_study``)."""
from __future__ import annotations

import dataclasses
import datetime
import json
import os
import platform
import subprocess
import time
import traceback
from pathlib import Path
from typing import Callable

from benchmarks import pool
from benchmarks.pool import TimeLimit

from .cases import ERRORS, LEVELS, Case, Plan
from .metrics import errors, finalize_rings
from .records import PHASES, json_lines, key, key_str, new_record, write_csv
from .scenes import make_scene

ROOT = Path(__file__).resolve().parents[2]

# ------------------------------------------------------------------------ one run (worker)


def run_case(case: Case, solve_fn: Callable | None = None) -> dict:
    """Solve one case and measure it; never raises (an exception is recorded)."""
    import warnings
    rec = new_record(case)
    t0, c0 = time.perf_counter(), time.process_time()
    try:
        if solve_fn is None:
            from fenicsx_mortar import solve as solve_fn
        scene = make_scene(case)
        eps = scene.contacts[0].enforcement.epsilon
        rec["epsilon"] = "" if eps is None else eps
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            t0, c0 = time.perf_counter(), time.process_time()
            result = solve_fn(scene, log=lambda s: None)
            rec["cpu_time"] = time.process_time() - c0
            rec["wall_time"] = time.perf_counter() - t0
        rec["warnings"] = " | ".join(sorted({str(w.message).split(":")[0] + ": "
                                             + str(w.message).split(":", 1)[-1].strip()[:80]
                                             for w in caught}))[:300]
        steps = result.steps
        rec.update(converged=bool(result.converged), message=result.message,
                   status="converged" if result.converged else (
                       "timeout" if "interrupted by" in result.message else "failed"),
                   reached_time=steps[-1]["time"] if steps else 0.0,
                   dofs=result.summary.get("dofs", ""), steps=len(steps),
                   cuts=sum(s["cuts"] for s in steps),
                   newton_iterations=sum(s["newton_iterations"] for s in steps),
                   augmentations=sum(s["augmentations"] for s in steps))
        for p in PHASES:
            rec[f"t_{p}"] = float(result.timings.get(p, 0.0))
        if result.pairs and result.pairs[0].state is not None:
            rec["slave_nodes"] = int(result.pairs[0].slave.n)
        if steps:
            rec["active_nodes"] = steps[-1]["contact"][scene.contacts[0].name]["active_nodes"]
        if case.benchmark == "half_rings":
            rec["curve"] = [[s["time"], s["reactions"]["hub"]["x"], s["reactions"]["hub"]["y"]]
                            for s in steps]
        if result.converged:
            rec.update(errors(case, result))
    except (Exception, TimeLimit) as e:  # a failing run is recorded, the study goes on
        rec.update(status="error", converged=False,
                   message=f"{type(e).__name__}: {e}".replace("\n", " ")[:500],
                   cpu_time=time.process_time() - c0, wall_time=time.perf_counter() - t0)
        rec["traceback"] = traceback.format_exc(limit=6)
    return rec


def work(fields: list) -> dict:
    """The pool's target: a case as the list of its fields."""
    return run_case(Case(*fields))


def warm_up(cases: list[list]) -> None:
    """One short solve per case, unrecorded: JIT-compiled forms and lazy imports out of the
    timed runs."""
    from fenicsx_mortar import solve
    for fields in cases:
        try:
            scene = make_scene(Case(*fields))
            scene.steps.times, scene.steps.count = scene.steps.targets()[:1], None
            solve(scene, log=lambda s: None)
        except Exception:
            pass


# -------------------------------------------------------------------- the plan on the pool


def run_cases(plan: Plan, jobs: int = 1, on_record: Callable[[dict, int, int], None] | None = None,
              log_path: Path | None = None) -> list[dict]:
    """Run ``plan.cases`` on ``jobs`` worker processes; a run over ``plan.cpu_limit`` CPU
    seconds (or ``plan.wall_limit`` wall seconds) is stopped (SIGTERM: the solver stops at
    its next Newton iteration; SIGKILL if it has not answered 60 s later) and recorded as
    "timeout"; a worker that dies is recorded as "crashed" and replaced.

    A case starts once the coarser levels of its combination are done; it is skipped when
    they did not converge at the ``plan.skip_after`` next coarser levels."""
    def combo(c: Case) -> tuple:
        return c.benchmark, c.method, c.smoothing, c.enforcement

    levels: dict[tuple, list[int]] = {}
    for c in plan.cases:
        levels.setdefault(combo(c), []).append(c.level)
    todo = list(dict.fromkeys(plan.cases))
    status: dict[tuple, str] = {}
    warmups = [Case(b, "mortar", "none", "penalty-1", 0)
               for b in dict.fromkeys(c.benchmark for c in plan.cases)]
    n = len(todo)
    records: list[dict] = []

    def done(rec: dict) -> None:
        records.append(rec)
        status[key(rec)] = rec["status"]
        if on_record:
            on_record(rec, len(records), n)

    def finished(out: pool.Outcome) -> None:
        rec = out.record
        if rec is None:
            rec = new_record(out.job.tag, status="crashed", converged=False,
                             message=f"worker process died (exit code {out.returncode})")
            rec["wall_time"] = out.wall
        if out.stopped and rec.get("status") != "converged":
            rec["status"] = "timeout"
            rec["message"] = (f"stopped at the time limit ({out.job.cpu_limit:.0f} s CPU / "
                              f"{plan.wall_limit:.0f} s wall): {rec.get('message', '')}")
        done(rec)

    def next_case() -> Case | None:
        """The finest case whose coarser levels are done (skipping the hopeless ones)."""
        while True:
            ready = []
            for c in todo:
                # the reference (the longest run) starts at once
                lower = [] if c == plan.reference else sorted(
                    k for k in levels[combo(c)] if k < c.level)
                if all(combo(c) + (k,) in status for k in lower):
                    ready.append((c, lower))
            if not ready:
                return None
            # finest first, then the long chains (B3, ALM, C1/C2 smoothings) so that they do
            # not end the study alone on one worker
            c, lower = max(ready, key=lambda x: (
                x[0].level, x[0].benchmark == "half_rings", x[0].enforcement == "alm",
                x[0].smoothing in ("bspline", "hermite")))
            todo.remove(c)
            last = lower[-plan.skip_after:] if plan.skip_after else []
            if (plan.skip_after and len(last) == plan.skip_after and c != plan.reference
                    and all(status[combo(c) + (k,)] != "converged" for k in last)):
                done(new_record(c, status="skipped", converged=False, message=(
                    "not run: the same combination did not converge at levels "
                    + ", ".join(LEVELS[c.benchmark][k].label for k in last))))
                continue
            return c

    def schedule():
        while todo:
            case = next_case()
            if case is None:
                yield None
                continue
            factor = plan.reference_limit_factor if case == plan.reference else 1.0
            yield pool.Job(dataclasses.astuple(case), plan.cpu_limit * factor,
                           plan.wall_limit * factor, tag=case)

    log_file = open(log_path, "a") if log_path else subprocess.DEVNULL
    try:
        pool.run("benchmarks.study.runner:work", schedule(), finished, workers=min(jobs, n),
                 warm_up="benchmarks.study.runner:warm_up",
                 warm_up_arg=[dataclasses.astuple(c) for c in warmups], output=log_file)
    finally:
        if log_path:
            log_file.close()
    return records


# --------------------------------------------------------------------------- the study


def run_study(plan: Plan, out: Path, jobs: int = 1, log: Callable[[str], None] = print,
              command: str = "") -> list[dict]:
    """Run the plan, post-process, write CSV, plots and the report into ``out``."""
    from .report import report
    out = Path(out)
    (out / "study").mkdir(parents=True, exist_ok=True)
    started = datetime.datetime.now().astimezone()
    t0, load0 = time.perf_counter(), os.getloadavg()
    log(f"study '{plan.name}': {len(plan.cases)} runs on {jobs} worker(s), limits "
        f"{plan.cpu_limit:.0f} s CPU / {plan.wall_limit:.0f} s wall per run")
    partial = out / "study" / "runs.partial.jsonl"
    partial.write_text("")

    def progress(rec: dict, k: int, n: int) -> None:
        with partial.open("a") as f:
            f.write(json.dumps(rec, default=str) + "\n")
        err = ERRORS[rec["benchmark"]][0]
        e = rec.get(err, "")
        log(f"[{k}/{n}] {rec['benchmark']} {rec['method']} {rec['smoothing']} "
            f"{rec['enforcement']} {rec['level_label']}: {rec['status']}"
            + (f", {err} {e:.3g}" if isinstance(e, float) else "")
            + (f", CPU {rec['cpu_time']:.1f} s" if isinstance(rec['cpu_time'], float) else "")
            + ("" if rec["status"] == "converged" else f" -- {str(rec['message'])[:160]}"))

    records = run_cases(plan, jobs, progress, log_path=out / "study" / "workers.log")
    finalize_rings(records, plan.reference)
    meta = dict(plan=plan.name, command=command or "benchmarks.study (Python API)",
                started=started.isoformat(timespec="seconds"),
                duration=time.perf_counter() - t0, jobs=jobs, load_before=load0,
                load_after=os.getloadavg(), cpu_limit=plan.cpu_limit,
                wall_limit=plan.wall_limit, left_out=plan.left_out, environment=_environment(),
                requested=["/".join(map(str, c.key)) for c in plan.cases])
    write_csv(records, out / "study" / "runs.csv")
    curves = {key_str(r): r["curve"] for r in records if r.get("curve")}
    (out / "study" / "reaction_curves.json").write_text(json_lines(curves))
    (out / "study" / "meta.json").write_text(json.dumps(meta, indent=1) + "\n")
    partial.unlink(missing_ok=True)
    wlog = out / "study" / "workers.log"
    if wlog.exists() and wlog.stat().st_size == 0:
        wlog.unlink()
    report(out, log)
    return records


def _environment() -> dict:
    env = {"python": platform.python_version(), "cpus": os.cpu_count(),
           "machine": platform.machine()}
    try:
        import dolfinx
        env["dolfinx"] = dolfinx.__version__
    except Exception:
        pass
    try:
        git = lambda *a: subprocess.run(["git", *a], cwd=ROOT, capture_output=True,  # noqa: E731
                                        text=True).stdout
        env["commit"] = git("rev-parse", "--short", "HEAD").strip()
        # uncommitted changes of the package itself change the numbers: say which
        env["modified"] = [line[3:] for line in git("status", "--porcelain").splitlines()
                           if line[3:].startswith("fenicsx_mortar/") and line[:2].strip() != "??"]
    except OSError:
        pass
    return env
