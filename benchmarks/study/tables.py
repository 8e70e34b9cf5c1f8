"""How the study's report shows things: the benchmarks' titles, the errors' labels, the
marks of runs that did not converge, number formats and Markdown tables."""
from __future__ import annotations

import math

from .records import num

TITLES = {
    "patch": "B1 contact patch test",
    "hertz": "B2 Hertz, curved slave (disk arc) on a flat master",
    "hertz_mc": "B2 Hertz, curved master (disk arc) under a flat slave",
    "half_rings": "B3 half-rings (press + 30 % of the turn)",
}

ERROR_LABELS = {
    "err_sigma_yy": "max |σ_yy + 1|",
    "err_l2": "relative L2 pressure error on [−a, a]",
    "err_p0": "|p_max/p₀ − 1|",
    "err_a": "|a_fit/a − 1|",
    "err_reaction": "reaction-curve error vs reference",
    "osc_reaction": "reaction-curve oscillation",
}

STATUS_MARK = {"failed": "✗", "timeout": "⏱", "error": "✗!", "crashed": "✗✗",
               "skipped": "⊘"}


def cell(r: dict | None, err: str) -> str:
    if r is None:
        return "—"
    if r["status"] != "converged":
        return f"{STATUS_MARK.get(r['status'], '✗')} {r['status']}"
    e = num(r.get(err, ""))
    es = "ref." if r.get("reference") else (f"{e:.2g}" if not math.isnan(e) else "?")
    return f"{es} ({num(r['cpu_time']):.2g} s)"


def md_table(header: list[str], rows: list[list[str]]) -> str:
    esc = lambda c: str(c).replace("|", "\\|")  # noqa: E731
    lines = ["| " + " | ".join(map(esc, header)) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(map(esc, row)) + " |" for row in rows]
    return "\n".join(lines)


def fmt_s(seconds: float) -> str:
    return f"{seconds / 60:.1f} min" if seconds >= 120 else f"{seconds:.0f} s"


def err_text(e: float) -> str:
    """An error for the tables; below 1e-9 it is round-off (exact to the solver tolerance)."""
    return "< 1e-9" if e < 1e-9 else f"{e:.2g}"
