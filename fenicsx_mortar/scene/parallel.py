"""An error on any rank ends every rank, with the same message and exit code, promptly.

A rank that raises alone leaves the others waiting in the next collective call (a barrier,
a broadcast, an assembly) until mpirun is killed. So the steps that can fail on one rank
only — rank 0's file reads and writes, gmsh on rank 0 — run through :func:`on_rank0`,
which broadcasts the outcome, and steps that each rank does for itself through
:func:`agree`, which gathers the outcomes: either way every rank raises the same error at
the same point. For an exception nobody foresaw the command line ends all ranks with
``MPI_Abort`` (cli.py).
"""
from __future__ import annotations

import time
from typing import Callable, TypeVar

from mpi4py import MPI

from .model import SceneError

T = TypeVar("T")


class RunError(RuntimeError):
    """The run cannot go on (a write failed, start-up was interrupted): exit 1, one line
    naming the cause; what converged is kept."""


class RankOSError(RunError):
    """An OSError as the other ranks re-raise it: errno, strerror and filename kept, so
    every rank words the same message (output.write_failure)."""

    def __init__(self, errno: int | None, strerror: str | None, filename: str | None):
        super().__init__(f"{filename or ''}: {strerror}".lstrip(": "))
        self.errno, self.strerror, self.filename = errno, strerror, filename

    def __reduce__(self):
        return RankOSError, (self.errno, self.strerror, self.filename)


class BrokenOutput(RunError):
    """A write inside the HDF5 library (XDMF) failed. Raised on the ranks where it failed
    only: the others may be waiting inside the collective HDF5 call, so the ranks cannot
    agree on it, and the file can no longer be closed. The command line says it once and
    ends every rank (MPI_Abort)."""


class Interrupted(RunError):
    """SIGINT or SIGTERM outside the load steps: raised wherever each rank happens to be,
    so the ranks do not agree on it (cli.py ends them all)."""


def _portable(e: BaseException) -> Exception:
    """The error as every rank re-raises it (picklable, same message)."""
    if isinstance(e, (SceneError, RunError)):
        return e
    if isinstance(e, OSError):
        return RankOSError(e.errno, e.strerror or str(e), e.filename)
    return RunError(f"{type(e).__name__}: {e}")


def wait_for_all(comm: MPI.Comm) -> None:
    """A barrier that keeps Python running while it waits (a non-blocking barrier polled),
    so a rank waiting for rank 0 (meshing in gmsh, say) still answers a signal: in a
    blocking MPI call no Python signal handler runs, and mpirun kills the ranks one second
    after forwarding SIGTERM."""
    if comm.size == 1:
        return
    request = comm.Ibarrier()
    while not request.Test():
        time.sleep(0.005)


def on_rank0(comm: MPI.Comm, fn: Callable[[], T], share: bool = False) -> T | None:
    """``fn()`` on rank 0 only; an error there is raised on every rank. ``share``: every
    rank gets rank 0's result (else only rank 0 has it)."""
    result, error = None, None
    if comm.rank == 0:
        try:
            result = fn()
        except Exception as e:
            if comm.size == 1:
                raise
            error = e
    if comm.size == 1:
        return result
    shared = comm.bcast((_portable(error) if error else None, result if share else None),
                        root=0)
    if error is not None:
        raise error           # rank 0: the original, with its traceback
    if shared[0] is not None:
        raise shared[0]
    return result if comm.rank == 0 else shared[1]


def agree(comm: MPI.Comm, fn: Callable[[], T]) -> T:
    """``fn()`` on every rank; if it fails on any, every rank raises the error of the
    lowest failing rank."""
    try:
        result, error = fn(), None
    except Exception as e:
        if comm.size == 1:
            raise
        result, error = None, e
    if comm.size == 1:
        return result
    errors = comm.allgather(_portable(error) if error else None)
    first = next((e for e in errors if e is not None), None)
    if first is not None:
        if error is not None and type(error) is type(first) and str(error) == str(first):
            raise error
        raise first
    return result
