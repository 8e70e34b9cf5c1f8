"""Run the hard-case scenes of the stability suite and write the table in docs/stability.md.

    .venv/bin/python benchmarks/stability_table.py            # all runs, 2 workers
    .venv/bin/python benchmarks/stability_table.py --only 7   # labels starting with "7"

The table replaces the text between the markers ``<!-- table -->`` and ``<!-- /table -->``
of docs/stability.md. Columns: converged; Newton iterations per converged step (mean / max,
summed over the step's augmentations, if any); step cuts over the run; the oscillation measure
(largest excess total variation of the nodal pressure over the converged steps, see
tests/stability/_common.py); wall and CPU seconds of the solve (each run in a
single-threaded worker process of ``benchmarks/pool.py``); the end of the message when the
run stopped early.
"""
from __future__ import annotations

import argparse
import re
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests" / "stability"))
sys.path.insert(0, str(ROOT))

from _cases import RUNS  # noqa: E402
from _common import HARD, run_scene  # noqa: E402

from benchmarks import pool  # noqa: E402

DOC = ROOT / "docs" / "stability.md"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", default="", help="run only labels starting with this")
    ap.add_argument("--no-write", action="store_true", help="print the table only")
    ap.add_argument("--jobs", type=int, default=2, help="worker processes (at most 2)")
    args = ap.parse_args()
    jobs = [pool.Job([label, scene], tag=label) for label, scene in RUNS.items()
            if label.startswith(args.only)]
    done: dict[str, str] = {}
    total_wall = total_cpu = 0.0

    def finished(out: pool.Outcome) -> None:
        nonlocal total_wall, total_cpu
        if out.record is None:
            raise RuntimeError(f"{out.job.tag}: worker process died (exit code {out.returncode})")
        r = out.record
        total_wall += r["seconds"]
        total_cpu += r["cpu"]
        its = r["newton"]
        its_s = f"{sum(its) / len(its):.1f} / {max(its)}" if its else "–"
        stopped = "" if r["converged"] else _short(r["message"])
        bad = f" (non-finite: {', '.join(r['nonfinite'])})" if r["nonfinite"] else ""
        done[r["label"]] = (
            f"| {r['label']} | `{r['scene']}` | {'yes' if r['converged'] else '**no**'}{bad} | "
            f"{its_s} | {r['cuts']} | {r['osc']:.3g} | {r['seconds']:.1f} | {r['cpu']:.1f} | "
            f"{stopped} |")
        print(done[r["label"]], flush=True)
    workers = max(1, min(args.jobs, 2))
    pool.run("benchmarks.stability_table:measure", jobs, finished, workers=workers)
    rows = ["| case | scene | converged | Newton its mean / max | cuts | oscillation "
            "| wall s | CPU s | stopped |",
            "|---|---|---|---|---|---|---|---|---|"]
    rows += [done[j.tag] for j in jobs]
    rows.append(f"\nTotal solve time: {total_wall:.0f} s wall, {total_cpu:.0f} s CPU (summed over "
                f"the runs, {workers} worker process{'es' if workers > 1 else ''}).")
    table = "\n".join(rows)
    if args.no_write or args.only:
        print(table)
        return
    text = DOC.read_text()
    new = re.sub(r"<!-- table -->.*<!-- /table -->",
                 lambda m: f"<!-- table -->\n{table}\n<!-- /table -->", text, flags=re.S)
    DOC.write_text(new)
    print(f"wrote {DOC}")


def measure(job: list) -> dict:
    """The pool's target: one hard case ``[label, scene file]``, what its table row shows."""
    label, scene = job
    c0 = time.process_time()
    run = run_scene(HARD / scene, name=label)
    return dict(label=label, scene=scene, converged=run.converged, nonfinite=run.nonfinite[:2],
                newton=run.newton, cuts=run.cuts, osc=run.osc, seconds=run.seconds,
                cpu=time.process_time() - c0, message=run.result.message)


def _short(message: str) -> str:
    m = re.search(r"stopped at pseudo-time ([0-9.e+-]+).*?"
                  r"(Newton failed: \w+|Newton stopped by the cycling guard"
                  r"|augmented Lagrangian[^;]*)",
                  message)
    return f"t = {m.group(1)}: {m.group(2)}" if m else message[:80].replace("|", "/")


if __name__ == "__main__":
    main()
