"""Run outputs: summary.json (atomic), solution.xdmf, PNG plots. Rank 0 writes files."""
from __future__ import annotations

import json
import os
import tempfile
from pathlib import Path

import numpy as np


def write_atomic(path: Path, text: str) -> None:
    """Write via a temporary file and rename, so a reader never sees half a file."""
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.")
    try:
        with os.fdopen(fd, "w") as f:
            f.write(text)
        os.replace(tmp, path)
    except BaseException:
        os.unlink(tmp)
        raise


def write_summary(out: Path, summary: dict) -> None:
    write_atomic(out / "summary.json", json.dumps(summary, indent=1, default=_jsonable) + "\n")


def _jsonable(o):
    if isinstance(o, np.generic):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    raise TypeError(f"not JSON serializable: {type(o)}")


def plot_reactions(out: Path, steps: list[dict]) -> Path | None:
    """Reaction force components of every support against pseudo-time."""
    if not steps or not steps[0].get("reactions"):
        return None
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    t = [0.0] + [s["time"] for s in steps]
    fig, ax = plt.subplots(figsize=(6, 4))
    for label in steps[0]["reactions"]:
        for comp in steps[0]["reactions"][label]:
            ax.plot(t, [0.0] + [s["reactions"][label][comp] for s in steps], "o-", ms=3,
                    label=f"{label} R{comp}")
    ax.set_xlabel("pseudo-time (load factor)")
    ax.set_ylabel("reaction force")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7)
    fig.tight_layout()
    path = out / "reactions.png"
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


def plot_convergence(out: Path, steps: list[dict]) -> Path | None:
    """Newton residual history of every step (log scale): quadratic convergence shows."""
    if not steps:
        return None
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(6, 4))
    for s in steps:
        r = np.asarray(s["residuals"], dtype=float)
        ax.semilogy(np.arange(len(r)), np.maximum(r, 1e-300), "o-", ms=3,
                    label=f"step {s['step']}" if len(steps) <= 10 else None)
    ax.set_xlabel("residual evaluation in the step (Newton iterations, all augmentations)")
    ax.set_ylabel("|R|")
    ax.grid(alpha=0.3, which="both")
    if len(steps) <= 10:
        ax.legend(fontsize=7)
    fig.tight_layout()
    path = out / "convergence.png"
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path
