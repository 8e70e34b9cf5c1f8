"""The B3 master-end sawtooth at fine turn steps (issue 31, item 3): is the hub R_x of the
smoothed masters really more jagged than the polyline's, and what sets the difference?

    .venv/bin/python benchmarks/half_rings_sawtooth.py            # 5 runs, 2 workers, ~5 min
    .venv/bin/python benchmarks/half_rings_sawtooth.py --redraw   # table from the saved runs

``benchmarks/half_rings_smoothing.py`` measures the oscillation at the scene's 20 turn steps,
about 2.5 steps per slave spacing — a sampling that could alias a periodic sawtooth. Here the
same B3 path (μ = 0.3, the scene's mesh, multipliers) runs with 100 turn steps of Δt = 0.01
from t = 1.2 on (the scene's 0.05 steps before: with the polyline, steps below 0.05 around
t = 1.16 end in an active-set cycle of the slave nodes at the master's end; recorded), and the
x-force of the slave nodes near the master's end F_x,end (``half_rings_smoothing.
interior_forces``), which carries the sawtooth, is split into a cubic trend over t ∈ [1.2, 2]
and the rest: its RMS and peak-to-peak, and the trend's value at t = 2.

Runs: the polyline ("none"), Hermite, B-spline, and Hermite with the *end chord's* tangent at
the master's open ends (its reflected ghost instead of the circle through the last three
nodes, ``Hermite.circle_ends = False``: the polyline's end geometry on a smoothed interior; a
worse geometry, O(h²) at the end segment, run only to find out what sets the sawtooth), the
B-spline and the polyline with the standard multiplier basis, the B-spline with a Hermite
slave curve (two-sided), and the frictionless polyline.

Writes the section between ``<!-- sawtooth -->`` markers of docs/smoothing.md and
``results/half_rings_sawtooth/runs.json``.
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from benchmarks import pool  # noqa: E402

OUT = ROOT / "results" / "half_rings_sawtooth"
DOC = ROOT / "docs" / "smoothing.md"
MARK = ("<!-- sawtooth -->", "<!-- /sawtooth -->")
FINE_FROM, N_TURN = 1.2, 100
#: (run, μ, smoothing, Hermite end tangent from the circle, other contact settings)
RUNS = [("none", 0.3, "none", True, {}), ("hermite", 0.3, "hermite", True, {}),
        ("bspline", 0.3, "bspline", True, {}), ("hermite, chord ends", 0.3, "hermite", False, {}),
        ("bspline, standard basis", 0.3, "bspline", True, {"basis": "standard"}),
        ("none, standard basis", 0.3, "none", True, {"basis": "standard"}),
        ("bspline, two-sided (hermite slave)", 0.3, "bspline", True,
         {"slave_smoothing": "hermite"}),
        ("none, μ = 0", 0.0, "none", True, {})]


def step_times() -> list[float]:
    coarse = [1.0 + 0.05 * k for k in range(1, int(round((FINE_FROM - 1.0) / 0.05)) + 1)]
    fine = [1.0 + k / N_TURN for k in range(1, N_TURN + 1) if 1.0 + k / N_TURN > FINE_FROM + 1e-9]
    return [0.25, 0.5, 0.75, 1.0] + coarse + fine


def run_job(job: dict) -> dict:
    """One run in a worker: the B3 scene with the fine steps (``half_rings_smoothing.run_one``
    with the scene's step times replaced)."""
    import fenicsx_mortar
    from benchmarks import half_rings_smoothing as H
    from fenicsx_mortar.contact import curves
    curves.Hermite.circle_ends = job["circle_ends"]
    load = fenicsx_mortar.load_scene

    def fine(path):
        scene = load(path)
        scene.steps.times = step_times()
        for key, value in job["contact"].items():
            setattr(scene.contacts[0], key, value)
        return scene
    fenicsx_mortar.load_scene = fine
    try:
        rec = H.run_one(job["name"], job["mu"], job["smoothing"], 3600.0, out_root=OUT)
    finally:
        fenicsx_mortar.load_scene = load
    return dict(rec, circle_ends=job["circle_ends"])


def analyse(rec: dict) -> dict:
    rows = [r for r in rec["rows"] if r["time"] > FINE_FROM - 1e-9]
    t = np.array([r["time"] for r in rows])
    out = dict(steps=len(rows), reached=rows[-1]["time"] if rows else float("nan"))
    for key, sign in (("Fx_end", -1.0), ("Rx", 1.0), ("Rx_int", 1.0)):
        v = sign * np.array([r[key] for r in rows])
        V = np.vander(t - 0.5 * (FINE_FROM + 2.0), 4)
        trend = V @ np.linalg.lstsq(V, v, rcond=None)[0]
        rest = v - trend
        out[key] = dict(rms=float(np.sqrt(np.mean(rest ** 2))), p2p=float(rest.max() - rest.min()),
                        end=float(trend[-1]), d2=float(np.mean(np.abs(np.diff(v, 2)))))
    # the sawtooth's teeth: the drops of F_x,end (a slave node leaving the master's end)
    v = -np.array([r["Fx_end"] for r in rows])
    drops = np.flatnonzero(np.diff(v) < 0)
    out["teeth"] = [dict(t=float(t[i]), peak=float(v[i]), after=float(v[i + 1])) for i in drops]
    return out


def table(runs: list[dict]) -> str:
    lines = ["| run | completed | steps ≥ 1.2 | F_x,end: trend at t = 2 / RMS / peak-to-peak of "
             "the rest | R_x: RMS / p2p | R_x,int: RMS / p2p | mean \\|Δ²R_x\\| (Δt = 0.01) "
             "| last three teeth: peak → after |",
             "|---|---|---|---|---|---|---|---|"]
    for r in runs:
        a = r["analysis"]
        teeth = "; ".join(f"{x['peak']:.0f} → {x['after']:.0f}" for x in a["teeth"][-3:])
        f, x, i = a["Fx_end"], a["Rx"], a["Rx_int"]
        lines.append(f"| {r['label']} | {'yes' if r['completed'] else 'no'} | {a['steps']} | "
                     f"{f['end']:.1f} / {f['rms']:.2f} / {f['p2p']:.1f} | {x['rms']:.2f} / "
                     f"{x['p2p']:.1f} | {i['rms']:.3f} / {i['p2p']:.2f} | {x['d2']:.2f} "
                     f"| {teeth} |")
    return "\n".join(lines)


def write_doc(runs: list[dict]) -> None:
    text = DOC.read_text()
    section = (f"{MARK[0]}\n*Generated by `benchmarks/half_rings_sawtooth.py` (the B3 path, "
               f"μ = 0.3 unless marked, 100 turn steps of Δt = 0.01 from t = {FINE_FROM}; F_x,end "
               "and R_x split into a cubic trend over t ∈ [1.2, 2] and the rest).*\n\n"
               + table(runs) + f"\n{MARK[1]}\n")
    if MARK[0] in text:
        head, rest = text.split(MARK[0], 1)
        text = head + section + rest.split(MARK[1], 1)[1].lstrip("\n")
    else:
        text = text.rstrip("\n") + "\n\n" + section
    DOC.write_text(text)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--redraw", action="store_true", help="no solve: the saved runs")
    ap.add_argument("--jobs", type=int, default=2)
    args = ap.parse_args()
    OUT.mkdir(parents=True, exist_ok=True)
    saved = OUT / "runs.json"
    if args.redraw:
        runs = json.loads(saved.read_text())
    else:
        t0 = time.perf_counter()
        done: dict[str, dict] = {}

        def finished(out: pool.Outcome) -> None:
            if out.record is None:
                raise RuntimeError(f"[{out.job.tag}] worker died ({out.returncode})")
            done[out.job.tag] = out.record
            print(f"[{out.job.tag}] {'completed' if out.record['completed'] else 'STOPPED'} "
                  f"in {out.record['wall']:.0f} s: {out.record['message'][:200]}", flush=True)
        jobs = [pool.Job(dict(name="".join(c if c.isalnum() else "_" for c in label),
                              mu=mu, smoothing=sm, circle_ends=ce, contact=extra), tag=label)
                for label, mu, sm, ce, extra in RUNS]
        pool.run("benchmarks.half_rings_sawtooth:run_job", jobs, finished,
                 workers=max(1, min(args.jobs, 2)), output=None)
        runs = []
        for label, *_ in RUNS:
            rec = dict(done[label], label=label)
            rec["analysis"] = analyse(rec)
            runs.append(rec)
        saved.write_text(json.dumps(runs))
        print(f"total wall {time.perf_counter() - t0:.0f} s")
    print(table(runs))
    write_doc(runs)


if __name__ == "__main__":
    main()
