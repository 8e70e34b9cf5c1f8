"""B3 half-rings with friction under mesh refinement: is the master-end sawtooth of the hub
reaction an error of the smoothed masters, or of the mesh?

    .venv/bin/python benchmarks/half_rings_refinement.py                 # 4 levels × 3 masters
    .venv/bin/python benchmarks/half_rings_refinement.py --levels 3      # one level (the others
                                                                         # kept from the JSON)
    .venv/bin/python benchmarks/half_rings_refinement.py --levels 0,1 --only bspline
    .venv/bin/python benchmarks/half_rings_refinement.py --redraw        # table + plot from JSON

The run of ``benchmarks/half_rings_smoothing.py`` (μ = 0.3, the scene's Lagrange multipliers,
24 steps, its step control), with both rings refined together: level L has 4·2^L radial
elements in each ring, 32·2^L segments on the master arc and 60·2^L on the slave arc. Masters:
none (the polyline), hermite, bspline. The averaged normals are left out: they follow the
polyline to 2–3 digits in that benchmark.

Per run, over the turn's 20 target states φ_j (as there):
* osc R_x = mean |Δ²R_x| / max |R_x| (the sawtooth measure of docs/friction.md), and the same
  for the force near the master's end F_x,end and the interior force R_x,int;
* the error of R_x against the reference curve, max_j |R_x − R_x^ref| / max_j |R_x^ref| and
  its mean over j, where R_x^ref is the mean of the finest level's runs that completed (no
  master favoured); how far each of them is from that mean (the finest rows of the table)
  bounds how well the reference itself is known.

Expected result: the sawtooth shrinks under refinement for every master, and at every level
the smoothed masters' R_x is at least as close to the reference as the polyline's. If the
polyline's smaller osc at level 0 comes from its faceting (the last chord inside the circle,
a relief next to the corner), its error against the reference is not smaller.

Writes ``docs/half_rings_refinement.json`` (every converged step of every run) and
``docs/half_rings_refinement.png``; per-run logs under ``results/half_rings_refinement/``.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from benchmarks import pool  # noqa: E402
from benchmarks.half_rings_smoothing import (MU, TURN_TARGETS, load_parameters,  # noqa: E402
                                            on_targets, oscillation)

DOCS = ROOT / "docs"
OUT = ROOT / "results" / "half_rings_refinement"
DATA = DOCS / "half_rings_refinement.json"
PNG = DOCS / "half_rings_refinement.png"
MASTERS = ["none", "hermite", "bspline"]


def mesh_params(level: int) -> dict:
    """Generator parameters of refinement level ``level`` (level 0 = the scene's mesh)."""
    k = 2 ** level
    return dict(fixed_nr=4 * k, fixed_nc=32 * k, moving_nr=4 * k, moving_nc=60 * k)


def run_job(job: dict) -> dict:
    from benchmarks.half_rings_smoothing import run_one
    run = run_one(job["name"], MU, job["smoothing"], job["wall_limit"],
                  mesh=mesh_params(job["level"]), out_root=OUT)
    run["level"] = job["level"]
    return run


def turn_curve(run: dict, key: str = "Rx") -> np.ndarray:
    """The component ``key`` at the 20 turn targets (nan where the run did not get)."""
    got = {round(r["time"], 9): r[key] for r in on_targets(run["rows"])}
    return np.array([got.get(round(t, 9), np.nan) for t in TURN_TARGETS])


def error_to(curve: np.ndarray, ref: np.ndarray) -> tuple[float, float]:
    """(max, mean) over the turn of |curve − ref| / max |ref|."""
    d = np.abs(curve - ref) / np.nanmax(np.abs(ref))
    return float(np.nanmax(d)), float(np.nanmean(d))


def reference(runs: list[dict]) -> np.ndarray:
    """R_x^ref: the mean curve of the finest level's runs that completed the path."""
    finest = max(r["level"] for r in runs)
    done = [turn_curve(r) for r in runs if r["level"] == finest and r["completed"]]
    if not done:
        raise SystemExit(f"no run of the finest level ({finest}) completed: no reference")
    return np.mean(done, axis=0)


def table(runs: list[dict]) -> str:
    ref_curve = reference(runs)
    lines = ["| level | master | slave / master segments | completed | Newton/step | osc R_x "
             "| osc F_x,end | osc R_x,int | R_x error max / mean | max p | wall s |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in sorted(runs, key=lambda r: (r["level"], MASTERS.index(r["smoothing"]))):
        m = mesh_params(r["level"])
        osc = {k: oscillation(turn_curve(r, k)[~np.isnan(turn_curve(r, k))])
               for k in ("Rx", "Fx_end", "Rx_int")}
        err = error_to(turn_curve(r), ref_curve)
        newton = np.mean([row["newton"] for row in r["rows"]]) if r["rows"] else np.nan
        lines.append(
            f"| {r['level']} | {r['smoothing']} | {m['moving_nc']} / {m['fixed_nc']} | "
            f"{'yes' if r['completed'] else '**no**'} | {newton:.1f} | {osc['Rx']:.3f} | "
            f"{osc['Fx_end']:.3f} | {osc['Rx_int']:.4f} | {err[0]:.4f} / {err[1]:.4f} | "
            f"{max((row['p_max'] for row in r['rows']), default=np.nan):.3g} | "
            f"{r['wall']:.0f} |")
    return "\n".join(lines)


def plot(runs: list[dict]) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    levels = sorted({r["level"] for r in runs})
    fig, axes = plt.subplots(1, len(levels), figsize=(5 * len(levels), 4.2),
                             constrained_layout=True, squeeze=False)
    colour = {"none": "C3", "hermite": "C0", "bspline": "C2"}
    for a, L in zip(axes[0], levels):
        for r in runs:
            if r["level"] != L:
                continue
            phi = np.degrees([load_parameters(t)[1] for t in TURN_TARGETS])
            a.plot(phi, turn_curve(r), marker="o", ms=3, color=colour[r["smoothing"]],
                   label=r["smoothing"])
        m = mesh_params(L)
        a.set(title=f"level {L}: slave {m['moving_nc']} / master {m['fixed_nc']} segments",
              xlabel="turn angle φ (degrees)", ylabel="hub reaction R_x")
        a.grid(alpha=0.3)
        a.legend(fontsize=8)
    fig.savefig(PNG, dpi=100)
    plt.close(fig)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--levels", default="0,1,2,3", help="comma-separated refinement levels")
    ap.add_argument("--only", default=",".join(MASTERS),
                    help="comma-separated masters to run (the others' saved runs are kept)")
    ap.add_argument("--jobs", type=int, default=2, help="worker processes (at most 2)")
    ap.add_argument("--wall-limit", type=float, default=3600.0, help="per run, seconds")
    ap.add_argument("--redraw", action="store_true", help="no solve: table and plot from JSON")
    args = ap.parse_args()
    OUT.mkdir(parents=True, exist_ok=True)
    if args.redraw:
        runs = json.loads(DATA.read_text())
    else:
        levels = [int(v) for v in args.levels.split(",")]
        unknown = set(args.only.split(",")) - set(MASTERS)
        if unknown:
            ap.error(f"--only: unknown master(s) {sorted(unknown)}; choose from {MASTERS}")
        masters = [m for m in MASTERS if m in args.only.split(",")]
        runs: list[dict] = []

        def finished(out: pool.Outcome) -> None:
            if out.record is None:
                raise RuntimeError(f"[{out.job.tag}] worker died (exit {out.returncode})")
            runs.append(out.record)
            print(f"[{out.job.tag}] {'completed' if out.record['completed'] else 'STOPPED'}"
                  f" in {out.record['wall']:.0f} s", flush=True)
        # the finest level first: its runs are the longest
        jobs = [pool.Job(dict(name=f"L{L}_{s}", level=L, smoothing=s,
                              wall_limit=args.wall_limit), tag=f"L{L}_{s}")
                for L in sorted(levels, reverse=True) for s in masters]
        pool.run("benchmarks.half_rings_refinement:run_job", jobs, finished,
                 workers=max(1, min(args.jobs, 2)), output=None)
        if DATA.exists():  # keep the saved runs not made now
            runs += [r for r in json.loads(DATA.read_text())
                     if r["level"] not in levels or r["smoothing"] not in masters]
        DATA.write_text(json.dumps(runs) + "\n")
    plot(runs)
    print(table(runs))
    finest = [r for r in runs if r["level"] == max(x["level"] for x in runs)]
    for a in finest:
        for b in finest:
            if MASTERS.index(a["smoothing"]) < MASTERS.index(b["smoothing"]):
                e = error_to(turn_curve(a), turn_curve(b))
                print(f"finest level, {a['smoothing']} against {b['smoothing']}: "
                      f"max {e[0]:.4f}, mean {e[1]:.4f}")

if __name__ == "__main__":
    main()
