"""Run outputs: summary.json (atomic), solution.xdmf, PNG plots. Rank 0 writes files.

Every file goes under the output directory (``--out``): names that become file names are
checked by the scene (contact pairs), and the directory is checked before meshing
(:func:`prepare_out`). A failed write raises OSError naming the file; the run stops
with a message naming the disk (:func:`write_failure`), and what converged before is kept
(atomic writes leave the last good file and no temporary one).
"""
from __future__ import annotations

import errno
import json
import os
import re
import tempfile
from glob import escape as glob_escape
from pathlib import Path

import numpy as np

from .scene import SceneError


def prepare_out(out: Path) -> None:
    """Create ``out`` if needed and prove a file can be written there (rank 0): a file, a
    path under a file, a read-only or unwritable place is refused before any meshing."""
    key = f"--out {out}"
    if out.exists() and not out.is_dir():
        raise SceneError(f"{key}: exists and is not a directory")
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise SceneError(f"{key}: cannot create the directory ({e.strerror})") from None
    try:
        fd, probe = tempfile.mkstemp(dir=out, prefix=".write-test.")
        try:
            os.write(fd, b"x")
        finally:
            os.close(fd)
            os.unlink(probe)
    except OSError as e:
        raise SceneError(f"{key}: cannot write there ({e.strerror})") from None


#: what a run writes into ``--out`` (beside interface/<pair>_NNNN.csv, <pair>_pressure.png)
OWN_FILES = ("summary.json", "scene.json", "checkpoint.npz", "solution.xdmf", "solution.h5",
             "solution_from_step_*.xdmf", "solution_from_step_*.h5", "reactions.png",
             "convergence.png")


def clear_previous(out: Path) -> int:
    """Remove a previous run's files from ``out`` (rank 0, before a new run writes there):
    a run without XDMF or with other pair names would otherwise leave them beside its own
    summary, to be taken for this run's. Only OWN_FILES go, and in ``interface/`` the
    files of the pairs the previous run's scene.json names; nothing through a symbolic
    link to a directory. Returns how many files went."""
    paths = [p for pattern in OWN_FILES for p in out.glob(pattern)]
    folder = out / "interface"
    if folder.is_dir() and not folder.is_symlink():
        try:
            names = [c["name"] for c in json.loads((out / "scene.json").read_text())
                     .get("contacts", [])]
        except (OSError, ValueError, TypeError, KeyError, AttributeError):
            names = []      # no readable record of its pairs: their files stay
        for n in names:
            paths += [p for p in folder.glob(f"{glob_escape(n)}_*")
                      if p.name[len(n):] == "_pressure.png"
                      or re.fullmatch(r"_\d{4,}\.csv", p.name[len(n):])]
    removed = 0
    for p in paths:
        if p.is_file() or p.is_symlink():
            try:
                p.unlink()
            except OSError as e:
                raise SceneError(f"--out {out}: cannot remove the previous run's {p} "
                                 f"({e.strerror})") from None
            removed += 1
    return removed


def write_atomic(path: Path, data: str | bytes) -> None:
    """Write via a temporary file and rename, so a reader never sees half a file and a
    failed write (a full disk) leaves the previous file and no temporary one. Raises
    OSError with ``filename`` = path."""
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.")
    except OSError as e:
        raise OSError(e.errno, e.strerror, str(path)) from None
    try:
        with os.fdopen(fd, "wb" if isinstance(data, bytes) else "w") as f:
            f.write(data)
        os.replace(tmp, path)
    except BaseException as e:
        os.unlink(tmp)
        if isinstance(e, OSError):
            raise OSError(e.errno, e.strerror, str(path)) from None
        raise


def write_failure(out: Path, e: OSError, kept: str) -> str:
    """The one-line message of a failed write: which file, why, and for a full disk, which
    disk (its mount point and free bytes); ``kept`` says what is still there."""
    name = Path(e.filename).name if e.filename else "an output file"
    text = f"{out}: cannot write {name}: {e.strerror or e}"
    if e.errno in (errno.ENOSPC, errno.EDQUOT, errno.EIO):
        # EIO: the HDF5 library failed (_dolfinx.XDMFWriter) and does not say why; the
        # disk's free space lets the user see whether it was a full disk
        mount = _mount_point(out)
        full = "is full: " if e.errno != errno.EIO else "has "
        try:
            free = os.statvfs(out).f_bavail * os.statvfs(out).f_frsize
            text += f" (the disk mounted at {mount} {full}{free:,} bytes free)"
        except OSError:
            text += f" (the disk mounted at {mount} is full)" if e.errno != errno.EIO else ""
    return f"{text}; {kept}"


def _mount_point(path: Path) -> Path:
    p = Path(os.path.abspath(path))
    while not os.path.ismount(p) and p != p.parent:
        p = p.parent
    return p


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
