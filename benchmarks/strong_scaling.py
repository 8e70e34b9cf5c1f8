"""Strong scaling of a large Hertz (B2) run, and the cost of the contact surfaces' gather.

What it measures
----------------
1. **Hertz refined to >= 500k dofs**, run with N = 1, 2, ... MPI ranks (``--ranks``): the
   scene ``demos/scenes/hertz.toml`` with the mesh parameters ``--h-contact`` / ``--h-far``
   (defaults 0.0024 = a/20 at the contact, 0.004 elsewhere: ~536k dofs) and ``--steps``
   load steps (default 1). Each N is one ``mpirun -n N`` of this script in ``--worker``
   mode, which calls ``fenicsx_mortar.solve`` and writes, from rank 0, the run's summary
   (what summary.json holds: ``timings`` by phase, per-step records, ``dofs``) plus the
   peak resident memory of every rank (``resource.getrusage(RUSAGE_SELF).ru_maxrss``,
   gathered on rank 0). The run writes no outputs of its own (``out=None``): an XDMF file of
   half a million dofs is not what is measured here.
   Printed: a table with wall time by phase (mesh, jit, bulk assembly, contact and its
   sub-phases search / kernel / insertion, linear solve, total) on every rank (each rank's
   own ``Result.timings``; summary.json holds rank 0's), Newton iterations and peak memory
   per rank, as Markdown (the table of docs/performance.md).

2. **Gather cost versus surface size** (``--gather``, run under ``mpirun -n 2`` by the
   driver): every rank holds both 1D contact surfaces, and at every residual evaluation a
   pair collects the current coordinates of its surface nodes from their owners and sums
   nodal quantities over ranks. Timed here with the package's own calling pattern on
   n = 1e3 ... 1e6 surface nodes split evenly over the ranks:
     * ``allgather``: ``comm.allgather((indices, (k, 2) coordinates))`` and scatter into an
       (n, 2) array (``Surface.displacement``),
     * ``allreduce``: ``comm.allreduce(n-vector, op=MPI.SUM)`` (``PairHook._owned_sum``),
   and, for comparison, their buffer versions ``Allgatherv`` / ``Allreduce``. Median of
   ``--reps`` repetitions (after a warm-up), slowest rank. Fitted per pattern: the
   exponent k of t ~ n^k (log-log least squares over n >= 1e4), the fixed cost (t at the
   smallest n) and the cost per node between the two largest n.

How to run
----------
    .venv/bin/python benchmarks/strong_scaling.py                  # both parts
    .venv/bin/python benchmarks/strong_scaling.py --only gather    # part 2 only, ~1 min
    .venv/bin/python benchmarks/strong_scaling.py --only scaling --ranks 1 2 \\
        --h-contact 0.0024 --h-far 0.004 --steps 1 --work results/strong_scaling

Part 1 takes ~10-15 minutes per N on this 2-core machine (meshing alone ~2 min). The
workers' JSON files stay in ``--work`` (default results/strong_scaling); ``--report`` prints
the table again from them without running anything. The ranks are started by the MPI
launcher of this Python (fenicsx_mortar/mpi_launch.py): Open MPI's ``mpirun -n N
--oversubscribe`` with its root-user variables (harmless when not root), or the venv's
``mpiexec -n N`` with PyPI's MPICH.
"""
from __future__ import annotations

import argparse
import json
import os
import re
import resource
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
if __package__ in (None, ""):
    sys.path.insert(0, str(ROOT))
from fenicsx_mortar.mpi_launch import mpi_command, mpi_env  # noqa: E402

PHASES = [("mesh", "mesh (gmsh, rank 0) + distribution"), ("jit", "forms, JIT, contact set-up"),
          ("bulk_assembly", "bulk assembly"), ("contact", "contact"),
          ("contact_search", "  contact: search"), ("contact_kernel", "  contact: kernel"),
          ("contact_insertion", "  contact: insertion"), ("linear_solve", "linear solve"),
          ("total", "total")]


# ------------------------------------------------------------------------- scene


def scene_text(h_contact: float, h_far: float, steps: int) -> str:
    """demos/scenes/hertz.toml with the mesh sizes and the number of load steps replaced."""
    text = (ROOT / "demos/scenes/hertz.toml").read_text()
    new, k = re.subn(r"params = \{ h_contact = [0-9.e-]+, h_far = [0-9.e-]+ \}",
                     f"params = {{ h_contact = {h_contact!r}, h_far = {h_far!r} }}", text)
    new, j = re.subn(r"\[steps\]\ncount = \d+", f"[steps]\ncount = {steps}", new)
    if k != 1 or j != 1:
        raise SystemExit("demos/scenes/hertz.toml changed: cannot set the mesh sizes/steps")
    return new


# ------------------------------------------------------------------------- workers


def worker_solve(scene_path: str, out_json: str) -> None:
    """Under mpirun: solve the scene, then rank 0 writes the summary + memory per rank."""
    from mpi4py import MPI

    from fenicsx_mortar import load_scene, solve
    comm = MPI.COMM_WORLD
    t0 = time.perf_counter()
    res = solve(load_scene(scene_path), log=print if comm.rank == 0 else (lambda s: None))
    wall = time.perf_counter() - t0
    usage = resource.getrusage(resource.RUSAGE_SELF)
    rss = comm.gather(usage.ru_maxrss / 1024.0, root=0)  # ru_maxrss is in KiB on Linux
    cpu = comm.gather(usage.ru_utime + usage.ru_stime, root=0)
    per_rank = comm.gather(dict(res.timings), root=0)
    if comm.rank == 0:
        summary = dict(res.summary)
        summary["peak_rss_mib_per_rank"] = rss
        summary["timings_per_rank"] = per_rank
        summary["wall_seconds"] = wall
        summary["cpu_seconds_per_rank"] = cpu  # < wall: the rank did not have a core to itself
        summary["host_cpus"] = os.cpu_count()
        summary["load_average_at_end"] = os.getloadavg()
        summary["surface_nodes"] = {p.name: {"slave": p.slave.n, "master": p.master.n}
                                    for p in res.pairs}
        Path(out_json).write_text(json.dumps(summary, indent=1, default=float) + "\n")


def worker_gather(sizes: list[int], reps: int, out_json: str) -> None:
    """Under mpirun: time the surface collectives for each surface size."""
    import numpy as np
    from mpi4py import MPI
    comm = MPI.COMM_WORLD
    P, r = comm.size, comm.rank
    rows = []
    for n in sizes:
        # this rank owns an even share of the n surface nodes (contiguous indices)
        lo, hi = n * r // P, n * (r + 1) // P
        idx = np.arange(lo, hi, dtype=np.int64)
        vals = np.random.default_rng(r).random((hi - lo, 2))
        vec = np.where((np.arange(n) >= lo) & (np.arange(n) < hi), 1.0, 0.0)
        counts = np.array([2 * (n * (q + 1) // P - n * q // P) for q in range(P)])
        displs = np.concatenate([[0], np.cumsum(counts)[:-1]])

        def allgather_pickled():
            out = np.empty((n, 2))
            for i, v in comm.allgather((idx, vals)):
                out[i] = v
            return out

        def allreduce_pickled():
            return comm.allreduce(vec, op=MPI.SUM)

        def allgatherv_buffer():
            out = np.empty((n, 2))
            comm.Allgatherv(vals, [out, counts, displs, MPI.DOUBLE])
            return out

        def allreduce_buffer():
            out = np.empty(n)
            comm.Allreduce(vec, out, op=MPI.SUM)
            return out

        for name, f in (("allgather", allgather_pickled), ("allreduce", allreduce_pickled),
                        ("Allgatherv", allgatherv_buffer), ("Allreduce", allreduce_buffer)):
            check = f()  # warm-up, and a check that the pattern does what it claims
            if name in ("allgather", "Allgatherv"):
                assert check.shape == (n, 2)
            else:
                assert np.allclose(check, 1.0)
            times = []
            for _ in range(reps):
                comm.Barrier()
                t = time.perf_counter()
                f()
                times.append(time.perf_counter() - t)
            slowest = comm.allreduce(float(np.median(times)), op=MPI.MAX)
            rows.append({"pattern": name, "n": n, "seconds": slowest})
    if r == 0:
        Path(out_json).write_text(json.dumps({"ranks": P, "reps": reps, "rows": rows},
                                             indent=1) + "\n")


# ------------------------------------------------------------------------- driver


def mpirun(n: int, args: list[str], log_path: Path) -> None:
    cmd = ([] if n == 1 else mpi_command(n)) + [sys.executable, *args]
    print("  $", " ".join(cmd), flush=True)
    with open(log_path, "w") as log:
        proc = subprocess.run(cmd, stdout=log, stderr=subprocess.STDOUT, cwd=ROOT,
                              env=mpi_env())
    if proc.returncode != 0:
        raise SystemExit(f"run failed (exit {proc.returncode}), see {log_path}")


def scaling_table(work: Path, ranks: list[int]) -> str:
    runs = {n: json.loads((work / f"hertz_n{n}.json").read_text()) for n in ranks
            if (work / f"hertz_n{n}.json").is_file()}
    if not runs:
        return "(no results in %s)" % work
    first = next(iter(runs.values()))
    surfaces = ", ".join(f"{k}: {v['slave']} slave + {v['master']} master nodes"
                         for k, v in first.get("surface_nodes", {}).items())
    lines = [f"Hertz (B2), {first['dofs']} dofs, {len(first['steps'])} load step(s); "
             f"surfaces {surfaces or '?'}", "",
             "| phase (wall s, rank 0 / rank 1 / ...) | "
             + " | ".join(f"N = {n}" for n in runs) + " |",
             "|---|" + "---:|" * len(runs)]
    for key, label in PHASES:
        cells = [" / ".join(f"{t.get(key, float('nan')):.1f}" for t in r["timings_per_rank"])
                 for r in runs.values()]
        lines.append(f"| {label} | " + " | ".join(cells) + " |")
    lines.append("| Newton iterations (per step) | " + " | ".join(
        "/".join(str(s["newton_iterations"]) for s in r["steps"]) for r in runs.values()) + " |")
    lines.append("| augmentations (per step) | " + " | ".join(
        "/".join(str(s["augmentations"]) for s in r["steps"]) for r in runs.values()) + " |")
    lines.append("| peak memory per rank (MiB) | " + " | ".join(
        ", ".join(f"{m:.0f}" for m in r["peak_rss_mib_per_rank"]) for r in runs.values()) + " |")
    if all("cpu_seconds_per_rank" in r for r in runs.values()):
        lines.append("| CPU time / wall time per rank | " + " | ".join(
            ", ".join(f"{c / r['wall_seconds']:.2f}" for c in r["cpu_seconds_per_rank"])
            for r in runs.values()) + " |")
    base = runs.get(1)
    if base is not None:
        lines.append("| speed-up of total vs N = 1 | " + " | ".join(
            f"{base['timings']['total'] / r['timings']['total']:.2f}" for r in runs.values())
            + " |")
    lines.append("| load average at the end (1 min) | " + " | ".join(
        f"{r['load_average_at_end'][0]:.1f}" for r in runs.values()) + " |")
    return "\n".join(lines)


def gather_table(work: Path) -> str:
    import numpy as np
    path = work / "gather.json"
    if not path.is_file():
        return "(no gather results in %s)" % work
    data = json.loads(path.read_text())
    rows = data["rows"]
    sizes = sorted({r["n"] for r in rows})
    patterns = list(dict.fromkeys(r["pattern"] for r in rows))
    t = {(r["pattern"], r["n"]): r["seconds"] for r in rows}
    lines = [f"Surface collectives at N = {data['ranks']} (median of {data['reps']}, slowest "
             "rank), milliseconds", "",
             "| n (surface nodes) | " + " | ".join(patterns) + " |",
             "|---:|" + "---:|" * len(patterns)]
    for n in sizes:
        lines.append(f"| {n:.0e} | " + " | ".join(f"{1e3 * t[p, n]:.3f}" for p in patterns)
                     + " |")
    lines += ["", "| pattern | t at the smallest n (us) | exponent k of t ~ n^k, n >= 1e4 | "
              "cost per node between the two largest n (ns) |", "|---|---:|---:|---:|"]
    for p in patterns:
        n = np.array(sizes, dtype=float)
        y = np.array([t[p, s] for s in sizes])
        big = n >= 1e4
        k = np.polyfit(np.log(n[big]), np.log(y[big]), 1)[0] if big.sum() >= 2 else np.nan
        c = (y[-1] - y[-2]) / (n[-1] - n[-2])
        lines.append(f"| {p} | {1e6 * y[0]:.0f} | {k:.2f} | {1e9 * c:.1f} |")
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--only", choices=["scaling", "gather"], action="append")
    ap.add_argument("--ranks", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--h-contact", type=float, default=0.0024)
    ap.add_argument("--h-far", type=float, default=0.004)
    ap.add_argument("--steps", type=int, default=1)
    ap.add_argument("--sizes", type=int, nargs="+",
                    default=[1000, 3000, 10000, 30000, 100000, 300000, 1000000])
    ap.add_argument("--gather-ranks", type=int, default=2)
    ap.add_argument("--reps", type=int, default=21)
    ap.add_argument("--work", type=Path, default=ROOT / "results/strong_scaling")
    ap.add_argument("--report", action="store_true", help="print the tables from --work only")
    ap.add_argument("--worker", nargs="+", help=argparse.SUPPRESS)
    a = ap.parse_args()
    if a.worker:
        if a.worker[0] == "solve":
            return worker_solve(a.worker[1], a.worker[2])
        return worker_gather(a.sizes, a.reps, a.worker[1])

    parts = a.only or ["scaling", "gather"]
    a.work.mkdir(parents=True, exist_ok=True)
    me = str(Path(__file__).resolve())
    if not a.report:
        if "scaling" in parts:
            scene = a.work / "hertz_large.toml"
            scene.write_text(scene_text(a.h_contact, a.h_far, a.steps))
            for n in a.ranks:
                print(f"Hertz, N = {n} ...", flush=True)
                mpirun(n, [me, "--worker", "solve", str(scene), str(a.work / f"hertz_n{n}.json")],
                       a.work / f"hertz_n{n}.log")
        if "gather" in parts:
            print(f"gather, N = {a.gather_ranks} ...", flush=True)
            mpirun(a.gather_ranks, [me, "--sizes", *map(str, a.sizes), "--reps", str(a.reps),
                                    "--worker", "gather", str(a.work / "gather.json")],
                   a.work / "gather.log")
    if "scaling" in parts:
        print(scaling_table(a.work, a.ranks) + "\n")
    if "gather" in parts:
        print(gather_table(a.work))


if __name__ == "__main__":
    main()
