"""What one Newton iteration costs as the problem grows (issue 30): the saddle-point MUMPS
solve against the condensed dual multipliers (docs/condensation.md) solved by MUMPS or by
GMRES + algebraic multigrid, on Hertz (B2) and a large-sliding case (B3 half-rings), at
~100k, ~500k and ~2M dofs, serially and on 2 MPI ranks.

One configuration per call::

    python -m benchmarks.scaling --case hertz --dofs 2M --solver amg [--ranks 2]

runs it in a fresh process (under ``mpirun -n 2`` with ``--ranks 2``), stores its record in
``--work`` (default results/scaling) and ends with one line::

    scaling: case=hertz dofs=1961796 solver=amg newton=9 s_per_newton=... assembly_s=...
             peak_mib=... total_s=...

(dofs as built; newton = the Newton iterations of the converged steps; wall seconds:
s_per_newton = the load steps' wall time over every Newton iteration done, those of
failed attempts (before a cut) included, assembly_s = one bulk Jacobian assembly, timed
after the solve (the median of 5), the slowest rank; peak_mib = the largest peak resident
memory of a rank; total_s = the process from its start, meshing included, to the end of the solve.)
``--all`` runs every configuration not stored yet, one at a time; ``--report`` prints the
table, writes it into docs/performance.md between its ``scaling`` markers (keeping the
rows there whose configuration has no record in ``--work``: measured earlier, elsewhere)
and draws docs/scaling.png (time per Newton iteration against dofs).

Solvers: ``mumps`` the saddle point [u, λ] with MUMPS (the default), ``condensed-mumps``
the condensed displacement system with MUMPS, ``amg`` the condensed system with GMRES and
PETSc's GAMG (``"gmres-gamg"``), ``gmg`` with GMRES and a geometric multigrid on the meshes
the Hertz mesh was refined from (``"gmres-gmg"``; Hertz from 500k, not sliding: its
structured grids are not made by refinement); docs/condensation.md §6.
Cases: ``hertz`` — demos/scenes/hertz.toml, one load step, on a uniform mesh h = 0.0164
refined 1, 2, 3 times (gmsh, new boundary nodes on the arc);
``sliding`` — demos/scenes/half_rings.toml (frictionless, docs/benchmarks.md B3) with its
structured grids scaled to the size, pressed in two steps and turned by 5 % and 10 % of
its full turn (the slave slides along the master, past new master nodes: the contact
couplings change as it goes).

Recorded per run: Newton iterations (of the converged steps, and of the failed attempts:
the table's "+ k failed"), linear (Krylov) iterations per Newton step, wall and
CPU seconds by phase (bulk assembly, contact — the condensation included —, linear solve),
per Newton iteration, peak memory of every rank, the load average at the end, and the
nodal pressures (for the comparison between solvers: ``--report`` prints their largest
difference relative to the peak pressure against the saddle-point run, or the condensed
MUMPS one where the saddle point was not run).
"""
from __future__ import annotations

import argparse
import json
import math
import os
import resource
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
MPI_ENV = {"OMPI_ALLOW_RUN_AS_ROOT": "1", "OMPI_ALLOW_RUN_AS_ROOT_CONFIRM": "1",
           "OMPI_MCA_rmaps_base_oversubscribe": "1", "OMP_NUM_THREADS": "1"}
SIZES = {"100k": 100_000, "500k": 500_000, "2M": 2_000_000}
CASES = ("hertz", "sliding")
SOLVERS = ("mumps", "condensed-mumps", "amg", "gmg")
#: the Hertz family: uniform h, refined k times (k = 1, 2, 3: 124k, 495k, 1.98M dofs). The
#: geometric multigrid gets a coarsest mesh of 31k dofs; h = 0.0082 refined twice left it
#: 124k (MUMPS: 38 ms a solve, 0.64 s a factorization): at 2M 2.14-2.21 s a Newton
#: iteration against 2.30-2.34 (docs/condensation.md §6)
HERTZ_H, HERTZ_DOFS0 = 0.0164, 123_636 / 4
#: assemblies timed for assembly_s (their median)
ASSEMBLY_REPEATS = 5
#: the half-rings grids at scale f: (4f x 32f, 4f x 60f) cells
RINGS = (4, 32, 4, 60)
TABLE_BEGIN, TABLE_END = "<!-- scaling:begin -->", "<!-- scaling:end -->"


def parse_dofs(text: str) -> int:
    if text in SIZES:
        return SIZES[text]
    return int(float(text.lower().replace("k", "e3").replace("m", "e6")))


def linear_solver(name: str) -> str:
    return {"amg": "gmres-gamg", "gmg": "gmres-gmg"}.get(name, name)


# ------------------------------------------------------------------------- scenes


def scene(case: str, dofs: int):
    """The scene of ``case`` with about ``dofs`` displacement dofs."""
    from fenicsx_mortar import load_scene
    if case == "hertz":
        k = max(0, min(4, round(math.log(dofs / HERTZ_DOFS0, 4))))
        sc = load_scene(ROOT / "demos/scenes/hertz.toml")
        sc.mesh.params = {"h_contact": HERTZ_H, "h_far": HERTZ_H, "refine": k}
        sc.steps.count = 1
    elif case == "sliding":
        fr, fc, mr, mc = RINGS
        per_f2 = 2 * (fr * fc + mr * mc)             # dofs ≈ per_f2 f² for large f
        f = max(1, round(math.sqrt(dofs / per_f2)))
        sc = load_scene(ROOT / "demos/scenes/half_rings.toml")
        sc.mesh.params = {"fixed_nr": fr * f, "fixed_nc": fc * f,
                          "moving_nr": mr * f, "moving_nc": mc * f}
        sc.steps.times = [0.5, 1.0, 1.05, 1.1]
    else:
        raise SystemExit(f"--case {case!r}: one of {', '.join(CASES)}")
    sc.output.xdmf = sc.output.plots = False
    return sc


# ------------------------------------------------------------------------- worker


def worker(case: str, dofs: int, solver: str, out_json: Path) -> None:
    """Solve one configuration (under mpirun when N > 1) and write its record (rank 0)."""
    t_start = time.perf_counter()
    import numpy as np
    from mpi4py import MPI

    from fenicsx_mortar import _dolfinx as dx
    from fenicsx_mortar import condensation, newton, stepping, timings
    from fenicsx_mortar import solve

    comm = MPI.COMM_WORLD
    cpu: dict[str, float] = {}
    enter, leave = timings._Phase.__enter__, timings._Phase.__exit__

    def phase_enter(self):
        self.c0 = time.process_time()
        return enter(self)

    def phase_exit(self, *exc):
        cpu[self.phase] = cpu.get(self.phase, 0.0) + time.process_time() - self.c0
        return leave(self, *exc)

    timings._Phase.__enter__, timings._Phase.__exit__ = phase_enter, phase_exit
    solvers: list = []
    init = newton.NewtonSolver.__init__

    def keep(self, *args, **kwargs):
        init(self, *args, **kwargs)
        solvers.append(self)

    newton.NewtonSolver.__init__ = keep
    linear_its: list[int] = []
    condensed_solve = condensation.CondensedSystem.solve

    def count(self, b, x, it):
        its, reason = condensed_solve(self, b, x, it)
        linear_its.append(int(its))
        return its, reason

    condensation.CondensedSystem.solve = count
    # every Newton iteration done, a failed attempt's (before its increment was cut) too
    attempted: list[int] = []
    solve_step = newton.NewtonSolver.solve_step

    def counted(self, *args, **kwargs):
        res = solve_step(self, *args, **kwargs)
        attempted.append(int(res.iterations))
        return res

    newton.NewtonSolver.solve_step = counted
    steps_clock = {"wall": 0.0, "cpu": 0.0}
    run_steps = stepping.LoadStepper.run

    def timed_run(self):
        w, c = time.perf_counter(), time.process_time()
        try:
            return run_steps(self)
        finally:
            steps_clock["wall"] += time.perf_counter() - w
            steps_clock["cpu"] += time.process_time() - c

    stepping.LoadStepper.run = timed_run
    sc = scene(case, dofs)
    sc.solver.linear_solver = linear_solver(solver)
    res = solve(sc, log=print if comm.rank == 0 else (lambda s: None))
    total = time.perf_counter() - t_start
    # one bulk Jacobian assembly, timed alone (the floor of a Newton iteration), into a
    # fresh matrix of the bulk form (the run closed its solver, its matrices are
    # destroyed): the median of ASSEMBLY_REPEATS, as the run's assemblies into a matrix
    # whose memory is touched already (the first into a new one took 0.82 s at 2M, the
    # others 0.71)
    system = solvers[-1].system
    matrix = dx.create_matrix(system.jacobian_form)
    samples = []
    for _ in range(ASSEMBLY_REPEATS):
        comm.Barrier()
        t0 = time.perf_counter()
        dx.assemble_jacobian(matrix, system.jacobian_form, system.bcs)
        samples.append(comm.allreduce(time.perf_counter() - t0, op=MPI.MAX))
    assembly = float(np.median(samples))
    matrix.destroy()
    usage = resource.getrusage(resource.RUSAGE_SELF)
    peak = comm.gather(usage.ru_maxrss / 1024.0, root=0)
    per_rank = comm.gather({"wall": dict(res.timings), "cpu": cpu,
                            "steps_wall": steps_clock["wall"],
                            "steps_cpu": steps_clock["cpu"]}, root=0)
    pair = res.pairs[0]
    d = pair.interface()
    if comm.rank != 0:
        return
    n_newton = sum(s["newton_iterations"] for s in res.steps)
    record = {
        "case": case, "dofs": res.summary["dofs"], "solver": solver,
        "linear_solver": solvers[-1].settings.linear_solver, "ranks": comm.size,
        "converged": res.converged, "message": res.message,
        "steps": len(res.steps), "newton": n_newton,
        "newton_per_step": [s["newton_iterations"] for s in res.steps],
        "cuts": sum(s["cuts"] for s in res.steps),
        "linear_its": linear_its or [1] * sum(attempted),
        "newton_attempted": sum(attempted),
        "s_per_newton": per_rank[0]["steps_wall"] / max(sum(attempted), 1),
        "assembly_s": assembly, "peak_mib": max(peak), "peak_mib_per_rank": peak,
        "total_s": total, "per_rank": per_rank,
        "load_average_at_end": os.getloadavg(), "host_cpus": os.cpu_count(),
        "active_nodes": int(np.sum(d["active"])), "slave_nodes": pair.slave.n,
    }
    out_json.write_text(json.dumps(record, indent=1, default=float) + "\n")
    np.savez(out_json.with_suffix(".npz"), x=d["x"], pressure=d["pressure"])


# ------------------------------------------------------------------------- driver


def record_path(work: Path, case: str, dofs: int, solver: str, ranks: int) -> Path:
    label = next((k for k, v in SIZES.items() if v == dofs), str(dofs))
    return work / f"{case}_{label}_{solver}_n{ranks}.json"


def run_one(case: str, dofs: int, solver: str, ranks: int, work: Path) -> dict:
    work.mkdir(parents=True, exist_ok=True)
    out = record_path(work, case, dofs, solver, ranks)
    cmd = [sys.executable, "-m", "benchmarks.scaling", "--worker", "--case", case,
           "--dofs", str(dofs), "--solver", solver, "--out", str(out)]
    if ranks > 1:
        cmd = ["mpirun", "-n", str(ranks), "--oversubscribe", *cmd]
    log = out.with_suffix(".log")
    with open(log, "w") as f:
        proc = subprocess.run(cmd, stdout=f, stderr=subprocess.STDOUT, cwd=ROOT,
                              env={**os.environ, **MPI_ENV})
    if proc.returncode != 0 or not out.is_file():
        raise SystemExit(f"scaling: {case} {dofs} {solver} N={ranks} failed "
                         f"(exit {proc.returncode}); see {log}")
    return json.loads(out.read_text())


def line(r: dict) -> str:
    return (f"scaling: case={r['case']} dofs={r['dofs']} solver={r['solver']} "
            f"newton={r['newton']} s_per_newton={r['s_per_newton']:.3g} "
            f"assembly_s={r['assembly_s']:.3g} peak_mib={r['peak_mib']:.0f} "
            f"total_s={r['total_s']:.1f}")


def load(work: Path) -> list[dict]:
    out = []
    for p in sorted(work.glob("*.json")):
        r = json.loads(p.read_text())
        r["path"] = p
        out.append(r)
    return out


def pressure_difference(r: dict, runs: list[dict]) -> tuple[float, str] | None:
    """Largest nodal pressure difference to the saddle-point run of the same case, size
    and ranks (else the condensed MUMPS one), relative to the peak pressure."""
    import numpy as np
    for ref_solver in ("mumps", "condensed-mumps"):
        ref = [q for q in runs if "path" in q and q["case"] == r["case"]
               and q["dofs"] == r["dofs"]
               and q["solver"] == ref_solver and q["ranks"] == r["ranks"]]
        if ref and ref[0]["path"] != r["path"]:
            a = np.load(r["path"].with_suffix(".npz"))["pressure"]
            b = np.load(ref[0]["path"].with_suffix(".npz"))["pressure"]
            if a.shape == b.shape:
                return float(np.abs(a - b).max() / np.abs(b).max()), ref_solver
    return None


def newton_cell(r: dict) -> str:
    """The Newton iterations of the converged steps, and those of failed attempts."""
    failed = r.get("newton_attempted", r["newton"]) - r["newton"]
    return f"{r['newton']}" + (f" + {failed} failed" if failed else "")


#: the phases of the table; the library times bulk assembly and the linear solve by wall
#: clock only (newton.py), so their CPU column is "—"
PHASES = ("bulk_assembly", "contact", "linear_solve")


def table(runs: list[dict]) -> str:
    head = ("| case | dofs | solver | N | Newton | linear its / Newton step (mean, max) "
            "| s / Newton | bulk / contact / linear solve, s / Newton (wall) "
            "| same, CPU s | 1 Jacobian assembly, s | s / Newton ÷ assembly "
            "| peak MiB (largest rank) | total s | Δp vs reference | load |")
    lines = [head, "|" + "---|" * 15]
    for r in sorted(runs, key=lambda q: (q["case"], q["dofs"], q["ranks"],
                                         SOLVERS.index(q["solver"]))):
        if "row" in r:
            lines.append(r["row"])
            continue
        n = max(r.get("newton_attempted", r["newton"]), 1)
        w, c = r["per_rank"][0]["wall"], r["per_rank"][0]["cpu"]
        its = r["linear_its"]
        diff = pressure_difference(r, runs)
        lines.append(
            f"| {r['case']} | {r['dofs']:,} "
            f"| {r['solver'] if r['converged'] else r['solver'] + ' (did not complete)'} "
            f"| {r['ranks']} | {newton_cell(r)} "
            f"| {sum(its) / len(its):.1f}, {max(its)} "
            f"| {r['s_per_newton']:.2f} "
            f"| {w.get('bulk_assembly', 0) / n:.2f} / {w.get('contact', 0) / n:.2f} / "
            f"{w.get('linear_solve', 0) / n:.2f} "
            f"| {' / '.join(f'{c[k] / n:.2f}' if k in c else '—' for k in PHASES)} "
            f"| {r['assembly_s']:.2f} | {r['s_per_newton'] / r['assembly_s']:.1f} "
            f"| {r['peak_mib']:.0f} | {r['total_s']:.0f} "
            f"| {'—' if diff is None or not r['converged'] else f'{diff[0]:.1e} ({diff[1]})'} "
            f"| {r['load_average_at_end'][0]:.1f} |")
    return "\n".join(lines)


def plot(runs: list[dict], path: Path) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(1, len(CASES), figsize=(11, 4.2), sharey=True)
    for ax, case in zip(axes, CASES):
        for solver in SOLVERS:
            for ranks, style in ((1, "-o"), (2, "--s")):
                rs = sorted((r for r in runs if r["case"] == case and r["solver"] == solver
                             and r["ranks"] == ranks), key=lambda r: r["dofs"])
                if rs:
                    ax.loglog([r["dofs"] for r in rs], [r["s_per_newton"] for r in rs],
                              style, label=f"{solver}, N = {ranks}")
        rs = sorted((r for r in runs if r["case"] == case and r["ranks"] == 1
                     and r["solver"] == "amg"), key=lambda r: r["dofs"])
        if rs:
            ax.loglog([r["dofs"] for r in rs], [r["assembly_s"] for r in rs], ":k",
                      label="one Jacobian assembly")
        ax.set_title(case)
        ax.set_xlabel("dofs")
        ax.grid(True, which="both", alpha=0.3)
    axes[0].set_ylabel("wall seconds per Newton iteration")
    axes[-1].legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=120)


def kept_rows(doc_text: str, runs: list[dict]) -> list[dict]:
    """The rows of the table in ``doc_text`` whose configuration has no record in ``runs``
    (measured on another machine or day, their records not here).

    Args:
        doc_text: docs/performance.md's text.
        runs: The records at hand.

    Returns:
        The rows as records with the fields the table and the plot read (and ``row``).
    """
    if TABLE_BEGIN not in doc_text:
        return []
    body = doc_text.split(TABLE_BEGIN, 1)[1].split(TABLE_END, 1)[0]
    have = {(r["case"], r["dofs"], r["solver"], r["ranks"]) for r in runs}
    out = []
    for row in body.strip().splitlines()[2:]:
        cells = [c.strip() for c in row.strip().strip("|").split("|")]
        case, dofs = cells[0], int(cells[1].replace(",", ""))
        solver, ranks = cells[2].split(" (")[0], int(cells[3])
        if (case, dofs, solver, ranks) in have:
            continue
        out.append({"case": case, "dofs": dofs, "solver": solver, "ranks": ranks,
                    "s_per_newton": float(cells[6]), "assembly_s": float(cells[9]),
                    "row": row})
    return out


def report(work: Path) -> None:
    """The table of the records in ``work`` and of the rows already in
    docs/performance.md that no record replaces, written there; docs/scaling.png."""
    doc = ROOT / "docs/performance.md"
    content = doc.read_text()
    runs = load(work)
    if not runs:
        raise SystemExit(f"scaling: no records in {work}")
    runs += kept_rows(content, runs)
    text = table(runs)
    print(text)
    if TABLE_BEGIN in content and TABLE_END in content:
        head, rest = content.split(TABLE_BEGIN, 1)
        _, tail = rest.split(TABLE_END, 1)
        doc.write_text(f"{head}{TABLE_BEGIN}\n{text}\n{TABLE_END}{tail}")
        print(f"(written into {doc.relative_to(ROOT)})")
    plot(runs, ROOT / "docs/scaling.png")
    print("(docs/scaling.png)")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--case", choices=CASES, default="hertz")
    ap.add_argument("--dofs", default="100k", help="100k, 500k, 2M or a number")
    ap.add_argument("--solver", choices=SOLVERS, default="amg")
    ap.add_argument("--ranks", type=int, default=1)
    ap.add_argument("--work", type=Path, default=ROOT / "results/scaling")
    ap.add_argument("--all", action="store_true", help="every configuration not stored")
    ap.add_argument("--report", action="store_true")
    ap.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    ap.add_argument("--out", type=Path, help=argparse.SUPPRESS)
    a = ap.parse_args()
    if a.worker:
        worker(a.case, parse_dofs(a.dofs), a.solver, a.out)
        return
    if a.report:
        report(a.work)
        return
    if a.all:
        for case in CASES:
            for size in SIZES.values():
                for ranks in (1, 2):
                    for solver in SOLVERS:
                        if record_path(a.work, case, size, solver, ranks).is_file() or (
                                solver == "gmg" and (case != "hertz" or size < 400_000)):
                            continue
                        print(line(run_one(case, size, solver, ranks, a.work)), flush=True)
        report(a.work)
        return
    print(line(run_one(a.case, parse_dofs(a.dofs), a.solver, a.ranks, a.work)))


if __name__ == "__main__":
    main()
