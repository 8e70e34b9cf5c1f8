"""B3 half-rings with Coulomb friction: the whole load path once per master smoothing, and how
smooth the hub reaction curve comes out.

    .venv/bin/python benchmarks/half_rings_smoothing.py              # 7 runs, 2 workers
    .venv/bin/python benchmarks/half_rings_smoothing.py --only hermite,bspline
    .venv/bin/python benchmarks/half_rings_smoothing.py --redraw     # table + plot from the CSV

Problem (docs/benchmarks.md B3, scene ``demos/scenes/half_rings.toml``, the set-up is ours): a
moving half ring (R_i = 8, R_e = 10, 4 × 60 quads; slave: its outer arc) inside a fixed half
ring (R_i = 10, R_e = 12, 4 × 32, clamped cut ends; master: its inner arc), Neo-Hooke
E = 689.56, ν = 0.32, mortar with Lagrange multipliers (the scene's). The moving ring's
inner arc is driven as a rigid hub:
pressed down by 0.5 (pseudo-time t ∈ [0, 1], 4 steps), then turned anticlockwise about the
origin by φ_max = arcsin(0.4) = 0.4115 rad (t ∈ [1, 2], 20 steps of Δφ = φ_max / 20), so the
contact zone slides ≈ 4 along the curved master and the slave's right end slides off the
master's end. Coulomb μ = 0.3, once for each smoothing of the master (none = the polyline,
averaged-simple, averaged-weighted, averaged-tangent, hermite, bspline; docs/smoothing.md),
plus one frictionless run with the polyline as a reference line. The scene's step control
(halve a failed increment, at most 8 cuts in a row) is used unchanged.

Reaction curve (docs/benchmarks.md B3 "Outputs"): the force the hub exerts on the moving ring,
R = (R_x, R_y), and its moment M about the origin, against the load parameter. The issue
asks for the oscillation of F_x = R_x; R_y and M are measured the same way.

Oscillation measure. Sliding phase = the turn, sampled at the scene's 20 target states
t_j = 1 + 0.05 j (φ_j = j φ_max / 20, j = 1 … 20); states added by cut steps are left out, so
every run is sampled at the same φ. t_0 = 1 (the end of the press) is left out too: the first
turn step switches the friction from the press's symmetric pattern to one-way slip, a corner
in every curve that is not an oscillation. With F_j the reaction component at t_j,

    osc(F) = mean_{j=2..19} |F_{j+1} − 2 F_j + F_{j−1}|  /  max_{j=1..20} |F_j|

i.e. the mean change of the curve's slope per turn step, relative to the force level of the
sliding phase. It does not grow with the number of steps for a zig-zag: a curve that jumps
by ±a from step to step gives ≈ 4a / max|F| whatever the step count, while a smooth curve
gives O(Δφ²) (its curvature times Δφ²) — so a smaller number means a smoother curve, and
polyline-induced kinks (slave nodes passing master nodes) show up as a larger number. A run
that stops early is measured over the target states it reached (marked in the table).

Interior force. During the whole turn the slave's right end slides off the master's end (a
corner at polar angle 0 whatever the smoothing): the last slave node still over the master
carries a pressure that grows until it leaves, then the next one takes over, once per slave
spacing (3° of turn ≈ 2.5 turn steps). To see the part of the reaction that the master's
smoothing can change, the nodal contact forces on the slave (normal + tangential, the pair's
own residual terms) are also summed with a weight w(θ) of the node's current polar angle θ:
w = 1 for θ ≤ −20°, 0 for θ ≥ −8°, cos² in between (smooth, so nodes moving through the
taper do not make steps). R_x,int = −Σ w F_x and M_int (its moment about the origin) are
what the hub would carry for the interior contact alone, F_x,end = Σ (1 − w) F_x the x-force
on the slave nodes near the master's end (R_x = R_x,int − F_x,end); osc is applied to them
too (normalized by their own maxima).
(Check: −Σ F_x over all slave nodes equals the hub R_x; the largest relative misfit is
printed.)

Other columns: completed (the solver's verdict), load fraction reached (pseudo-time / 2),
converged steps, cuts (failed increments over the run = steps cut) and steps that needed a
cut, Newton iterations per converged step (summed over its augmentations, if any; mean and
max; the iterations of failed attempts are not included), wall and CPU seconds of the
run (2 workers of ``benchmarks/pool.py`` on a shared 2-core machine).

Expected result: every run completes the path; the smoothed masters (hermite, bspline) give
a visibly and measurably smoother R_x curve (smaller osc) than the polyline (none) — at
least in the interior force, where the master's faceting acts; the end-node sawtooth is a
matter of the master's end, which no smoothing removes. (Measured: all seven runs complete;
the interior force is smoother with B-spline and Hermite, the hub R_x is not — the table and
verdict are in docs/friction.md.)

Writes ``docs/friction_half_rings_smoothing.csv`` (every converged step of every run),
``docs/friction_half_rings_smoothing.png`` (the overlaid curves) and, per run,
``results/half_rings_smoothing/<run>/`` (``run.log`` with the solver's step lines and stop
message, the package's outputs in ``run/``: summary.json, per-step interface CSVs).
"""
from __future__ import annotations

import argparse
import csv
import json
import sys
import time
import traceback
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from benchmarks import pool  # noqa: E402

DOCS = ROOT / "docs"
OUT = ROOT / "results" / "half_rings_smoothing"
CSV = DOCS / "friction_half_rings_smoothing.csv"
PNG = DOCS / "friction_half_rings_smoothing.png"
PHI_MAX, PRESS = 0.41152, 0.5
TURN_TARGETS = [1.0 + 0.05 * j for j in range(1, 21)]
MU = 0.3
SMOOTHINGS = ["none", "averaged-simple", "averaged-weighted", "averaged-tangent",
              "hermite", "bspline"]
# (run name, mu, smoothing); the frictionless polyline run is the reference line
RUNS = [(f"mu0.3_{s}", MU, s) for s in SMOOTHINGS] + [("mu0_none", 0.0, "none")]
COLUMNS = ["run", "mu", "smoothing", "step", "time", "press", "phi", "Rx", "Ry", "M", "N", "T",
           "Rx_int", "M_int", "Fx_end", "active", "stick", "slip", "p_max", "newton",
           "augmentations", "cuts"]
# the taper that keeps the slave nodes near the master's end (at polar angle 0) out of the
# "interior" contact force: weight 1 below TAPER[0] degrees, 0 above TAPER[1], cos² between
TAPER = (-20.0, -8.0)


class Stop(Exception):
    """Stop a run that creeps (the step control keeps cutting) or exceeds its wall limit."""


def load_parameters(t: float) -> tuple[float, float]:
    """(press s, turn φ) at pseudo-time t."""
    return PRESS * min(t, 1.0), PHI_MAX * min(max(t - 1.0, 0.0), 1.0)


def taper(theta_deg: np.ndarray) -> np.ndarray:
    """Weight of a slave node in the interior contact force, from its polar angle (degrees)."""
    a = np.clip((theta_deg - TAPER[0]) / (TAPER[1] - TAPER[0]), 0.0, 1.0)
    return np.cos(0.5 * np.pi * a) ** 2


def interior_forces(pair) -> dict:
    """Nodal contact forces on the slave (normal + tangential, from the pair's residual
    terms, read-only) split into the tapered interior part and the part near the master's
    end: Rx_int, M_int = the hub reaction and moment that the interior part alone would
    balance; Fx_end = x-force on the slave nodes near the end; Rx_all = −Σ all (a check)."""
    n = pair.slave.n
    F = -pair.nodal_forces()[: 2 * n].reshape(-1, 2)
    xs = pair.state.xs
    w = taper(np.degrees(np.arctan2(xs[:, 1], xs[:, 0])))
    return dict(Rx_int=float(-np.sum(w * F[:, 0])),
                M_int=float(-np.sum(w * (xs[:, 0] * F[:, 1] - xs[:, 1] * F[:, 0]))),
                Fx_end=float(np.sum((1.0 - w) * F[:, 0])), Rx_all=float(-np.sum(F[:, 0])))


def run_one(name: str, mu: float, smoothing: str, wall_limit: float,
            mesh: dict | None = None, out_root: Path = OUT) -> dict:
    """One full load path in this (worker) process; returns the per-step rows and the verdict.
    ``mesh``: generator parameters replacing the scene's (meshes/half_rings.py)."""
    sys.path.insert(0, str(ROOT / "demos"))
    from demo_half_rings import hub_moment  # the demo's moment of the hub forces
    from fenicsx_mortar import Friction, load_scene, solve

    out = Path(out_root) / name
    out.mkdir(parents=True, exist_ok=True)
    logf = open(out / "run.log", "w")

    def log(s: str) -> None:
        logf.write(s + "\n")
        logf.flush()

    scene = load_scene(ROOT / "demos" / "scenes" / "half_rings.toml")
    scene.contacts[0].friction = Friction(law="coulomb", mu=mu) if mu > 0 else Friction()
    scene.contacts[0].smoothing = smoothing
    if mesh:
        scene.mesh.params = dict(mesh)
    rows: list[dict] = []
    misfit = [0.0]  # max |−Σ nodal contact F_x − hub R_x| / max(|R_x|, 1) over the steps
    t0, c0 = time.perf_counter(), time.process_time()

    def on_step(rec: dict, state) -> None:
        c = rec["contact"]["rings"]
        s, phi = load_parameters(rec["time"])
        split = interior_forces(state.pairs[0])
        Rx = rec["reactions"]["hub"]["x"]
        misfit[0] = max(misfit[0], abs(split.pop("Rx_all") - Rx) / max(abs(Rx), 1.0))
        rows.append(dict(run=name, mu=mu, smoothing=smoothing, step=rec["step"],
                         time=rec["time"], press=s, phi=phi,
                         Rx=rec["reactions"]["hub"]["x"], Ry=rec["reactions"]["hub"]["y"],
                         M=hub_moment(state), N=c["normal_force"],
                         T=c.get("tangential_force", 0.0), active=c["active_nodes"],
                         stick=c.get("stick_nodes", 0), slip=c.get("slip_nodes", 0),
                         p_max=c["max_pressure"], newton=rec["newton_iterations"],
                         augmentations=rec["augmentations"], cuts=rec["cuts"], **split))
        print(f"[{name}] t = {rec['time']:.5f}  Newton {rec['newton_iterations']:3d}  "
              f"cuts {rec['cuts']}  Rx = {rows[-1]['Rx']:9.3f}  p_max = {c['max_pressure']:.3g}"
              f"  ({time.perf_counter() - t0:.0f} s)", flush=True)
        if len(rows) >= 20 and rows[-1]["time"] - rows[-20]["time"] < 0.01:
            raise Stop(f"stalled: 20 steps advanced pseudo-time by less than 0.01 "
                       f"(t = {rec['time']:.6g})")
        if time.perf_counter() - t0 > wall_limit:
            raise Stop(f"wall limit {wall_limit:.0f} s reached at t = {rec['time']:.6g}")

    try:
        result = solve(scene, out=out / "run", log=log, on_step=on_step)
        completed, message = result.converged, result.message
    except Stop as e:
        completed, message = False, str(e)
    except Exception as e:  # a crash is a result too: keep what converged
        completed, message = False, f"{type(e).__name__}: {e}\n{traceback.format_exc()}"
    log(("done: " if completed else "STOPPED: ") + message)
    logf.close()
    return dict(name=name, mu=mu, smoothing=smoothing, completed=bool(completed),
                message=message, rows=rows, wall=time.perf_counter() - t0,
                cpu=time.process_time() - c0, split_misfit=misfit[0])


def run_job(job: dict) -> dict:
    """The pool's target: :func:`run_one` with its arguments by name."""
    return run_one(**job)


def on_targets(rows: list[dict]) -> list[dict]:
    """The rows at the turn's target states t_j (those reached)."""
    sel = []
    for tj in TURN_TARGETS:
        r = next((r for r in rows if abs(r["time"] - tj) < 1e-9), None)
        if r is not None:
            sel.append(r)
    return sel


def oscillation(values: np.ndarray) -> float:
    """mean |second difference| / max |value| (see the module docstring); nan if < 3 values."""
    if len(values) < 3 or np.max(np.abs(values)) == 0:
        return float("nan")
    return float(np.mean(np.abs(np.diff(values, 2))) / np.max(np.abs(values)))


def measures(run: dict) -> dict:
    rows = run["rows"]
    turn = on_targets(rows)
    newton = [r["newton"] for r in rows]
    return dict(
        completed=run["completed"],
        reached=rows[-1]["time"] / 2.0 if rows else 0.0,
        steps=len(rows), cuts=sum(int(r["cuts"]) for r in rows),
        cut_steps=sum(int(r["cuts"]) > 0 for r in rows),
        newton_mean=float(np.mean(newton)) if newton else float("nan"),
        newton_max=int(max(newton)) if newton else 0,
        n_turn=len(turn),
        **{f"osc_{k}": oscillation(np.array([r[k] for r in turn]))
           for k in ("Rx", "Ry", "M", "Rx_int", "M_int", "Fx_end")},
        p_max=max((r["p_max"] for r in rows), default=float("nan")))


def table(runs: list[dict]) -> str:
    lines = ["| run | completed | load reached | steps | cuts (steps cut) | Newton/step mean / max "
             "| osc R_x | osc R_y | osc M | osc R_x,int | osc F_x,end | max p | wall s | CPU s |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for run in runs:
        m = measures(run)
        label = f"μ = {run['mu']:g}, {run['smoothing']}"
        partial = "" if m["n_turn"] == 20 else f" ({m['n_turn']} of 20 turn states)"
        lines.append(
            f"| {label} | {'yes' if m['completed'] else '**no**'} | {100 * m['reached']:.1f} % "
            f"| {m['steps']} | {m['cuts']} ({m['cut_steps']}) | {m['newton_mean']:.1f} / "
            f"{m['newton_max']} | {m['osc_Rx']:.2e}{partial} | {m['osc_Ry']:.2e} | "
            f"{m['osc_M']:.2e} | {m['osc_Rx_int']:.2e} | {m['osc_Fx_end']:.2e} | "
            f"{m['p_max']:.3g} | {run['wall']:.0f} | {run['cpu']:.0f} |")
    return "\n".join(lines)


def write_csv(runs: list[dict]) -> None:
    with open(CSV, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=COLUMNS)
        w.writeheader()
        for run in runs:
            for r in run["rows"]:
                w.writerow({k: (f"{r[k]:.12g}" if isinstance(r[k], float) else r[k])
                            for k in COLUMNS})
    (OUT / "runs.json").write_text(json.dumps(
        [{k: v for k, v in run.items() if k != "rows"} for run in runs], indent=1) + "\n")


def read_saved() -> list[dict]:
    info = {r["name"]: r for r in json.loads((OUT / "runs.json").read_text())}
    rows: dict[str, list[dict]] = {}
    with open(CSV) as f:
        for r in csv.DictReader(f):
            rows.setdefault(r["run"], []).append(
                {k: (r[k] if k in ("run", "smoothing") else float(r[k])) for k in COLUMNS})
    return [dict(info[n], rows=rows.get(n, [])) for n, _, _ in RUNS if n in info]


def plot(runs: list[dict]) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    # the averaged-normal runs coincide with the polyline: thin dotted lines over its thick one
    look = {"none": dict(color="C3", lw=2.6, marker="o", ms=3.5, zorder=2),
            "averaged-simple": dict(color="C1", lw=0.9, ls=":", marker="x", ms=3, zorder=3),
            "averaged-weighted": dict(color="C8", lw=0.9, ls=":", marker="+", ms=4, zorder=3),
            "averaged-tangent": dict(color="C4", lw=0.9, ls=":", marker="1", ms=4, zorder=3),
            "hermite": dict(color="C0", lw=1.5, marker="s", ms=2.5, zorder=4),
            "bspline": dict(color="C2", lw=1.5, marker="^", ms=2.5, zorder=4)}
    fig, axes = plt.subplots(3, 2, figsize=(12, 12), constrained_layout=True)
    (a_x, a_d), (a_i, a_di), (a_y, a_m) = axes
    for run in runs:
        rows = run["rows"]
        if not rows:
            continue
        fr = run["mu"] == 0
        style = dict(color="k", ls="--", lw=1.0, zorder=1) if fr else look[run["smoothing"]]
        m = measures(run)
        label = ("μ = 0, none (frictionless)" if fr else
                 f"{run['smoothing']}: osc R_x {m['osc_Rx']:.3f}, interior {m['osc_Rx_int']:.3f}"
                 ) + ("" if run["completed"] else f" — STOPPED at t = {rows[-1]['time']:.4g}")
        t = np.array([0.0] + [r["time"] for r in rows])

        def col(k):
            return np.array([0.0] + [r[k] for r in rows])
        a_x.plot(t, col("Rx"), label=label, **style)
        a_i.plot(t, col("Rx_int"), **style)
        a_y.plot(t, col("Ry"), **style)
        a_m.plot(t, col("M"), **style)
        turn = on_targets(rows)
        if len(turn) >= 3:
            deg = np.degrees([r["phi"] for r in turn[1:-1]])
            a_d.plot(deg, np.diff([r["Rx"] for r in turn], 2), **style)
            a_di.plot(deg, np.diff([r["Rx_int"] for r in turn], 2), **style)
    for a, k in ((a_x, "hub reaction R_x"), (a_y, "hub reaction R_y"),
                 (a_m, "hub moment M about the origin"),
                 (a_i, "R_x,int: interior contact force (end taper)")):
        a.set(xlabel="load parameter t (0–1 press 0.5, 1–2 turn by 23.6°)", ylabel=k)
        a.axvline(1.0, color="0.6", lw=0.8)
    a_x.legend(fontsize=7.5, loc="upper left")
    a_x.set_title("B3 half-rings, μ = 0.3, per master smoothing (dashed: frictionless)")
    a_i.set_title(f"x-force of the slave nodes below {TAPER[0]:g}° (taper to 0 at {TAPER[1]:g}°; "
                  "master's end at 0°)", fontsize=9)
    for a, k in ((a_d, "R_x"), (a_di, "R_x,int")):
        a.set(xlabel="turn angle φ (degrees)", ylabel=f"{k}[j+1] − 2 {k}[j] + {k}[j−1]",
              title=f"second difference of {k} over the turn (Δφ = φ_max / 20)")
        a.axhline(0.0, color="0.6", lw=0.8)
    for a in axes.ravel():
        a.grid(alpha=0.3)
    fig.savefig(PNG, dpi=100)
    plt.close(fig)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--jobs", type=int, default=2, help="worker processes (at most 2)")
    ap.add_argument("--only", default="", help="comma-separated smoothings (μ = 0.3 runs)")
    ap.add_argument("--wall-limit", type=float, default=3600.0, help="per run, seconds")
    ap.add_argument("--redraw", action="store_true", help="no solve: table and plot from CSV")
    args = ap.parse_args()
    OUT.mkdir(parents=True, exist_ok=True)
    if args.redraw:
        runs = read_saved()
    else:
        todo = [r for r in RUNS if not args.only or (r[1] > 0 and r[2] in args.only.split(","))]
        t0 = time.perf_counter()
        done: dict[str, dict] = {}

        def finished(out: pool.Outcome) -> None:
            if out.record is None:
                raise RuntimeError(f"[{out.job.tag}] worker process died (exit code "
                                   f"{out.returncode})")
            run = out.record
            done[run["name"]] = run
            print(f"[{run['name']}] {'completed' if run['completed'] else 'STOPPED'} in "
                  f"{run['wall']:.0f} s: {run['message'].splitlines()[0][:300]}", flush=True)
        # the run's own wall limit (``run_one``) keeps what converged, so the pool sets none;
        # the workers print their step lines here
        jobs = [pool.Job(dict(name=n, mu=mu, smoothing=s, wall_limit=args.wall_limit), tag=n)
                for n, mu, s in todo]
        pool.run("benchmarks.half_rings_smoothing:run_job", jobs, finished,
                 workers=max(1, min(args.jobs, 2)), output=None)
        print(f"total wall time {time.perf_counter() - t0:.0f} s", flush=True)
        if args.only:  # keep the other runs' saved data
            try:
                old = {r["name"]: r for r in read_saved()}
            except FileNotFoundError:
                old = {}
            done = {**old, **done}
        runs = [done[n] for n, _, _ in RUNS if n in done]
        write_csv(runs)
    plot(runs)
    print(table(runs))
    for run in runs:
        if "split_misfit" in run:
            print(f"{run['name']}: max |−Σ nodal F_x − R_x| / max(|R_x|, 1) = "
                  f"{run['split_misfit']:.1e}")
        if not run["completed"]:
            print(f"\n{run['name']} STOPPED: {run['message']}")
    print(f"\nwrote {CSV.relative_to(ROOT)}, {PNG.relative_to(ROOT)}, {OUT.relative_to(ROOT)}/")


if __name__ == "__main__":
    main()
