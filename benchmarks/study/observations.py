"""The study's "What the numbers say": facts read off the runs (computed, so they follow
the data when it changes)."""
from __future__ import annotations

import statistics

from .cases import ENFORCEMENTS, ERRORS, METHODS, SMOOTHINGS
from .records import key, num, valid
from .tables import ERROR_LABELS, STATUS_MARK

#: the enforcements that close the gap exactly, and the penalties
EXACT = [e for e in ENFORCEMENTS if not e.startswith("penalty")]
PENALTIES = [e for e in ENFORCEMENTS if e.startswith("penalty")]


def observations(rows: list[dict], benches: list[str]) -> list[str]:
    lines = ["## What the numbers say", ""]

    def pick(**kw):
        return [r for r in rows if all(r[k] == v for k, v in kw.items())]

    def rng(rs, err):
        v = [r[err] for r in rs if valid(r, err)]
        return (min(v), max(v), len(v)) if v else None

    if "patch" in benches:
        for m in METHODS:
            for group, smooth in (("none / averaged-*", SMOOTHINGS[:4]),
                                  ("hermite / bspline", SMOOTHINGS[4:])):
                for e in EXACT:
                    rs = [r for r in pick(benchmark="patch", method=m, enforcement=e)
                          if r["smoothing"] in smooth]
                    x = rng(rs, "err_sigma_yy")
                    if x:
                        lines.append(f"* B1, {m} + {e}, {group}: max |σ_yy + 1| from "
                                     f"{x[0]:.1e} to {x[1]:.1e} over {x[2]} converged runs "
                                     "(all levels).")
        for m in METHODS:
            for e in PENALTIES:
                x = rng(pick(benchmark="patch", method=m, enforcement=e, smoothing="none"),
                        "err_sigma_yy")
                if x:
                    lines.append(f"* B1, {m} + {e} + none: {x[0]:.1e} … {x[1]:.1e}.")
    for b in ("hertz", "hertz_mc"):
        if b not in benches:
            continue
        for m in METHODS:
            for s in SMOOTHINGS:
                for e in EXACT:
                    rs = sorted(pick(benchmark=b, method=m, smoothing=s, enforcement=e),
                                key=lambda r: r["level"])
                    seq = [f"{r['err_l2']:.3f}" if valid(r, "err_l2") else
                           STATUS_MARK.get(r["status"], "?") for r in rs]
                    if len(rs) > 1:
                        lines.append(f"* {b}, {m} + {s} + {e}, L2 error over the levels: "
                                     + " → ".join(seq) + ".")
    if "half_rings" in benches:
        for s in SMOOTHINGS:
            rs = pick(benchmark="half_rings", smoothing=s)
            osc = rng(rs, "osc_reaction")
            n_bad = sum(r["status"] != "converged" for r in rs)
            if rs:
                lines.append(f"* half_rings, {s}: {len(rs) - n_bad} of {len(rs)} runs converged"
                             + (f"; oscillation {osc[0]:.1e} … {osc[1]:.1e}" if osc else "")
                             + ".")
    # one enforcement against another: same benchmark, method, smoothing and level
    by_key = {key(r): r for r in rows}
    for a, other in (("lagrange", "penalty-1"), ("alm", "penalty-1"), ("lagrange", "alm")):
        for b in benches:
            err = ERRORS[b][0]
            cpu, acc = [], []
            for r in rows:
                if r["benchmark"] != b or r["enforcement"] != a or r["status"] != "converged":
                    continue
                p = by_key.get(key(r)[:3] + (other, r["level"]))
                if p is not None and p["status"] == "converged" and num(p["cpu_time"]) > 0:
                    cpu.append(num(r["cpu_time"]) / num(p["cpu_time"]))
                    if (valid(r, err) and valid(p, err) and p[err] > 0
                            and not r.get("reference") and not p.get("reference")):
                        acc.append(r[err] / p[err])
            if cpu:
                lines.append(f"* {b}: `{a}` takes {statistics.median(cpu):.2g}× the CPU time "
                             f"of `{other}` (median over {len(cpu)} pairs of runs that differ "
                             "only in the enforcement)"
                             + (f"; its {ERROR_LABELS[err]} is {statistics.median(acc):.2g}× "
                                f"`{other}`'s" if acc else "") + ".")
    for b in benches:
        for m in METHODS:
            rs = [r for r in rows if r["benchmark"] == b and r["method"] == m]
            ran = [r for r in rs if r["status"] != "skipped"]
            bad = [r for r in ran if r["status"] != "converged"]
            if bad:
                lines.append(f"* {b}, {m}: {len(bad)} of {len(ran)} runs did not converge"
                             + (f" ({len(rs) - len(ran)} more skipped)" if len(rs) > len(ran)
                                else "") + ".")
    # cost of the smoothings: contact kernel time relative to none, same everything else
    ratios = {}
    for r in rows:
        if r["smoothing"] == "none" or r["status"] != "converged":
            continue
        k = key(r)
        base = by_key.get(k[:2] + ("none",) + k[3:])
        if (base is not None and base["status"] == "converged"
                and num(base["t_contact_kernel"]) > 0 and num(base["newton_iterations"]) > 0):
            per_it = (num(r["t_contact_kernel"]) / max(num(r["newton_iterations"]), 1)) / (
                num(base["t_contact_kernel"]) / num(base["newton_iterations"]))
            ratios.setdefault(r["smoothing"], []).append(per_it)
    if ratios:
        lines.append("* Contact-kernel time per Newton iteration relative to `none` (median over "
                     "all converged pairs of runs differing only in the smoothing): "
                     + ", ".join(f"{s} {statistics.median(v):.1f}×" for s, v in ratios.items())
                     + ".")
    return lines + [""]
