"""The study's Pareto plots: error against CPU time per benchmark, one front per method and
smoothing."""
from __future__ import annotations

from pathlib import Path

from .cases import ERRORS, METHODS, SMOOTHINGS
from .records import num, valid
from .tables import ERROR_LABELS, TITLES

_COLORS = {"none": "tab:gray", "averaged-simple": "tab:blue", "averaged-weighted": "tab:cyan",
           "averaged-tangent": "tab:purple", "hermite": "tab:orange", "bspline": "tab:red"}


def pareto_front(points: list[tuple[float, float]]) -> list[tuple[float, float]]:
    """Non-dominated (time, error) points: sorted by time, each with a smaller error than
    every cheaper one."""
    front, best = [], float("inf")
    for t, e in sorted(points):
        if e < best:
            front.append((t, e))
            best = e
    return front


def plot_pareto(rows: list[dict], bench: str, path: Path) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    errs = ERRORS[bench]
    fig, axes = plt.subplots(1, len(errs), figsize=(6.2 * len(errs), 4.6), squeeze=False)
    for ax, err in zip(axes[0], errs):
        for m in METHODS:
            for s in SMOOTHINGS:
                sel = [r for r in rows if r["method"] == m and r["smoothing"] == s
                       and valid(r, err) and not r.get("reference")]
                pts = [(num(r["cpu_time"]), max(r[err], 1e-16)) for r in sel]
                if not pts:
                    continue
                ls, mk = ("-", "o") if m == "mortar" else ("--", "s")
                ax.loglog(*zip(*pts), mk, color=_COLORS[s], ms=3, alpha=0.25, mfc="none")
                front = pareto_front(pts)
                ax.loglog(*zip(*front), ls, marker=mk, color=_COLORS[s], ms=4, lw=1.3,
                          label=f"{m} / {s}")
        ax.set_xlabel("CPU time per run [s] (process CPU of the solve)")
        ax.set_ylabel(ERROR_LABELS[err])
        ax.grid(alpha=0.3, which="both")
        ax.set_title(f"{TITLES[bench]}\n{ERROR_LABELS[err]}", fontsize=9)
    handles, labels = axes[0][0].get_legend_handles_labels()
    if handles:
        fig.legend(handles, labels, loc="center right", fontsize=7, frameon=False,
                   title="Pareto front of\nmethod / smoothing", title_fontsize=7)
    fig.tight_layout(rect=(0, 0, 1 - 2.0 / fig.get_figwidth(), 1))
    fig.savefig(path, dpi=110, metadata={"Software": None})
    plt.close(fig)
