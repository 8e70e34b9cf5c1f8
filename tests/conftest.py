import os
import subprocess
import sys
from pathlib import Path

import pytest

# before any test module imports petsc4py or DOLFINx: PyPI's wheel finds MPICH's libmpi only
# once mpi4py.MPI has loaded it (fenicsx_mortar/_dolfinx.py)
import mpi4py.MPI  # noqa: F401

ROOT = Path(__file__).resolve().parents[1]
# the tests of benchmarks/ import it as a package from the repository root, wherever
# pytest is started
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))
from fenicsx_mortar.mpi_launch import mpi_command, mpi_env  # noqa: E402

# OMP_NUM_THREADS: Debian 13's MUMPS runs OpenMP threads, one per core in every rank, so
# mpirun -n 2..4 on 2 cores ran the parallel solves 3x slower (thread oversubscription)
MPI_ENV = {**mpi_env({}), "OMP_NUM_THREADS": "1"}


def run_cli(*args: str, ranks: int = 1, timeout: float = 600) -> subprocess.CompletedProcess:
    """Run ``python -m fenicsx_mortar ARGS`` (under the MPI launcher when ranks > 1)."""
    cmd = [sys.executable, "-m", "fenicsx_mortar", *args]
    return run_python(cmd, ranks=ranks, timeout=timeout)


def run_python(cmd: list[str], ranks: int = 1, timeout: float = 600) -> subprocess.CompletedProcess:
    if ranks > 1:
        cmd = [*mpi_command(ranks), *cmd]
    env = {**os.environ, **MPI_ENV}
    return subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, cwd=ROOT, env=env)


@pytest.fixture
def root() -> Path:
    return ROOT
