"""A contact pair's files in a run's output directory: the interface table of every step
as CSV (``interface/<pair>_<step>.csv``) and the pressure plot."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..contact.output import interface_table
from .output import save_figure, write_file


def write_interface(pair, out: Path, step: int) -> None:
    """``out/interface/<pair>_<step>.csv``: the :func:`interface_table` (rank 0 calls it)."""
    d = interface_table(pair)
    cols = tuple(d)
    lines = [",".join(cols)]
    for row in zip(*(d[c] for c in cols)):
        lines.append(",".join(f"{v:.12g}" if isinstance(v, float) else str(v) for v in row))
    write_file(out, f"interface/{pair.name}_{step:04d}.csv", "\n".join(lines) + "\n")


def plot_pressure(pair, out: Path) -> None:
    """``out/interface/<pair>_pressure.png``: nodal pressure at the last converged step."""
    if pair.state is None:
        return
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    d = interface_table(pair)
    fig, ax = plt.subplots(figsize=(6, 3.5))
    order = np.argsort(d["x"])
    ax.plot(d["x"][order], d["pressure"][order], "o-", ms=3)
    on = d["pressure"] > 0
    if on.any():  # zoom on the contact zone
        lo, hi = d["x"][on].min(), d["x"][on].max()
        pad = max(0.5 * (hi - lo), 1e-12)
        ax.set_xlim(lo - pad, hi + pad)
    ax.set_xlabel("x (current configuration)")
    ax.set_ylabel("contact pressure")
    ax.set_title(f"{pair.name}: pressure at the last converged step")
    ax.grid(alpha=0.3)
    fig.tight_layout()
    try:
        save_figure(fig, out, f"interface/{pair.name}_pressure.png")
    finally:
        plt.close(fig)
