"""The library API under MPI equals serial: the ring between two plates
(demos/demo_api_ring.py: two frictional pairs, LoadStepper, reactions summed over the
ranks, fields written by every rank) gives the same squeeze force, reactions and contact
forces at every step on 1 and 2 ranks."""
import json
import re
import sys

import pytest

from conftest import ROOT, run_python

LINE = re.compile(r"t = ([\d.]+): squeeze force ([-+\d.e]+), bottom reaction ([-+\d.e]+), "
                  r"contact forces on the ring ([-+\d.e]+) / ([-+\d.e]+)")


def steps(ranks: int, out) -> list[tuple[float, ...]]:
    proc = run_python([sys.executable, str(ROOT / "demos/demo_api_ring.py"), str(out)],
                      ranks=ranks)
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
    found = [tuple(map(float, m.groups())) for m in LINE.finditer(proc.stdout)]
    assert len(found) == 4, proc.stdout[-2000:]
    assert (out / "ring.h5").is_file()
    return found


@pytest.mark.mpi
def test_the_ring_on_two_ranks_equals_serial(tmp_path):
    serial, parallel = steps(1, tmp_path / "n1"), steps(2, tmp_path / "n2")
    for a, b in zip(serial, parallel):
        assert b == pytest.approx(a, rel=1e-8, abs=1e-10)


#: after a solve, every rank holds the same parallel PETSc objects; then a new matrix on the
#: same communicator (a collective creation) completes on both ranks
AFTER_SOLVE = """
import gc
import json
from mpi4py import MPI
from petsc4py import PETSc
from fenicsx_mortar import _dolfinx as dx, load_scene, newton, solve
solvers = []
init = newton.NewtonSolver.__init__
def keep(self, *a, **k):
    init(self, *a, **k)
    solvers.append(self)
newton.NewtonSolver.__init__ = keep
sc = load_scene("demos/scenes/hertz.toml")
sc.output.xdmf = sc.output.plots = False
sc.steps.count = 1
res = solve(sc, log=lambda s: None)
gc.collect()
live = sorted(type(o).__name__ for o in gc.get_objects() if isinstance(o, PETSc.Object)
              and o.handle and o.getComm().getSize() > 1)
every = MPI.COMM_WORLD.allgather(live)
A = dx.create_matrix(solvers[-1].system.jacobian_form)
if MPI.COMM_WORLD.rank == 0:
    print("converged", res.converged, "live", json.dumps(every), "matrix", A.getSize())
"""


@pytest.mark.mpi
def test_a_solve_leaves_every_rank_the_same_petsc_objects():
    # a contact layout cache held the Jacobian on the one rank that owned all contact rows:
    # the next matrix created on that communicator deadlocked (PETSc duplicated the
    # communicator on one rank only)
    proc = run_python([sys.executable, "-c", AFTER_SOLVE], ranks=2, timeout=120)
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
    m = re.search(r"converged True live (\[.*\]) matrix", proc.stdout)
    assert m, proc.stdout[-2000:]
    every = json.loads(m.group(1))
    assert len(every) == 2 and every[0] == every[1]
