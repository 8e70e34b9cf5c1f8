"""Command line of the study: ``python -m benchmarks.study [--quick] [--out DIR] [--jobs N]
[--report-only]`` from the repository root (``fenicsx-mortar study`` calls :func:`main`)."""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

from .cases import full_plan, quick_plan
from .report import DOCS, ROOT, report
from .runner import run_study

PROG = "python -m benchmarks.study"


def main(argv: list[str] | None = None, prog: str = PROG) -> int:
    ap = argparse.ArgumentParser(prog=prog, description="accuracy against compute time: "
                                 "method x smoothing x enforcement x mesh size on B1-B3 "
                                 "(docs/accuracy-vs-time.md)")
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
    args = ap.parse_args(argv)
    out = args.out or (ROOT / "results" / "study_quick" if args.quick else DOCS)
    if args.report_only:
        report(out)
        return 0
    # the solves run in worker processes; this process only schedules them
    plan = quick_plan() if args.quick else full_plan()
    cmd = (prog + (" --quick" if args.quick else "")
           + (f" --out {args.out}" if args.out else "")
           + (f" --jobs {args.jobs}" if args.jobs != 2 else ""))
    records = run_study(plan, out, args.jobs, command=cmd)
    bad = sum(r["status"] != "converged" for r in records)
    print(f"study done: {len(records)} runs, {bad} not converged; report in "
          f"{out / 'accuracy-vs-time.md'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
