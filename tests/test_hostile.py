"""Hostile input and faults (issue 18): every case of tests/hostile/cases.py gets its
expected outcome — the exit code, the key or file at fault named in a one-line message,
no traceback, nothing written outside ``--out``, and (``stage = "scene"``) no meshing
started. Most cases run in this process (``fenicsx_mortar.cli.main``); signals, the full
disk and the MPI cases run as processes, the MPI ones under ``mpirun -n 2``.
``python -m tests.hostile.outcomes`` tabulates the same cases by outcome, on any version.
"""
from __future__ import annotations

import numpy as np
import pytest

from fenicsx_mortar.cli import main
from hostile.cases import CASES, Skip, unmount
from hostile.harness import Donors, files_under, fresh, ours, run_process, stray

PREFIX = "fenicsx-mortar: error: "


@pytest.fixture(scope="module")
def donors(tmp_path_factory):
    return Donors(tmp_path_factory.mktemp("donors"))


def test_the_suite_is_large_enough():
    assert len(CASES) >= 100
    assert len({c.id for c in CASES}) == len(CASES)


def check_outcome(case, code, out, err, d, strays: list[str], problem=None) -> None:
    assert "Traceback" not in err + out, err[-3000:]
    assert code == case.expect, f"exit {code}: {err[-2000:] or out[-2000:]}"
    if case.expect == 2:
        assert err.startswith(PREFIX) and err.count("\n") == 1, err
        assert case.key in err, err
    elif case.expect == 1:
        assert case.key in err + out, err + out[-2000:]
        # warnings (one line each) may come first: what was noticed before the failure
        lines = [x for x in err.splitlines() if x.strip("\x00 ")
                 and not x.startswith("fenicsx-mortar: warning: ")]
        assert not lines or (len(lines) == 1 and lines[0].startswith(PREFIX)), err
    else:
        assert case.key in out, out[-2000:]
    if case.check is not None:
        assert (case.check(d, out, err) if problem is None else problem) == ""
    assert strays == [], f"written outside --out: {strays}"


def _no_meshing(*args, **kwargs):
    raise AssertionError("meshing started: this input must be refused before")


@pytest.mark.parametrize("case", [c for c in CASES if c.mode == "inproc"], ids=lambda c: c.id)
def test_hostile(case, tmp_path, donors, capsys, monkeypatch):
    d = tmp_path / "case"
    try:
        case.write_inputs(d, donors)
    except Skip as e:
        pytest.skip(str(e))
    before = files_under(d)
    monkeypatch.chdir(d / "work")
    if case.stage == "scene":
        import gmsh
        monkeypatch.setattr(gmsh, "initialize", _no_meshing)
    try:
        code = main(case.args(d))
        out, err = capsys.readouterr()
        check_outcome(case, code, out, err, d, stray(d, before))
    finally:
        unmount(d)


@pytest.mark.parametrize("case", [c for c in CASES if c.mode == "process"], ids=lambda c: c.id)
def test_hostile_process(case, tmp_path, donors):
    d = fresh(tmp_path / "case")
    try:
        o = run_process(case, d, donors)
    except Skip as e:
        pytest.skip(str(e))
    assert o.code is not None, f"hung: {o.err[-2000:]}"
    check_outcome(case, o.code, o.out, o.err, d, o.stray, o.problem)


@pytest.mark.mpi
@pytest.mark.parametrize("case", [c for c in CASES if c.mode == "mpi"], ids=lambda c: c.id)
def test_hostile_mpi(case, tmp_path, donors):
    """Under mpirun -n 2 every rank ends, promptly, with one message (from rank 0) and the
    same exit code (mpirun returns the first non-zero one)."""
    d = fresh(tmp_path / "case")
    o = run_process(case, d, donors)
    assert o.code is not None, f"hung (killed after {case.timeout} s): {o.err[-2000:]}"
    assert o.seconds < 45, f"took {o.seconds:.0f} s"
    check_outcome(case, o.code, o.out, ours(o.err), d, o.stray, o.problem)


def test_singular_factorization_is_a_step_failure():
    """Library level: a stiffness with zero rows (half the cells carry no material) makes
    MUMPS fail (INFOG(1) = -10); the solve returns not converged with that message, no
    exception."""
    import ufl
    from mpi4py import MPI

    import fenicsx_mortar as fm
    from fenicsx_mortar import _dolfinx as dx
    msh = dx.unit_square(MPI.COMM_WORLD, 4, 4)
    V = dx.vector_space(msh)
    u, v = dx.Function(V), ufl.TestFunction(V)
    # no stiffness right of x = 1/2: the dofs there have zero rows
    k = ufl.conditional(ufl.lt(ufl.SpatialCoordinate(msh)[0], 0.5), 1.0, 0.0)
    F = (k * ufl.inner(ufl.grad(u), ufl.grad(v)) - ufl.dot(ufl.as_vector((1.0, 0.0)), v)) \
        * ufl.dx(domain=msh, metadata={"quadrature_degree": 2})
    bottom = dx.locate_vertices(msh, lambda x: np.isclose(x[1], 0.0))
    bcs = [dx.dirichletbc(dx.constant(msh, 0.0), dx.vertex_dofs(V, i, bottom), V, i)
           for i in range(2)]
    result = fm.ContactProblem(F, u, bcs, []).solve()
    assert not result.converged
    assert "INFOG(1) = -10" in result.reason and "singular" in result.reason, result.reason
