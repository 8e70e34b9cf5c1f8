"""The table of outcomes by kind of every hostile case, for any version of the code:

    python -m tests.hostile.outcomes [--code DIR] [--jobs 2] [--only ID,ID] [--verbose]

runs each case of tests/hostile/cases.py as a process (``--code``: the checkout whose
``fenicsx_mortar`` runs, default this one) in a temporary directory, 60 s at most each, and
prints one line per case and the counts by kind (harness.py)."""
from __future__ import annotations

import argparse
import collections
import os
import sys
import tempfile
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

from .cases import CASES, ROOT, Skip
from .harness import GOOD, Donors, fresh, kind, run_process


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--code", type=Path, default=ROOT)
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--only", default="")
    ap.add_argument("--verbose", action="store_true")
    args = ap.parse_args()
    env = {**os.environ, "PYTHONPATH": str(args.code.resolve())}
    cases = [c for c in CASES if not args.only or c.id in args.only.split(",")]
    with tempfile.TemporaryDirectory(prefix="hostile-") as tmp:
        tmp = Path(tmp)
        donors = Donors(tmp / "donors", env)
        donors.get("base"), donors.get("base_p05")

        def one(case):
            try:
                o = run_process(case, fresh(tmp / case.id), donors, env)
            except Skip as e:
                return case, "skipped", None, str(e)
            return case, kind(case, o), o, ""

        with ThreadPoolExecutor(args.jobs) as pool:
            results = list(pool.map(one, cases))
    counts = collections.Counter()
    for case, k, o, why in results:
        counts[k] += 1
        if o is None:
            print(f"{case.id:40s} {k} ({why})")
            continue
        last = (o.err.strip().splitlines() or o.out.strip().splitlines() or [""])[-1]
        print(f"{case.id:40s} exit {o.code!s:4s} {o.seconds:5.1f} s  {k:24s} {last[:110]}")
        if args.verbose and k not in GOOD:
            print("    stderr:", o.err[-1500:].replace("\n", "\n    "))
    print(f"\n{len(results)} cases")
    for k, n in counts.most_common():
        print(f"  {n:4d}  {k}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
