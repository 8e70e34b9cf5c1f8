"""The command line that starts N MPI ranks, for either MPI the package runs on.

Debian's DOLFINx runs on Open MPI (``mpirun -n N --oversubscribe``, and as root two
``OMPI_ALLOW_RUN_AS_ROOT*`` variables); PyPI's ``dolfinx-solver-real`` on the ``mpich``
wheel's MPICH, whose Hydra launcher is ``mpiexec`` in the venv's ``bin`` (Open MPI's
mpirun cannot start its ranks, and Hydra refuses ``--oversubscribe``: it needs none). The
tests and benchmarks build their MPI command lines here. Nothing here starts MPI.
"""
from __future__ import annotations

import functools
import os
import shutil
import subprocess
import sys
from pathlib import Path

#: Open MPI as root, and more ranks than cores (4.x's and 5.x's spellings); MPICH ignores
#: them
OPEN_MPI_ENV = {"OMPI_ALLOW_RUN_AS_ROOT": "1", "OMPI_ALLOW_RUN_AS_ROOT_CONFIRM": "1",
                "OMPI_MCA_rmaps_base_oversubscribe": "1",
                "PRTE_MCA_rmaps_default_mapping_policy": ":oversubscribe"}


@functools.lru_cache(maxsize=None)
def launcher() -> tuple[str, str]:
    """The MPI launcher for this Python and its kind.

    Returns:
        (path, kind): the ``mpiexec`` beside ``sys.executable`` (a venv with the ``mpich``
        wheel) if there is one, else ``mpirun`` or ``mpiexec`` on PATH; kind is
        "openmpi", "mpich" or "unknown", from its ``--version``.

    Raises:
        RuntimeError: no launcher is found.
    """
    beside = Path(sys.executable).parent / "mpiexec"
    found = [str(beside)] if os.access(beside, os.X_OK) else []
    found += [p for p in (shutil.which("mpirun"), shutil.which("mpiexec")) if p]
    if not found:
        raise RuntimeError(f"no MPI launcher: neither {beside} nor mpirun/mpiexec on PATH "
                           "(install Open MPI's mpirun, or the 'mpich' wheel into the venv)")
    path = found[0]
    try:
        proc = subprocess.run([path, "--version"], capture_output=True, text=True, timeout=60)
        text = proc.stdout + proc.stderr
    except (OSError, subprocess.TimeoutExpired):
        text = ""
    kind = ("openmpi" if "Open MPI" in text or "OpenRTE" in text
            else "mpich" if "HYDRA" in text or "MPICH" in text else "unknown")
    return path, kind


def mpi_command(ranks: int) -> list[str]:
    """The launcher's arguments for ``ranks`` processes (the program to run follows).

    Args:
        ranks: number of MPI processes, at least 1; more than cores is allowed.

    Returns:
        e.g. ``["mpirun", "-n", "3", "--oversubscribe"]`` (Open MPI) or
        ``[".venv/bin/mpiexec", "-n", "3"]`` (MPICH).
    """
    if int(ranks) != ranks or ranks < 1:
        raise ValueError(f"ranks: a positive whole number, not {ranks!r}")
    path, kind = launcher()
    return [path, "-n", str(int(ranks))] + (["--oversubscribe"] if kind == "openmpi" else [])


def mpi_env(base: dict[str, str] | None = None) -> dict[str, str]:
    """``base`` (default: this process's environment) with Open MPI's switches for root and
    oversubscription and one OpenMP thread per rank (Debian 13's MUMPS starts one a core in
    every rank otherwise: 3x slower on 2 cores).

    Args:
        base: the environment to extend.

    Returns:
        A new dict.
    """
    env = dict(os.environ if base is None else base)
    env.update(OPEN_MPI_ENV)
    env.setdefault("OMP_NUM_THREADS", "1")
    return env
