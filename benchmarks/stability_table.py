"""Run the hard-case scenes of the stability suite and write the table in docs/stability.md.

    .venv/bin/python benchmarks/stability_table.py            # all runs
    .venv/bin/python benchmarks/stability_table.py --only 7   # labels starting with "7"

The table replaces the text between the markers ``<!-- table -->`` and ``<!-- /table -->``
of docs/stability.md. Columns: converged; Newton iterations per converged step (mean / max,
summed over the step's ALM augmentations); step cuts over the run; the oscillation measure
(largest excess total variation of the nodal pressure over the converged steps, see
tests/stability/_common.py); wall and CPU seconds of the solve; the end of the message when
the run stopped early.
"""
from __future__ import annotations

import argparse
import re
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests" / "stability"))

from _cases import RUNS  # noqa: E402
from _common import HARD, run_scene  # noqa: E402

DOC = ROOT / "docs" / "stability.md"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", default="", help="run only labels starting with this")
    ap.add_argument("--no-write", action="store_true", help="print the table only")
    args = ap.parse_args()
    rows = ["| case | scene | converged | Newton its mean / max | cuts | oscillation | wall s | CPU s | stopped |",
            "|---|---|---|---|---|---|---|---|---|"]
    total_wall = total_cpu = 0.0
    for label, scene in RUNS.items():
        if not label.startswith(args.only):
            continue
        c0 = time.process_time()
        run = run_scene(HARD / scene, name=label)
        cpu = time.process_time() - c0
        total_wall += run.seconds
        total_cpu += cpu
        its = run.newton
        its_s = f"{sum(its) / len(its):.1f} / {max(its)}" if its else "–"
        stopped = "" if run.converged else _short(run.result.message)
        bad = f" (non-finite: {', '.join(run.nonfinite[:2])})" if run.nonfinite else ""
        rows.append(f"| {label} | `{scene}` | {'yes' if run.converged else '**no**'}{bad} | "
                    f"{its_s} | {run.cuts} | {run.osc:.3g} | {run.seconds:.1f} | {cpu:.1f} | "
                    f"{stopped} |")
        print(rows[-1], flush=True)
    rows.append(f"\nTotal solve time: {total_wall:.0f} s wall, {total_cpu:.0f} s CPU (one process).")
    table = "\n".join(rows)
    if args.no_write or args.only:
        print(table)
        return
    text = DOC.read_text()
    new = re.sub(r"<!-- table -->.*<!-- /table -->",
                 lambda m: f"<!-- table -->\n{table}\n<!-- /table -->", text, flags=re.S)
    DOC.write_text(new)
    print(f"wrote {DOC}")


def _short(message: str) -> str:
    m = re.search(r"stopped at pseudo-time ([0-9.e+-]+).*?(Newton failed: \w+|Newton stopped by the cycling guard|augmented Lagrangian[^;]*)",
                  message)
    return f"t = {m.group(1)}: {m.group(2)}" if m else message[:80].replace("|", "/")


if __name__ == "__main__":
    main()
