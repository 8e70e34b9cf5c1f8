"""Accuracy against compute time: ``fenicsx-mortar study [--quick] [--out DIR] [--jobs N]``.

A thin driver around :func:`fenicsx_mortar.solve`. It runs the matrix

    method (nts, mortar) x smoothing (six) x enforcement (penalty at 1, 10, 100 x E/h; alm)
    x mesh level (four per benchmark)

on four benchmarks built from the demo scenes by changing dataclass fields (``make_scene``):

* ``patch``       B1 contact patch test (``demos/scenes/patch_test.toml``), error
                  max over cells of |sigma_yy + 1|;
* ``hertz``       B2 Hertz, slave = the disk's arc, master = the block's flat top
                  (``demos/scenes/hertz.toml``), errors |p_max/p0 - 1| and the relative L2
                  error of the nodal pressure on [-a, a] (as ``demos/demo_hertz.py``);
* ``hertz_mc``    the same with the roles swapped: master = the curved arc (so the master
                  smoothing acts on a curved surface), slave = the block's top;
* ``half_rings``  B3 frictionless half-rings on a shortened load path (press in two steps,
                  then the turn up to t = 1.3 in steps of 0.025, i.e. 30 % of the scene's
                  turn); errors: the hub reaction curve against the reference (the bspline +
                  mortar + alm run on a mesh twice the scene's) and its oscillation.

E/h: the slave body's Young's modulus over the slave element size in the contact zone
(``Level.h``). Step control is the scene's, with a floor at 1/16 of its smallest increment.

The full plan (``full_plan``) leaves out what would only repeat other runs and what has
already failed: averaged-tangent runs at the coarsest level only (in 2D its nodal normal is
averaged-simple's), and a combination that did not converge at the two next coarser levels
is recorded as "skipped" at the finer ones. It takes about 40 min on two shared cores;
``--quick`` (``quick_plan``) a few minutes.

Every run happens in a worker process (``--jobs`` of them, each single-threaded), so a run
that crashes or exceeds the per-run CPU limit is recorded as such and the study goes on. Per
run it records the errors, process CPU time, wall time in total and by phase
(``Result.timings``), Newton iterations, augmentations, cuts and the solver's message.

Outputs, in ``--out`` (default: the repository's ``docs/``; ``--quick``: ``results/study_quick``):
``accuracy-vs-time.md`` (tables), ``study/runs.csv`` (one row per run),
``study/reaction_curves.json`` (B3 curves), ``study/meta.json`` (command, duration, load,
environment), ``study/pareto_<benchmark>.png`` (error against CPU time, log-log, one curve
per method/smoothing). When ``--out`` is the repository's ``docs/``, the headline table in
README.md (between the ``study-headline`` markers) is regenerated too. ``--report-only``
rewrites tables and plots from an existing CSV.
"""
from __future__ import annotations

import csv
import dataclasses
import datetime
import json
import math
import os
import platform
import signal
import subprocess
import sys
import time
import traceback
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Iterable

ROOT = Path(__file__).resolve().parents[1]
SCENES = ROOT / "demos" / "scenes"
DOCS = ROOT / "docs"

METHODS = ("nts", "mortar")
SMOOTHINGS = ("none", "averaged-simple", "averaged-weighted", "averaged-tangent", "hermite",
              "bspline")
# penalty: epsilon = factor * E/h (slave body's E, h = slave element size in the contact zone)
ENFORCEMENTS = ("penalty-1", "penalty-10", "penalty-100", "alm")
BENCHMARKS = ("patch", "hertz", "hertz_mc", "half_rings")

# ---------------------------------------------------------------- analytic Hertz (B2)
# docs/hertz.md: R = 1, F = 1 (traction 0.5 on the flat edge of width 2), E = 1000, nu = 0.3
HERTZ_R, HERTZ_F, HERTZ_E, HERTZ_NU = 1.0, 1.0, 1000.0, 0.3
HERTZ_E_STAR = 1.0 / (2.0 * (1.0 - HERTZ_NU**2) / HERTZ_E)
HERTZ_A = 2.0 * math.sqrt(HERTZ_F * HERTZ_R / (math.pi * HERTZ_E_STAR))
HERTZ_P0 = 2.0 * HERTZ_F / (math.pi * HERTZ_A)
HERTZ_REFINE_RADIUS = 0.1       # uniformly refined zone around the contact point, ~2a

# B3 shortened load path: press (t in [0, 1]) in two steps, then 12 turn steps of 0.025
RINGS_TIMES = [0.5, 1.0] + [round(1.0 + 0.025 * k, 10) for k in range(1, 13)]


@dataclass(frozen=True)
class Level:
    """One mesh size of a benchmark: a label, the slave element size h in the contact zone
    (the penalty scale E/h uses it) and the mesh generator's parameters."""
    label: str
    h: float
    params: dict


def _patch_level(n: int) -> Level:
    # upper block (slave) bottom: 2 long, 20 n elements
    return Level(f"n={n}", 2.0 / (20 * n),
                 dict(lower_nx=16 * n, lower_ny=8 * n, upper_nx=20 * n, upper_ny=4 * n))


def _hertz_level(d: int) -> Level:
    h = HERTZ_A / d
    return Level(f"a/{d}", h, dict(h_contact=h, h_far=0.1, refine_radius=HERTZ_REFINE_RADIUS))


def _rings_level(nr: int, fixed_nc: int, moving_nc: int) -> Level:
    # (4, 32, 60) is the scene's own mesh; slave = the moving ring's outer arc, r = 10
    return Level(f"{nr}x{fixed_nc}/{nr}x{moving_nc}", 10.0 * math.pi / moving_nc,
                 dict(fixed_nr=nr, fixed_nc=fixed_nc, moving_nr=nr, moving_nc=moving_nc))


LEVELS: dict[str, tuple[Level, ...]] = {
    "patch": tuple(_patch_level(n) for n in (1, 2, 3, 4)),
    "hertz": tuple(_hertz_level(d) for d in (2, 4, 8, 16)),
    "hertz_mc": tuple(_hertz_level(d) for d in (2, 4, 8, 16)),
    # levels 0-3 for the matrix, level 4 (twice the scene's mesh) for the reference only
    "half_rings": (_rings_level(2, 16, 30), _rings_level(3, 24, 44), _rings_level(4, 32, 60),
                   _rings_level(5, 40, 76), _rings_level(8, 64, 120)),
}
MATRIX_LEVELS = {"patch": (0, 1, 2, 3), "hertz": (0, 1, 2, 3), "hertz_mc": (0, 1, 2, 3),
                 "half_rings": (0, 1, 2, 3)}
RINGS_REFERENCE = ("half_rings", "mortar", "bspline", "alm", 4)

TITLES = {
    "patch": "B1 contact patch test",
    "hertz": "B2 Hertz, curved slave (disk arc) on a flat master",
    "hertz_mc": "B2 Hertz, curved master (disk arc) under a flat slave",
    "half_rings": "B3 half-rings (press + 30 % of the turn)",
}
# the error a benchmark is ranked by (first) and the others it reports
ERRORS = {
    "patch": ("err_sigma_yy",),
    "hertz": ("err_l2", "err_p0"),
    "hertz_mc": ("err_l2", "err_p0"),
    "half_rings": ("err_reaction", "osc_reaction"),
}
ERROR_LABELS = {
    "err_sigma_yy": "max |σ_yy + 1|",
    "err_l2": "relative L2 pressure error on [−a, a]",
    "err_p0": "|p_max/p₀ − 1|",
    "err_a": "|a_fit/a − 1|",
    "err_reaction": "reaction-curve error vs reference",
    "osc_reaction": "reaction-curve oscillation",
}
PHASES = ("mesh", "jit", "bulk_assembly", "contact", "contact_search", "contact_kernel",
          "contact_insertion", "linear_solve", "output", "total")

COLUMNS = (["benchmark", "method", "smoothing", "enforcement", "level", "level_label", "h",
            "epsilon", "status", "converged", "reached_time", "message",
            "err_sigma_yy", "err_p0", "err_l2", "err_a", "err_force", "err_reaction",
            "osc_reaction", "dofs", "slave_nodes", "active_nodes", "steps", "cuts",
            "newton_iterations", "augmentations", "cpu_time", "wall_time"]
           + [f"t_{p}" for p in PHASES] + ["warnings"])


@dataclass(frozen=True)
class Case:
    benchmark: str
    method: str
    smoothing: str
    enforcement: str
    level: int

    @property
    def key(self) -> tuple:
        return (self.benchmark, self.method, self.smoothing, self.enforcement, self.level)

    def describe(self) -> str:
        return (f"{self.benchmark} {self.method} {self.smoothing} {self.enforcement} "
                f"{LEVELS[self.benchmark][self.level].label}")


@dataclass
class Plan:
    """The cases to run, the per-run limits and what the report says was left out.

    ``skip_after``: a case is not run (recorded as "skipped") when the same combination did
    not converge at the ``skip_after`` next coarser levels of the plan (0: run everything).
    ``reference``: the B3 reference case (never skipped; its CPU limit is
    ``reference_limit_factor`` times the others')."""
    name: str
    cases: list[Case]
    cpu_limit: float = 120.0           # seconds of the worker's CPU time per run
    wall_limit: float = 600.0          # backstop on wall time per run
    left_out: list[str] = field(default_factory=list)
    skip_after: int = 2
    reference: Case | None = None
    reference_limit_factor: float = 4.0


def matrix(benchmarks: Iterable[str] = BENCHMARKS, methods: Iterable[str] = METHODS,
           smoothings: Iterable[str] = SMOOTHINGS, enforcements: Iterable[str] = ENFORCEMENTS,
           levels: dict[str, Iterable[int]] | Iterable[int] | None = None) -> list[Case]:
    """Every combination; ``levels`` as indices into LEVELS[benchmark] (one list for all
    benchmarks or a dict per benchmark; default MATRIX_LEVELS)."""
    out = []
    for b in benchmarks:
        if levels is None:
            lv = MATRIX_LEVELS[b]
        elif isinstance(levels, dict):
            lv = levels.get(b, ())
        else:
            lv = levels
        for m in methods:
            for s in smoothings:
                for e in enforcements:
                    for k in lv:
                        out.append(Case(b, m, s, e, int(k)))
    return out


def reference_case(cases: Iterable[Case]) -> Case | None:
    """B3 reference: the finest-level bspline + mortar + alm run among ``cases``."""
    rings = [c for c in cases if c.benchmark == "half_rings" and c.method == "mortar"
             and c.smoothing == "bspline" and c.enforcement == "alm"]
    return max(rings, key=lambda c: c.level, default=None)


def make_plan(name: str, cases: list[Case], **kw) -> Plan:
    """A plan whose B3 reference is the finest bspline + mortar + alm case in it."""
    return Plan(name, cases, reference=reference_case(cases), **kw)


def full_plan() -> Plan:
    """The documented matrix (2 x 6 x 4 x 4 levels per benchmark), with the reductions
    listed in ``left_out``, and the B3 reference on a mesh twice the scene's."""
    cases = [c for c in matrix() if not (c.smoothing == "averaged-tangent" and c.level > 0)]
    cases.append(Case(*RINGS_REFERENCE))
    return make_plan("full", cases, cpu_limit=120.0, wall_limit=600.0, left_out=[
        "`averaged-tangent` is run at the coarsest level only: in 2D its nodal normal is "
        "that of `averaged-simple` (docs/smoothing.md), and the level-0 runs show the same "
        "errors (table below); at the finer levels its results would repeat "
        "`averaged-simple`'s",
        "a combination that did not converge at the two next coarser levels is not run at a "
        "finer one (status `skipped` in the CSV and the tables)",
        "B3 uses a shortened load path (press, then 30 % of the scene's turn), and its finest "
        "mesh (8x64/8x120, twice the scene's) only for the reference run"])


def quick_plan() -> Plan:
    """A few minutes: the two coarsest levels, two smoothings, two enforcements."""
    cases = matrix(smoothings=("none", "bspline"), enforcements=("penalty-1", "alm"),
                   levels=(0, 1))
    return make_plan("quick", cases, cpu_limit=30.0, wall_limit=120.0, left_out=[
        "levels: only the two coarsest of each benchmark (B3 reference: bspline + mortar + "
        "alm at the second level)",
        "smoothings: only `none` and `bspline`",
        "enforcements: only `penalty-1` and `alm`"])


# ------------------------------------------------------------------------- scene building


def make_scene(case: Case, times: list[float] | None = None):
    """The scene of one run: the demo scene with the case's mesh level, contact method,
    smoothing and enforcement, no file outputs. ``times`` overrides the load steps."""
    from .scene import Enforcement, OutputSettings, load_scene
    b, lv = case.benchmark, LEVELS[case.benchmark][case.level]
    if b == "patch":
        scene = load_scene(SCENES / "patch_test.toml")
    elif b in ("hertz", "hertz_mc"):
        scene = load_scene(SCENES / "hertz.toml")
    elif b == "half_rings":
        scene = load_scene(SCENES / "half_rings.toml")
        scene.steps.times = list(RINGS_TIMES)
        scene.steps.count = None
    else:
        raise ValueError(f"unknown benchmark {b!r}")
    scene.mesh.params = dict(scene.mesh.params, **lv.params)
    pair = scene.contacts[0]
    if b == "hertz_mc":
        pair.slave, pair.master = pair.master, pair.slave
    pair.method, pair.smoothing = case.method, case.smoothing
    tol = pair.enforcement.tolerance
    if case.enforcement == "alm":
        pair.enforcement = Enforcement(type="alm", tolerance=tol)
    else:
        factor = float(case.enforcement.split("-")[1])
        pair.enforcement = Enforcement(type="penalty", epsilon=factor * slave_modulus(scene) / lv.h,
                                       tolerance=tol)
    scene.output = OutputSettings(xdmf=False, plots=False)
    if times is not None:
        scene.steps.times, scene.steps.count = list(times), None
    # a run that needs increments below 1/16 of the scene's smallest one counts as failed
    # (the package default, 1e-4 of the final time, lets a stalled run creep on for minutes)
    targets = scene.steps.targets()
    scene.steps.min_increment = min(b - a for a, b in zip([0.0] + targets, targets)) / 16
    return scene


def slave_modulus(scene) -> float:
    """Young's modulus of the body whose boundary is the slave surface (by group name)."""
    slave = scene.contacts[0].slave
    slave = slave if isinstance(slave, str) else slave[0]
    for body in scene.bodies:
        if slave.startswith(body.group):
            return body.material.E
    return scene.bodies[0].material.E


# ------------------------------------------------------------------------ one run (worker)


def run_case(case: Case, solve_fn: Callable | None = None) -> dict:
    """Solve one case and measure it; never raises (an exception is recorded)."""
    import warnings
    lv = LEVELS[case.benchmark][case.level]
    rec = {c: "" for c in COLUMNS}
    rec.update(benchmark=case.benchmark, method=case.method, smoothing=case.smoothing,
               enforcement=case.enforcement, level=case.level, level_label=lv.label, h=lv.h)
    t0, c0 = time.perf_counter(), time.process_time()
    try:
        if solve_fn is None:
            from . import solve as solve_fn
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
            rec.update(_errors(case, result))
    except (Exception, TimeLimit) as e:  # a failing run is recorded, the study goes on
        rec.update(status="error", converged=False,
                   message=f"{type(e).__name__}: {e}".replace("\n", " ")[:500],
                   cpu_time=time.process_time() - c0, wall_time=time.perf_counter() - t0)
        rec["traceback"] = traceback.format_exc(limit=6)
    return rec


def _errors(case: Case, result) -> dict:
    import numpy as np
    if case.benchmark == "patch":
        s = result.stress.values()
        return {"err_sigma_yy": float(np.abs(s[:, 1, 1] + 1.0).max())}
    if case.benchmark in ("hertz", "hertz_mc"):
        d = result.pairs[0].interface()
        f = result.steps[-1]["contact"][result.scene.contacts[0].name]["force_on_slave"][1]
        return hertz_errors(d["x"], d["pressure"], abs(f))
    return {}


def hertz_errors(x, p, force: float) -> dict:
    """|p_max/p0 - 1|, relative L2 error of the piecewise-linear nodal pressure on [-a, a],
    |a_fit/a - 1| (least-squares fit of p_max sqrt(1 - x^2/a_fit^2)) and |F_c - F|/F; the
    definitions of ``demos/demo_hertz.py::hertz_metrics``."""
    import numpy as np
    from scipy.optimize import minimize_scalar
    a, p0 = HERTZ_A, HERTZ_P0
    order = np.argsort(x)
    x, p = np.asarray(x)[order], np.asarray(p)[order]
    p_max = float(p.max())
    fit = minimize_scalar(
        lambda s: np.sum((p - p_max * np.sqrt(np.clip(1 - x**2 / s**2, 0, None)))**2),
        bounds=(0.5 * a, 2.0 * a), method="bounded", options={"xatol": 1e-10})
    xs = np.linspace(-a, a, 4001)
    exact = p0 * np.sqrt(np.clip(1 - xs**2 / a**2, 0, None))
    l2 = np.sqrt(np.trapz((np.interp(xs, x, p) - exact)**2, xs) / np.trapz(exact**2, xs))
    return {"err_p0": abs(p_max / p0 - 1.0), "err_l2": float(l2),
            "err_a": abs(float(fit.x) / a - 1.0), "err_force": abs(force - HERTZ_F) / HERTZ_F}


# ------------------------------------------------------------------- B3 post-processing


def reaction_errors(curve: list, reference: list) -> tuple[float, float]:
    """(error, oscillation) of a hub reaction curve [[t, Rx, Ry], ...] over RINGS_TIMES.

    error: max over the study's load-step times of |R(t) - R_ref(t)| / max |R_ref|.
    oscillation: over the turn (t in [1, 1.3], 13 equally spaced states), the largest
    distance of R(t) from its least-squares cubic in t, divided by max |R|: 0 for a curve
    as smooth as a cubic, about the wiggle amplitude / max |R| for a curve that wiggles as
    the slave nodes pass the master's nodes."""
    import numpy as np
    R = _at_times(curve)
    osc = float("nan")
    turn = [k for k, t in enumerate(RINGS_TIMES) if t > 1.0 - 1e-12]
    if not np.isnan(R[turn]).any():
        t = np.array(RINGS_TIMES)[turn] - 1.0
        V = np.vander(t, 4)
        fit = V @ np.linalg.lstsq(V, R[turn], rcond=None)[0]
        osc = float(np.linalg.norm(R[turn] - fit, axis=1).max()
                    / np.linalg.norm(R, axis=1).max())
    err = float("nan")
    if reference:
        Rr = _at_times(reference)
        if not (np.isnan(R).any() or np.isnan(Rr).any()):
            err = float(np.linalg.norm(R - Rr, axis=1).max() / np.linalg.norm(Rr, axis=1).max())
    return err, osc


def _at_times(curve: list):
    """Reactions at RINGS_TIMES (rows of NaN where the run did not reach a time)."""
    import numpy as np
    out = np.full((len(RINGS_TIMES), 2), np.nan)
    for t, rx, ry in curve:
        for k, tk in enumerate(RINGS_TIMES):
            if abs(t - tk) < 1e-9:
                out[k] = rx, ry
    return out


# -------------------------------------------------------------------------- worker pool
# Workers are plain subprocesses (``python -m fenicsx_mortar.study --worker FD``): cases go
# to their stdin as JSON lines, records come back as JSON lines on the pipe FD (stdout and
# stderr of the package and of PETSc go to study/workers.log). Nothing needs a __main__
# guard in the caller, a worker that dies takes only its current run with it.

_THREAD_VARS = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")


class TimeLimit(BaseException):
    """Raised in a worker by SIGTERM outside the solver's Newton loop (a BaseException, so
    that no ``except Exception`` on the way swallows it)."""


def _worker_main(fd: int) -> None:
    """Worker process: the first line on stdin lists warm-up cases, then one case per line
    until EOF; one JSON record per case is written to ``fd``."""
    # SIGTERM = the parent's time limit. Inside solve()'s Newton loop the solver turns it into
    # a clean stop; elsewhere during a case it aborts the case; between cases it is ignored.
    busy = [False]

    def on_term(*args):
        if busy[0]:
            raise TimeLimit("stopped by the study's time limit")
    signal.signal(signal.SIGTERM, on_term)
    out = os.fdopen(fd, "w")
    from . import solve
    warmups = [Case(*c) for c in json.loads(sys.stdin.readline())]
    for case in warmups:  # JIT-compiled forms and lazy imports out of the timed runs
        try:
            scene = make_scene(case)
            scene.steps.times, scene.steps.count = scene.steps.targets()[:1], None
            solve(scene, log=lambda s: None)
        except Exception:
            pass
    out.write('"ready"\n')
    out.flush()
    for line in sys.stdin:
        if not line.strip():
            continue
        busy[0] = True
        try:
            rec = run_case(Case(*json.loads(line)))
        finally:
            busy[0] = False
        out.write(json.dumps(rec, default=str) + "\n")
        out.flush()


class _Worker:
    def __init__(self, warmups: list[Case], log_file):
        r, w = os.pipe()
        env = {**os.environ, **{k: "1" for k in _THREAD_VARS}}  # one core per worker
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "fenicsx_mortar.study", "--worker", str(w)],
            stdin=subprocess.PIPE, stdout=log_file, stderr=log_file, pass_fds=(w,), env=env,
            text=True)
        os.close(w)
        os.set_blocking(r, False)
        self.fd, self.buf = r, b""
        self.send(json.dumps([dataclasses.astuple(c) for c in warmups]))
        self.ready = False
        self.case: Case | None = None
        self.t0 = self.cpu0 = 0.0
        self.limit = 0.0
        self.terminated_at: float | None = None

    def send(self, line: str) -> None:
        try:
            self.proc.stdin.write(line + "\n")
            self.proc.stdin.flush()
        except (BrokenPipeError, OSError):
            pass

    def messages(self) -> list:
        """Complete JSON lines received so far."""
        try:
            while True:
                chunk = os.read(self.fd, 1 << 16)
                if not chunk:
                    break
                self.buf += chunk
        except BlockingIOError:
            pass
        *lines, self.buf = self.buf.split(b"\n")
        return [json.loads(x) for x in lines if x.strip()]

    def alive(self) -> bool:
        return self.proc.poll() is None

    def cpu(self) -> float:
        return _process_cpu(self.proc.pid)

    def close(self) -> None:
        try:
            self.proc.stdin.close()
        except OSError:
            pass
        try:
            self.proc.wait(10)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()
        os.close(self.fd)


def _process_cpu(pid: int) -> float:
    """User + system CPU seconds of a process (Linux /proc)."""
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
        return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")
    except (OSError, IndexError, ValueError):
        return 0.0


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
    log_file = open(log_path, "a") if log_path else subprocess.DEVNULL
    records: list[dict] = []

    def done(rec: dict, w: "_Worker | None" = None) -> None:
        if w is not None:
            if w.terminated_at is not None and rec.get("status") != "converged":
                rec["status"] = "timeout"
                rec["message"] = (f"stopped at the time limit ({w.limit:.0f} s CPU / "
                                  f"{plan.wall_limit:.0f} s wall): {rec.get('message', '')}")
            w.case, w.terminated_at = None, None
        records.append(rec)
        status[_key(rec)] = rec["status"]
        if on_record:
            on_record(rec, len(records), n)

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
                done(_record(c, "skipped", "not run: the same combination did not converge "
                             "at levels " + ", ".join(LEVELS[c.benchmark][k].label for k in last)))
                continue
            return c

    workers = [_Worker(warmups, log_file) for _ in range(max(1, min(jobs, n)))]
    deaths_before_ready = 0
    try:
        while todo or any(w.case is not None for w in workers):
            for i, w in enumerate(workers):
                for msg in w.messages():
                    if msg == "ready":
                        w.ready = True
                    elif w.case is not None:
                        done(msg, w)
                if not w.alive():
                    for msg in w.messages():
                        if w.case is not None and msg != "ready":
                            done(msg, w)
                    if w.case is not None:
                        rec = _record(w.case, "crashed", f"worker process died (exit code "
                                                         f"{w.proc.returncode})")
                        rec["wall_time"] = time.perf_counter() - w.t0
                        done(rec, w)
                    if not w.ready:
                        deaths_before_ready += 1
                        if deaths_before_ready > 3:
                            raise RuntimeError("study workers die before they are ready: run "
                                               "`python -m fenicsx_mortar.study --worker 1` "
                                               "to see why")
                    w.close()
                    workers[i] = w = _Worker(warmups, log_file)
                if w.ready and w.case is None and todo:
                    case = next_case()
                    if case is not None:
                        w.case = case
                        w.limit = plan.cpu_limit * (plan.reference_limit_factor
                                                    if case == plan.reference else 1.0)
                        w.t0, w.cpu0 = time.perf_counter(), w.cpu()
                        w.send(json.dumps(dataclasses.astuple(case)))
                if w.case is not None:
                    wall_limit = plan.wall_limit * w.limit / plan.cpu_limit
                    over = (w.cpu() - w.cpu0 > w.limit
                            or time.perf_counter() - w.t0 > wall_limit)
                    if over and w.terminated_at is None:
                        w.terminated_at = time.perf_counter()
                        w.proc.send_signal(signal.SIGTERM)
                    elif w.terminated_at is not None and time.perf_counter() - w.terminated_at > 60:
                        w.proc.kill()
                        w.proc.wait()
            time.sleep(0.05)
    finally:
        for w in workers:
            w.close()
        if log_path:
            log_file.close()
    return records


def _record(case: Case, status: str, message: str) -> dict:
    """A record for a case that produced none itself (skipped, crashed)."""
    lv = LEVELS[case.benchmark][case.level]
    rec = {c: "" for c in COLUMNS}
    rec.update(benchmark=case.benchmark, method=case.method, smoothing=case.smoothing,
               enforcement=case.enforcement, level=case.level, level_label=lv.label, h=lv.h,
               status=status, converged=False, message=message)
    return rec


# --------------------------------------------------------------------------- the study


def run_study(plan: Plan, out: Path, jobs: int = 1, log: Callable[[str], None] = print,
              command: str = "") -> list[dict]:
    """Run the plan, post-process, write CSV, plots and the report into ``out``."""
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
    meta = dict(plan=plan.name, command=command or "fenicsx-mortar study (Python API)",
                started=started.isoformat(timespec="seconds"),
                duration=time.perf_counter() - t0, jobs=jobs, load_before=load0,
                load_after=os.getloadavg(), cpu_limit=plan.cpu_limit,
                wall_limit=plan.wall_limit, left_out=plan.left_out, environment=_environment(),
                requested=["/".join(map(str, c.key)) for c in plan.cases])
    write_csv(records, out / "study" / "runs.csv")
    curves = {_key_str(r): r["curve"] for r in records if r.get("curve")}
    (out / "study" / "reaction_curves.json").write_text(_json_lines(curves))
    (out / "study" / "meta.json").write_text(json.dumps(meta, indent=1) + "\n")
    partial.unlink(missing_ok=True)
    wlog = out / "study" / "workers.log"
    if wlog.exists() and wlog.stat().st_size == 0:
        wlog.unlink()
    report(out, log)
    return records


def _json_lines(d: dict) -> str:
    """A JSON object with one line per key (diff-friendly, compact)."""
    return "{\n" + ",\n".join(f"{json.dumps(k)}: {json.dumps(v)}" for k, v in d.items()) + "\n}\n"


def finalize_rings(records: list[dict], ref: Case | None) -> None:
    """B3 errors: every half-rings curve against the reference run's."""
    reference = None
    if ref is not None:
        for r in records:
            if _key(r) == ref.key and r["status"] == "converged":
                reference = r.get("curve")
    for r in records:
        if r["benchmark"] == "half_rings" and r.get("curve"):
            ok = r["status"] == "converged"
            err, osc = reaction_errors(r["curve"], reference if ok else None)
            r["osc_reaction"] = osc if r["status"] == "converged" else ""
            r["err_reaction"] = err if (reference and r["status"] == "converged") else ""
            r["reference"] = ref is not None and _key(r) == ref.key


def _key(r: dict) -> tuple:
    return (r["benchmark"], r["method"], r["smoothing"], r["enforcement"], int(r["level"]))


def _key_str(r: dict) -> str:
    return "/".join(map(str, _key(r)))


def write_csv(records: list[dict], path: Path) -> None:
    order = {b: i for i, b in enumerate(BENCHMARKS)}
    rows = sorted(records, key=lambda r: (order[r["benchmark"]], METHODS.index(r["method"]),
                                          SMOOTHINGS.index(r["smoothing"]),
                                          ENFORCEMENTS.index(r["enforcement"]), int(r["level"])))
    with path.open("w", newline="") as f:
        w = csv.DictWriter(f, COLUMNS + ["reference"], extrasaction="ignore")
        w.writeheader()
        for r in rows:
            w.writerow({k: _fmt(r.get(k, "")) for k in COLUMNS + ["reference"]})


def _fmt(v):
    if isinstance(v, float):
        return "" if math.isnan(v) else f"{v:.6g}"
    return v


def read_csv(path: Path) -> list[dict]:
    """Rows of runs.csv with numbers as floats ('' stays '')."""
    out = []
    with Path(path).open(newline="") as f:
        for row in csv.DictReader(f):
            r = {}
            for k, v in row.items():
                if k in ("benchmark", "method", "smoothing", "enforcement", "level_label",
                         "status", "message", "warnings"):
                    r[k] = v
                elif k in ("converged", "reference"):
                    r[k] = v == "True"
                else:
                    try:
                        r[k] = float(v) if v != "" else ""
                    except ValueError:
                        r[k] = v
            r["level"] = int(r["level"])
            out.append(r)
    return out


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


# ----------------------------------------------------------------------- report and plots

# Headline budgets: CPU seconds per run within which each benchmark's best error is quoted
BUDGETS = {"patch": (0.5, 2.0), "hertz": (2.0, 10.0), "hertz_mc": (2.0, 10.0),
           "half_rings": (5.0, 30.0)}
_STATUS_MARK = {"failed": "✗", "timeout": "⏱", "error": "✗!", "crashed": "✗✗",
                "skipped": "⊘"}
_COLORS = {"none": "tab:gray", "averaged-simple": "tab:blue", "averaged-weighted": "tab:cyan",
           "averaged-tangent": "tab:purple", "hermite": "tab:orange", "bspline": "tab:red"}
_README_BEGIN = "<!-- study-headline: generated by `fenicsx-mortar study`, do not edit -->"
_README_END = "<!-- /study-headline -->"


def _num(v) -> float:
    return v if isinstance(v, float) and not math.isnan(v) else float("nan")


def _ok(r: dict, err: str) -> bool:
    return r["status"] == "converged" and not math.isnan(_num(r.get(err, "")))


def pareto_front(points: list[tuple[float, float]]) -> list[tuple[float, float]]:
    """Non-dominated (time, error) points: sorted by time, each with a smaller error than
    every cheaper one."""
    front, best = [], float("inf")
    for t, e in sorted(points):
        if e < best:
            front.append((t, e))
            best = e
    return front


def best_within(rows: list[dict], err: str, budget: float) -> dict | None:
    """The converged run with the smallest ``err`` among those with cpu_time <= budget."""
    cands = [r for r in rows if _ok(r, err) and _num(r["cpu_time"]) <= budget
             and not r.get("reference")]
    return min(cands, key=lambda r: r[err], default=None)


def plot_pareto(rows: list[dict], bench: str, path: Path) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    errs = ERRORS[bench]
    fig, axes = plt.subplots(1, len(errs), figsize=(6.2 * len(errs), 4.6), squeeze=False)
    for ax, err in zip(axes[0], errs):
        floor = None
        for m in METHODS:
            for s in SMOOTHINGS:
                sel = [r for r in rows if r["method"] == m and r["smoothing"] == s
                       and _ok(r, err) and not r.get("reference")]
                pts = [(_num(r["cpu_time"]), max(r[err], 1e-16)) for r in sel]
                if not pts:
                    continue
                floor = min([e for _, e in pts] + ([floor] if floor else []))
                ls, mk = ("-", "o") if m == "mortar" else ("--", "s")
                ax.loglog(*zip(*pts), mk, color=_COLORS[s], ms=3, alpha=0.25, mfc="none")
                front = pareto_front(pts)
                ax.loglog(*zip(*front), ls, marker=mk, color=_COLORS[s], ms=4, lw=1.3,
                          label=f"{m} / {s}")
        ax.set_xlabel("CPU time per run [s] (process CPU of the solve)")
        ax.set_ylabel(ERROR_LABELS[err])
        ax.grid(alpha=0.3, which="both")
        ax.set_title(f"{TITLES[bench]}\n{ERROR_LABELS[err]}", fontsize=9)
    handles, labels = axes[0][0].get_legend_handles_labels()
    if handles:
        fig.legend(handles, labels, loc="center right", fontsize=7, frameon=False,
                   title="Pareto front of\nmethod / smoothing", title_fontsize=7)
    fig.tight_layout(rect=(0, 0, 1 - 2.0 / fig.get_figwidth(), 1))
    fig.savefig(path, dpi=110, metadata={"Software": None})
    plt.close(fig)


def _cell(r: dict | None, err: str) -> str:
    if r is None:
        return "—"
    if r["status"] != "converged":
        return f"{_STATUS_MARK.get(r['status'], '✗')} {r['status']}"
    e = _num(r.get(err, ""))
    es = "ref." if r.get("reference") else (f"{e:.2g}" if not math.isnan(e) else "?")
    return f"{es} ({_num(r['cpu_time']):.2g} s)"


def _md_table(header: list[str], rows: list[list[str]]) -> str:
    esc = lambda c: str(c).replace("|", "\\|")  # noqa: E731
    lines = ["| " + " | ".join(map(esc, header)) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(map(esc, row)) + " |" for row in rows]
    return "\n".join(lines)


def _fmt_s(seconds: float) -> str:
    return f"{seconds / 60:.1f} min" if seconds >= 120 else f"{seconds:.0f} s"


def report(out: Path, log: Callable[[str], None] = print) -> str:
    """Write ``out/accuracy-vs-time.md`` and the Pareto plots from ``out/study/runs.csv``
    and ``meta.json``; returns the markdown. With ``out`` = the repository's docs/, also
    the README headline."""
    out = Path(out)
    rows = read_csv(out / "study" / "runs.csv")
    meta = json.loads((out / "study" / "meta.json").read_text())
    benches = [b for b in BENCHMARKS if any(r["benchmark"] == b for r in rows)]
    for b in benches:
        plot_pareto([r for r in rows if r["benchmark"] == b], b, out / "study" / f"pareto_{b}.png")
    text = _markdown(rows, meta, benches)
    (out / "accuracy-vs-time.md").write_text(text)
    if out.resolve() == DOCS.resolve():
        _update_readme(headline_table(rows, benches), _recommendation(rows))
    log(f"wrote {out / 'accuracy-vs-time.md'} and {len(benches)} plots in {out / 'study'}")
    return text


def headline_table(rows: list[dict], benches: list[str]) -> str:
    """Per smoothing: the best primary error reached within each benchmark's CPU budgets."""
    header = ["smoothing"] + [f"{b}: ≤ {B:g} s" for b in benches for B in BUDGETS[b]]
    body = []
    for s in SMOOTHINGS:
        if not any(r["smoothing"] == s for r in rows):
            continue
        line = [s + (" (coarsest level only)" if s == "averaged-tangent" and not any(
            r["smoothing"] == s and r["level"] > 0 for r in rows) else "")]
        for b in benches:
            err = ERRORS[b][0]
            sel = [r for r in rows if r["benchmark"] == b and r["smoothing"] == s]
            for B in BUDGETS[b]:
                r = best_within(sel, err, B)
                line.append("—" if r is None else _err_text(r[err]))
        body.append(line)
    return _md_table(header, body)


def _err_text(e: float) -> str:
    """An error for the tables; below 1e-9 it is round-off (exact to the solver tolerance)."""
    return "< 1e-9" if e < 1e-9 else f"{e:.2g}"


def _recommendation(rows: list[dict]) -> str:
    """Which configuration gives the smallest error within the larger budget, per benchmark."""
    out = []
    for b in BENCHMARKS:
        err = ERRORS[b][0]
        sel = [r for r in rows if r["benchmark"] == b]
        r = best_within(sel, err, BUDGETS[b][-1])
        if r is not None:
            out.append(f"{b}: {r['method']} + {r['smoothing']} + {r['enforcement']} at "
                       f"{r['level_label']} ({ERROR_LABELS[err]} {_err_text(r[err])} in "
                       f"{_num(r['cpu_time']):.2g} s CPU)")
    return "; ".join(out)


def _update_readme(table: str, best: str) -> None:
    readme = ROOT / "README.md"
    text = readme.read_text()
    if _README_BEGIN not in text or _README_END not in text:
        return
    a = text.index(_README_BEGIN) + len(_README_BEGIN)
    b = text.index(_README_END)
    block = f"\n{table}\n\nBest within the larger budget: {best}.\n"
    readme.write_text(text[:a] + block + text[b:])


def _markdown(rows: list[dict], meta: dict, benches: list[str]) -> str:
    env = meta.get("environment", {})
    n_ok = sum(r["status"] == "converged" for r in rows)
    cpu_sum = sum(_num(r["cpu_time"]) for r in rows if not math.isnan(_num(r["cpu_time"])))
    lines = [
        "# What accuracy costs: contact method, smoothing, enforcement and mesh size",
        "",
        f"*Generated by `{meta['command']}` (`fenicsx_mortar/study.py`); do not edit by hand.*",
        f"*This run: started {meta['started']}, took {_fmt_s(meta['duration'])} of wall time "
        f"on {meta['jobs']} worker process(es), {len(rows)} runs ({n_ok} converged), "
        f"{_fmt_s(cpu_sum)} of CPU time in the solves; commit {env.get('commit', '?')}"
        + (f" with uncommitted changes in {len(env['modified'])} package files (listed in "
           "study/meta.json)" if env.get("modified") else "")
        + ", "
        f"DOLFINx {env.get('dolfinx', '?')}, {env.get('cpus', '?')} CPUs, load average "
        f"{meta['load_before'][0]:.1f} before / {meta['load_after'][0]:.1f} after.*",
        "",
        "```sh",
        ".venv/bin/fenicsx-mortar study            # the full matrix below, writes this file",
        ".venv/bin/fenicsx-mortar study --quick    # a subset in a few minutes "
        "(results/study_quick/)",
        ".venv/bin/fenicsx-mortar study --report-only   # tables and plots again from the CSV",
        "```",
        "",
        "Raw data: [`study/runs.csv`](study/runs.csv) (one row per run: errors, CPU and wall "
        "time, time by phase, Newton iterations, augmentations, cuts, status and the solver's "
        "message), [`study/reaction_curves.json`](study/reaction_curves.json) (B3 hub "
        "reactions per load step), [`study/meta.json`](study/meta.json).",
        "",
        "## The matrix",
        "",
        "Every combination of",
        "",
        "* **method**: `nts` (node-to-segment), `mortar` (segment-to-segment);",
        "* **smoothing** of the master surface: " + ", ".join(f"`{s}`" for s in SMOOTHINGS)
        + " (docs/smoothing.md);",
        "* **enforcement**: penalty with ε = 1, 10 and 100 × E/h (`penalty-1`, `penalty-10`, "
        "`penalty-100`; E the slave body's Young's modulus, h the slave element size in the "
        "contact zone; ε above the pair's E/h is reached by continuation: each load step "
        "is solved at E/h first, then with ε ×10 per converged solve, counted as "
        "augmentations), and the augmented Lagrangian `alm` (tolerance 1e-10, the scenes' "
        "default);",
        "* **mesh level**: four per benchmark,",
        "",
        "on four benchmarks, each built from a demo scene by changing dataclass fields only:",
        "",
    ]
    bench_rows = []
    for b in benches:
        lv = sorted({(r["level"], r["level_label"], r["h"]) for r in rows if r["benchmark"] == b})
        bench_rows.append([f"`{b}`", TITLES[b], _SETUPS[b],
                           ", ".join(f"{lab} (h = {h:.3g})" for _, lab, h in lv),
                           "; ".join(ERROR_LABELS[e] for e in ERRORS[b])])
    lines += [_md_table(["benchmark", "", "set-up", "levels", "errors"], bench_rows), ""]
    lines += _definitions(meta)
    lines += ["", "## Headline: best error reached within a CPU budget", "",
              "Per smoothing, the smallest error (first error of each benchmark) of any "
              "converged run — any method, enforcement and level — whose solve took at most "
              "the "
              "budget in process CPU seconds:", "", headline_table(rows, benches), "",
              "Best within the larger budget: " + _recommendation(rows) + ".", ""]
    for b in benches:
        lines += _bench_section(rows, b)
    lines += _failure_section(rows)
    lines += _observations(rows, benches)
    return "\n".join(lines) + "\n"


_SETUPS = {
    "patch": "`patch_test.toml`: lower block 16n × 8n, upper 20n × 4n quads, pressure 1, "
             "one load step",
    "hertz": "`hertz.toml`: slave = disk arc, master = block top; h_c = a/d within 0.1 of "
             "the contact point, h_far = 0.1; 2 load steps",
    "hertz_mc": "`hertz.toml` with slave and master swapped: slave = block top, master = "
                "disk arc; same meshes",
    "half_rings": "`half_rings.toml`, frictionless; load steps t = 0.5, 1 (press), then "
                  "1.025 … 1.3 (turn, 30 % of the scene's); levels: radial × circumferential "
                  "quads of the fixed / moving ring (the scene's own mesh is 4x32/4x60)",
}


def _definitions(meta: dict) -> list[str]:
    left = meta.get("left_out") or []
    return [
        "Errors:",
        "",
        "* **B1** max over the cells of |σ_yy + 1| (Cauchy stress, the exact solution is "
        "σ_yy = −1 everywhere).",
        f"* **B2** (analytic, small strain: a = {HERTZ_A:.5f}, p₀ = {HERTZ_P0:.4f}) "
        "|p_max/p₀ − 1| from the largest nodal pressure and the relative L2 error of the "
        "piecewise-linear nodal pressure against p₀√(1 − x²/a²) on [−a, a], x the "
        "current "
        "slave node positions (the definitions of `demos/demo_hertz.py`; docs/hertz.md). The "
        "CSV also has |a_fit/a − 1| and the force balance |F_c − F|/F. The bulk is Neo-Hooke "
        "(finite strain), so the errors need not converge to exactly 0 (docs/hertz.md: L2 "
        "2.6 %, p₀ 0.6 % at a/20).",
        "* **B3** the hub reaction (R_x, R_y) at the 14 load-step times: error = max_t "
        "|R − R_ref| / max_t |R_ref| against the reference = the finest-level bspline + mortar "
        "+ alm run of the same study (its own error is 0, shown as \"ref.\"); oscillation = the "
        "largest distance of R(t) over the turn from its least-squares cubic in t, over "
        "max |R| (a smooth curve gives ~0, a curve that wiggles as slave nodes pass master "
        "nodes gives the wiggle's relative size).",
        "",
        "Errors are computed only for converged runs; a run that fails is kept in the CSV with "
        "its status (`failed`: the solver stopped, e.g. too many cuts; `timeout`: stopped at "
        f"the per-run limit of {meta['cpu_limit']:.0f} s CPU / {meta['wall_limit']:.0f} s wall; "
        "`error`: an exception; `crashed`: the worker process died; `skipped`: not run, see "
        "below), the pseudo-time reached and the message. Step control: the scenes' own "
        "(halving on failure, `max_cuts`), except that a run whose increment would fall "
        "below 1/16 of the scene's smallest increment stops as failed (`min_increment`; the "
        "package default, 1e-4 of the final time, lets a stalled run creep on for minutes).",
        "",
        "Times: **CPU time** is the process CPU time (user + system) of the `solve()` call in "
        "its worker process, which is single-threaded (OMP/OpenBLAS threads = 1); **wall "
        "time** and the phases are `Result.timings` (wall clock): `bulk_assembly` (UFL residual "
        "and tangent), `contact` (all contact work, of which `contact_search`, `contact_kernel` "
        "= master curve + projection + mortar/NTS integration in one vectorized pass, and "
        "`contact_insertion` into the PETSc vector/matrix), `linear_solve` (MUMPS LU), `mesh`, "
        "`jit`. Each worker first solves one small warm-up run per benchmark (not recorded), so "
        "form compilation and imports are not in the timed runs.",
        "",
        "**Other jobs share this 2-core machine**, and the workers run side by side: wall "
        "times vary with the load (the load average is given above), CPU times much less. "
        "The plots and the budgets therefore use CPU time; the CSV has both.",
        "",
    ] + (["Left out in this run (to keep it within its time):", ""]
         + [f"* {x}" for x in left] + [""] if left else [])


def _bench_section(rows: list[dict], b: str) -> list[str]:
    sel = [r for r in rows if r["benchmark"] == b]
    err = ERRORS[b][0]
    levels = sorted({(r["level"], r["level_label"]) for r in sel})
    idx = {_key(r): r for r in sel}
    lines = [f"## {TITLES[b]}", "", f"![Pareto: {b}](study/pareto_{b}.png)", "",
             f"{ERROR_LABELS[err]} (CPU seconds of the solve) per level; "
             "✗ failed, ⏱ time limit, ⊘ skipped (failed at the two coarser levels), — "
             "not in "
             "the plan:", ""]
    combos = []                        # (method, smoothing, enforcement, runs per level)
    for m in METHODS:
        for s in SMOOTHINGS:
            for e in ENFORCEMENTS:
                cells = [idx.get((b, m, s, e, k)) for k, _ in levels]
                if any(c is not None for c in cells):
                    combos.append((m, s, e, cells))
    head = ["method", "smoothing", "enforcement"] + [lab for _, lab in levels]
    body = [[m, s, e] + [_cell(c, err) for c in cells] for m, s, e, cells in combos]
    lines += [_md_table(head, body), ""]
    for extra in ERRORS[b][1:]:
        body = [[m, s, e] + ["—" if c is None else (f"{c[extra]:.2g}" if _ok(c, extra) else
                                                    _STATUS_MARK.get(c["status"], "?"))
                             for c in cells]
                for m, s, e, cells in combos]
        lines += [f"{ERROR_LABELS[extra]}:", "", _md_table(head, body), ""]
    # cost breakdown at the finest level reached by most runs
    k = max(lv for lv, _ in levels)
    fin = [r for r in sel if r["level"] == k and r["enforcement"] in ("alm", "penalty-1")]
    body = []
    for r in sorted(fin, key=_order):
        w = _num(r["t_total"])
        if math.isnan(w) or w <= 0:
            continue
        pct = lambda p: f"{100 * _num(r[f't_{p}']) / w:.0f} %"  # noqa: E731
        body.append([r["method"], r["smoothing"], r["enforcement"], r["status"],
                     f"{_num(r['cpu_time']):.2f}", f"{w:.2f}", pct("bulk_assembly"),
                     pct("contact"), pct("contact_search"), pct("contact_kernel"),
                     pct("contact_insertion"), pct("linear_solve"),
                     f"{int(_num(r['newton_iterations']))}", f"{int(_num(r['augmentations']))}",
                     f"{int(_num(r['cuts']))}"])
    lines += [f"Cost at the finest level ({levels[-1][1]}), alm and penalty-1: CPU and wall "
              "seconds, share of the wall time by phase (contact = search + kernel + insertion "
              "+ a little bookkeeping), Newton iterations, augmentations and cuts summed over "
              "the load steps:", "",
              _md_table(["method", "smoothing", "enforcement", "status", "CPU s", "wall s",
                         "bulk", "contact", "search", "kernel", "insertion", "linear solve",
                         "Newton", "aug.", "cuts"], body), ""]
    return lines


def _order(r: dict) -> tuple:
    return (BENCHMARKS.index(r["benchmark"]), METHODS.index(r["method"]),
            SMOOTHINGS.index(r["smoothing"]), ENFORCEMENTS.index(r["enforcement"]),
            int(r["level"]))


def _failure_section(rows: list[dict]) -> list[str]:
    bad = [r for r in rows if r["status"] != "converged"]
    lines = ["## Runs that did not converge", ""]
    if not bad:
        return lines + ["None.", ""]
    ran_bad = [r for r in bad if r["status"] != "skipped"]
    counts = {}
    for r in bad:
        counts.setdefault((r["benchmark"], r["method"], r["smoothing"]), []).append(r)
    total = {}
    for r in rows:
        total[(r["benchmark"], r["method"], r["smoothing"])] = total.get(
            (r["benchmark"], r["method"], r["smoothing"]), 0) + 1
    body = [[b, m, s, f"{sum(x['status'] != 'skipped' for x in v)} / "
             f"{sum(x['status'] == 'skipped' for x in v)} / {total[(b, m, s)]}",
             ", ".join(f"{x['enforcement']}@{x['level_label']}" for x in sorted(
                 v, key=lambda x: (ENFORCEMENTS.index(x["enforcement"]), x["level"]))
                 if x["status"] != "skipped")]
            for (b, m, s), v in sorted(counts.items(), key=lambda kv: (
                BENCHMARKS.index(kv[0][0]), METHODS.index(kv[0][1]), SMOOTHINGS.index(kv[0][2])))]
    lines += [f"{len(ran_bad)} runs did not converge and {len(bad) - len(ran_bad)} were skipped, "
              f"of {len(rows)}. Per benchmark, method and smoothing (not converged / skipped / "
              "all; which ran and did not converge):", "",
              _md_table(["benchmark", "method", "smoothing", "count", "which (ran, not converged)"],
                        body), "",
              "Each run that did not converge, with the pseudo-time reached and the solver's "
              "message (shortened):", ""]
    body = []
    for r in sorted(ran_bad, key=_order):
        msg = str(r["message"]).replace("|", "/")
        body.append([r["benchmark"], r["method"], r["smoothing"], r["enforcement"],
                     r["level_label"], r["status"],
                     "" if r["reached_time"] == "" else f"{_num(r['reached_time']):.4g}",
                     msg[:220] + ("…" if len(msg) > 220 else "")])
    lines += [_md_table(["benchmark", "method", "smoothing", "enforcement", "level", "status",
                         "t reached", "message"], body), ""]
    return lines


def _observations(rows: list[dict], benches: list[str]) -> list[str]:
    """Facts read off the table (computed, so they follow the data when it changes)."""
    lines = ["## What the numbers say", ""]

    def pick(**kw):
        return [r for r in rows if all(r[k] == v for k, v in kw.items())]

    def rng(rs, err):
        v = [r[err] for r in rs if _ok(r, err)]
        return (min(v), max(v), len(v)) if v else None

    if "patch" in benches:
        for m in METHODS:
            for group, smooth in (("none / averaged-*", SMOOTHINGS[:4]),
                                  ("hermite / bspline", SMOOTHINGS[4:])):
                rs = [r for r in pick(benchmark="patch", method=m, enforcement="alm")
                      if r["smoothing"] in smooth]
                x = rng(rs, "err_sigma_yy")
                if x:
                    lines.append(f"* B1, {m} + alm, {group}: max |σ_yy + 1| from {x[0]:.1e} to "
                                 f"{x[1]:.1e} over {x[2]} converged runs (all levels).")
        for m in METHODS:
            for e in ENFORCEMENTS[:3]:
                x = rng(pick(benchmark="patch", method=m, enforcement=e, smoothing="none"),
                        "err_sigma_yy")
                if x:
                    lines.append(f"* B1, {m} + {e} + none: {x[0]:.1e} … {x[1]:.1e}.")
    for b in ("hertz", "hertz_mc"):
        if b not in benches:
            continue
        for m in METHODS:
            for s in SMOOTHINGS:
                rs = sorted(pick(benchmark=b, method=m, smoothing=s, enforcement="alm"),
                            key=lambda r: r["level"])
                seq = [f"{r['err_l2']:.3f}" if _ok(r, "err_l2") else
                       _STATUS_MARK.get(r["status"], "?") for r in rs]
                if len(rs) > 1:
                    lines.append(f"* {b}, {m} + {s} + alm, L2 error over the levels: "
                                 + " → ".join(seq) + ".")
    if "half_rings" in benches:
        for s in SMOOTHINGS:
            rs = pick(benchmark="half_rings", smoothing=s)
            osc = rng(rs, "osc_reaction")
            n_bad = sum(r["status"] != "converged" for r in rs)
            if rs:
                lines.append(f"* half_rings, {s}: {len(rs) - n_bad} of {len(rs)} runs converged"
                             + (f"; oscillation {osc[0]:.1e} … {osc[1]:.1e}" if osc else "")
                             + ".")
    # ALM against the softest penalty: same benchmark, method, smoothing and level
    import statistics
    by_key = {_key(r): r for r in rows}
    for b in benches:
        err = ERRORS[b][0]
        cpu, acc = [], []
        for r in rows:
            if r["benchmark"] != b or r["enforcement"] != "alm" or r["status"] != "converged":
                continue
            p = by_key.get(_key(r)[:3] + ("penalty-1", r["level"]))
            if p is not None and p["status"] == "converged" and _num(p["cpu_time"]) > 0:
                cpu.append(_num(r["cpu_time"]) / _num(p["cpu_time"]))
                if _ok(r, err) and _ok(p, err) and p[err] > 0 and not r.get("reference"):
                    acc.append(r[err] / p[err])
        if cpu:
            lines.append(f"* {b}: `alm` takes {statistics.median(cpu):.1f}× the CPU time of "
                         f"`penalty-1` (median over {len(cpu)} pairs of runs that differ only in "
                         "the enforcement)" + (f"; its {ERROR_LABELS[err]} is "
                                                f"{statistics.median(acc):.2g}× the penalty's"
                                                if acc else "") + ".")
    for b in benches:
        for m in METHODS:
            rs = [r for r in rows if r["benchmark"] == b and r["method"] == m]
            ran = [r for r in rs if r["status"] != "skipped"]
            bad = [r for r in ran if r["status"] != "converged"]
            if bad:
                lines.append(f"* {b}, {m}: {len(bad)} of {len(ran)} runs did not converge"
                             + (f" ({len(rs) - len(ran)} more skipped)" if len(rs) > len(ran)
                                else "") + ".")
    # cost of the smoothings: contact kernel time relative to none, same everything else
    ratios = {}
    for r in rows:
        if r["smoothing"] == "none" or r["status"] != "converged":
            continue
        k = _key(r)
        base = by_key.get(k[:2] + ("none",) + k[3:])
        if (base is not None and base["status"] == "converged"
                and _num(base["t_contact_kernel"]) > 0 and _num(base["newton_iterations"]) > 0):
            per_it = (_num(r["t_contact_kernel"]) / max(_num(r["newton_iterations"]), 1)) / (
                _num(base["t_contact_kernel"]) / _num(base["newton_iterations"]))
            ratios.setdefault(r["smoothing"], []).append(per_it)
    if ratios:
        lines.append("* Contact-kernel time per Newton iteration relative to `none` (median over "
                     "all converged pairs of runs differing only in the smoothing): "
                     + ", ".join(f"{s} {statistics.median(v):.1f}×" for s, v in ratios.items())
                     + ".")
    return lines + [""]


def main(argv: list[str] | None = None) -> int:
    import argparse
    ap = argparse.ArgumentParser(prog="fenicsx-mortar study")
    add_arguments(ap)
    return run_from_args(ap.parse_args(argv))


def add_arguments(ap) -> None:
    ap.add_argument("--quick", action="store_true",
                    help="a subset that takes a few minutes (two coarse levels, fewer "
                         "combinations)")
    ap.add_argument("--out", type=Path, default=None,
                    help="output directory (default: docs/ of the repository; with --quick: "
                         "results/study_quick)")
    ap.add_argument("--jobs", type=int, default=2,
                    help="worker processes, one core each (default 2)")
    ap.add_argument("--report-only", action="store_true",
                    help="no runs: rewrite tables and plots from OUT/study/runs.csv")


def run_from_args(args) -> int:
    out = args.out or (ROOT / "results" / "study_quick" if args.quick else DOCS)
    if args.report_only:
        report(out)
        return 0
    plan = quick_plan() if args.quick else full_plan()
    cmd = ("fenicsx-mortar study" + (" --quick" if args.quick else "")
           + (f" --out {args.out}" if args.out else "")
           + (f" --jobs {args.jobs}" if args.jobs != 2 else ""))
    records = run_study(plan, out, args.jobs, command=cmd)
    bad = sum(r["status"] != "converged" for r in records)
    print(f"study done: {len(records)} runs, {bad} not converged; report in "
          f"{out / 'accuracy-vs-time.md'}")
    return 0


if __name__ == "__main__":
    if len(sys.argv) == 3 and sys.argv[1] == "--worker":
        _worker_main(int(sys.argv[2]))
    else:
        sys.exit(main())
