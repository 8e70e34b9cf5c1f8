"""A run's record: its columns, the CSV it is written to and read back from, and the
study's JSON files."""
from __future__ import annotations

import csv
import json
import math
from pathlib import Path

from .cases import BENCHMARKS, ENFORCEMENTS, LEVELS, METHODS, SMOOTHINGS, Case

PHASES = ("mesh", "jit", "bulk_assembly", "contact", "contact_search", "contact_kernel",
          "contact_insertion", "linear_solve", "output", "total")

COLUMNS = (["benchmark", "method", "smoothing", "enforcement", "level", "level_label", "h",
            "epsilon", "status", "converged", "reached_time", "message",
            "err_sigma_yy", "err_p0", "err_l2", "err_a", "err_force", "err_reaction",
            "osc_reaction", "dofs", "slave_nodes", "active_nodes", "steps", "cuts",
            "newton_iterations", "augmentations", "cpu_time", "wall_time"]
           + [f"t_{p}" for p in PHASES] + ["warnings"])
_TEXT = ("benchmark", "method", "smoothing", "enforcement", "level_label", "status", "message",
         "warnings")


def new_record(case: Case, **fields) -> dict:
    """A record of ``case``: every column empty but the case's own and ``fields``."""
    lv = LEVELS[case.benchmark][case.level]
    rec = {c: "" for c in COLUMNS}
    rec.update(benchmark=case.benchmark, method=case.method, smoothing=case.smoothing,
               enforcement=case.enforcement, level=case.level, level_label=lv.label, h=lv.h,
               **fields)
    return rec


def key(r: dict) -> tuple:
    return (r["benchmark"], r["method"], r["smoothing"], r["enforcement"], int(r["level"]))


def key_str(r: dict) -> str:
    return "/".join(map(str, key(r)))


def order(r: dict) -> tuple:
    """The study's order of records: benchmark, method, smoothing, enforcement, level."""
    return (BENCHMARKS.index(r["benchmark"]), METHODS.index(r["method"]),
            SMOOTHINGS.index(r["smoothing"]), ENFORCEMENTS.index(r["enforcement"]),
            int(r["level"]))


def num(v) -> float:
    """A number of a row read back from the CSV; NaN for an empty cell."""
    return v if isinstance(v, float) and not math.isnan(v) else float("nan")


def valid(r: dict, err: str) -> bool:
    """A converged run with a value of ``err``."""
    return r["status"] == "converged" and not math.isnan(num(r.get(err, "")))


def write_csv(records: list[dict], path: Path) -> None:
    with path.open("w", newline="") as f:
        w = csv.DictWriter(f, COLUMNS + ["reference"], extrasaction="ignore")
        w.writeheader()
        for r in sorted(records, key=order):
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
                if k in _TEXT:
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


def json_lines(d: dict) -> str:
    """A JSON object with one line per key (diff-friendly, compact)."""
    return "{\n" + ",\n".join(f"{json.dumps(k)}: {json.dumps(v)}" for k, v in d.items()) + "\n}\n"
