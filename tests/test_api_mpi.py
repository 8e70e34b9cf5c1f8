"""The library API under MPI equals serial: the ring between two plates
(demos/demo_api_ring.py: two frictional pairs, LoadStepper, reactions summed over the
ranks, fields written by every rank) gives the same squeeze force, reactions and contact
forces at every step on 1 and 2 ranks."""
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
