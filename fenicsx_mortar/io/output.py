"""Run outputs: summary.json (atomic), solution.xdmf, PNG plots. Rank 0 writes files.

Every file goes under the output directory (``--out``) and through :func:`write_file`,
which opens it directory by directory from ``--out`` without following a symbolic link
(a link inside ``--out`` is replaced by the file, or refused where it stands for a
directory), so no write can land outside. The directory is checked before meshing
(:func:`prepare_out`) and locked for the run (:func:`locked`): a second run into it is
refused. A failed write raises OSError naming the file; the run stops with a message
naming the disk (:func:`write_failure`), and what converged before is kept (atomic writes
leave the last good file and no temporary one).
"""
from __future__ import annotations

import contextlib
import errno
import fcntl
import io
import json
import os
import re
import secrets
import stat
import tempfile
from glob import escape as glob_escape
from pathlib import Path, PurePosixPath
from typing import Iterator

import numpy as np

from ..scene import SceneError, json_loads


def prepare_out(out: Path) -> None:
    """Create ``out`` if needed and prove a file can be written there (rank 0): a file, a
    path under a file, a read-only or unwritable place is refused before any meshing."""
    key = f"--out {out}"
    if out.exists() and not out.is_dir():
        raise SceneError(f"{key}: exists and is not a directory")
    _refuse_linked_dirs(out, key)
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
            names = [c["name"] for c in json_loads((out / "scene.json").read_text())
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


#: the directories a run writes into inside ``--out``
OWN_DIRS = ("interface",)
_DIR_FLAGS = os.O_RDONLY | os.O_DIRECTORY | os.O_NOFOLLOW | os.O_CLOEXEC


def _refuse_linked_dirs(out: Path, key: str) -> None:
    """A directory the run writes into that is a symbolic link (or not a directory): the
    outputs would go where it points; refused by name before anything is written."""
    for name in OWN_DIRS:
        p = out / name
        if p.is_symlink():
            raise SceneError(f"{key}: {name} is a symbolic link (to {os.readlink(p)}); a run "
                             "writes into its own directories, never through a link: remove "
                             "it")
        if p.exists() and not p.is_dir():
            raise SceneError(f"{key}: {name} exists and is not a directory; remove it")


def _parts(rel: str | Path) -> tuple[str, ...]:
    parts = PurePosixPath(rel).parts
    if not parts or PurePosixPath(rel).is_absolute() or any(
            p in ("", ".", "..") or "\x00" in p for p in parts):
        raise ValueError(f"{rel!r}: not a plain relative path inside the output directory")
    return parts


def write_file(out: Path, rel: str | Path, data: str | bytes) -> Path:
    """Write ``out/rel`` (the one way a run writes a file). The directories from ``out``
    on are opened one by one without following links (a link to a directory is refused:
    ELOOP or ENOTDIR), missing ones made; the bytes go to a temporary file beside the
    target, renamed over it, so a reader never sees half a file, a failed write (a full
    disk) leaves the previous file and no temporary one, and a link at the target's
    place is replaced, not followed. ``out`` itself may be a link (the user's choice of
    place). Raises OSError with ``filename`` = ``out/rel``; returns that path."""
    parts = _parts(rel)
    path = Path(out, *parts)
    payload = data.encode() if isinstance(data, str) else bytes(data)
    fds: list[int] = []
    try:
        try:
            fds.append(os.open(out, os.O_RDONLY | os.O_DIRECTORY | os.O_CLOEXEC))
            for name in parts[:-1]:
                with contextlib.suppress(FileExistsError):
                    os.mkdir(name, dir_fd=fds[-1])
                fds.append(os.open(name, _DIR_FLAGS, dir_fd=fds[-1]))
        except OSError as e:
            why = "a symbolic link or not a directory on the way (outputs are never " \
                "written through a link)" if e.errno in (errno.ELOOP, errno.ENOTDIR) \
                else e.strerror
            raise OSError(e.errno, why, str(path)) from None
        _write_in(fds[-1], parts[-1], payload, path)
    finally:
        for fd in fds:
            os.close(fd)
    return path


def _write_in(dir_fd: int, name: str, payload: bytes, path: Path) -> None:
    tmp = f".{name}.{secrets.token_hex(4)}"
    try:
        fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW | os.O_CLOEXEC,
                     0o666, dir_fd=dir_fd)
    except OSError as e:
        raise OSError(e.errno, e.strerror, str(path)) from None
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(payload)
        os.replace(tmp, name, src_dir_fd=dir_fd, dst_dir_fd=dir_fd)
    except BaseException as e:
        with contextlib.suppress(OSError):
            os.unlink(tmp, dir_fd=dir_fd)
        if isinstance(e, OSError):
            raise OSError(e.errno, e.strerror, str(path)) from None
        raise


def path_for(out: Path, rel: str | Path) -> Path:
    """The path of ``out/rel`` for a library that opens it by name itself (HDF5): its
    directories are checked as :func:`write_file` does, and a symbolic link at its place
    (for ``.xdmf``, also at its ``.h5``) removed: the library would write through it.
    Raises OSError naming the path."""
    parts = _parts(rel)
    path = Path(out, *parts)
    d = Path(out)
    for name in parts[:-1]:
        d = d / name
        if d.is_symlink() or (d.exists() and not d.is_dir()):
            raise OSError(errno.ELOOP, "a symbolic link or not a directory on the way "
                          "(outputs are never written through a link)", str(path))
        with contextlib.suppress(FileExistsError):
            d.mkdir()
    for p in (path, path.with_suffix(".h5")) if path.suffix == ".xdmf" else (path,):
        with contextlib.suppress(FileNotFoundError):   # every rank may try
            if stat.S_ISLNK(os.lstat(p).st_mode):
                os.unlink(p)
    return path


@contextlib.contextmanager
def locked(out: Path, key: str = "--out") -> Iterator[None]:
    """Hold ``out``'s lock (an exclusive ``flock`` on the directory itself: no file is
    left behind, and the kernel drops it when the process ends, however it ends) for the
    run; a directory another run holds is refused by name (SceneError)."""
    try:
        fd = os.open(out, os.O_RDONLY | os.O_DIRECTORY | os.O_CLOEXEC)
    except OSError as e:
        raise SceneError(f"{key} {out}: cannot open the directory ({e.strerror})") from None
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            raise SceneError(f"{key} {out}: another run is writing there (it holds the "
                             "directory's lock); wait for it to end or choose another "
                             "directory") from None
        except OSError:
            pass        # a file system without locks (some network mounts): unlocked
        yield
    finally:
        os.close(fd)


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
    write_file(out, "summary.json", json.dumps(summary, indent=1, default=_jsonable) + "\n")


def save_figure(fig, out: Path, rel: str) -> Path:
    """A matplotlib figure as PNG through :func:`write_file` (savefig would follow a link
    at the path)."""
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=120)
    return write_file(out, rel, buf.getvalue())


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
    try:
        return save_figure(fig, out, "reactions.png")
    finally:
        plt.close(fig)


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
    try:
        return save_figure(fig, out, "convergence.png")
    finally:
        plt.close(fig)
