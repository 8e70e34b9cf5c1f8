"""The Newton driver (newton.py), load stepping (stepping.py) and the acceptance of a
converged state (acceptance.py)."""
from __future__ import annotations

import pytest

from fenicsx_mortar import solve
from benchmarks.study.cases import Case
from benchmarks.study.scenes import make_scene


def test_full_newton_retry_rescues_stiff_penalty_hertz(monkeypatch):
    """Hertz (dead load F = 1, the disk held by contact alone), mortar, penalty 10 E/h at
    h = a/2, without the penalty continuation (every solve at the final ε): the l2 line
    search stalls on the active set's kinks in the first increment (this failed at every
    cut down to the floor); the increment retried with full Newton steps converges.
    Checked physically: the contact force on the disk balances the load (F = 1 downward,
    so the block pushes the disk up with 1)."""
    from fenicsx_mortar.contact import enforcement
    monkeypatch.setattr(enforcement.Penalty, "begin_step",
                        lambda self: self.epsilon.fill(self.epsilon0))
    scene = make_scene(Case("hertz", "mortar", "none", "penalty-10", 0))
    res = solve(scene, log=lambda s: None)
    assert res.converged, res.message
    rec = res.steps[-1]["contact"]["hertz"]
    assert rec["force_on_slave"][1] == pytest.approx(1.0, rel=1e-8)


@pytest.mark.parametrize("stalled", [True, False])
def test_only_a_stalled_newton_is_retried_with_full_steps(stalled):
    """A Newton solve that ran out of iterations (its line search stuck on a kink) is tried
    again with full steps; one that failed otherwise (a residual that is not finite, a
    rejected state, a failed linear solve) goes straight to the cut: full steps would go
    the same way (see full_newton_steps)."""
    from types import SimpleNamespace

    from fenicsx_mortar.newton import StepResult
    from fenicsx_mortar.stepping import full_newton_steps
    searches, retried = [], []
    newton = SimpleNamespace(line_search="l2-full", pairs=[], set_line_search=searches.append)
    inc = SimpleNamespace(stepper=SimpleNamespace(problem=SimpleNamespace(newton=newton)),
                          below_floor=False, out_of_cuts=False,
                          attempt=lambda: StepResult(converged=True),
                          retried=lambda how, reason: retried.append(how))
    failed = StepResult(converged=False, reason="Newton failed", stalled=stalled)
    res = full_newton_steps(inc, failed)
    assert res.converged == stalled
    assert retried == (["full Newton steps"] if stalled else [])
    assert searches == (["basic", "l2-full"] if stalled else [])


def test_a_failed_factorization_does_not_poison_the_next_solve():
    """A singular stiffness (no material right of x = 1/2: zero rows) fails MUMPS with
    INFOG(1) = -10; once the material is back, the same problem solves, to the solution of
    a problem that never failed. Without resetting the linear solver the second solve
    failed at once with INFOG(1) = -3 (B3 with a finer master: after one singular iterate
    the step cuts never factorized again)."""
    import numpy as np
    import ufl
    from mpi4py import MPI

    import fenicsx_mortar as fm
    from fenicsx_mortar import _dolfinx as dx
    msh = dx.unit_square(MPI.COMM_WORLD, 4, 4)
    V = dx.vector_space(msh)
    left = dx.locate_vertices(msh, lambda x: np.isclose(x[0], 0.0))
    bcs = [dx.dirichletbc(dx.constant(msh, 0.0), dx.vertex_dofs(V, i, left), V, i)
           for i in range(2)]

    def problem(right_stiffness: float):
        u, v = dx.Function(V), ufl.TestFunction(V)
        right = dx.constant(msh, right_stiffness)
        k = ufl.conditional(ufl.lt(ufl.SpatialCoordinate(msh)[0], 0.5), 1.0, right)
        F = (k * ufl.inner(ufl.grad(u), ufl.grad(v)) - ufl.dot(ufl.as_vector((1.0, 0.0)), v)) \
            * ufl.dx(domain=msh, metadata={"quadrature_degree": 2})
        return fm.ContactProblem(F, u, bcs, []), u, right

    failing, u, right = problem(0.0)
    first = failing.solve()
    assert not first.converged and "INFOG(1) = -10" in first.reason, first.reason
    right.value = 1.0
    second = failing.solve()
    assert second.converged, second.reason
    fresh, u_fresh, _ = problem(1.0)
    assert fresh.solve().converged
    assert np.max(np.abs(u_fresh.x.array)) > 0.1
    assert np.allclose(u.x.array, u_fresh.x.array, rtol=0.0, atol=1e-12)


def test_out_of_workspace_grows_it_instead_of_cutting(monkeypatch):
    """MUMPS with a negative workspace margin (``-mat_mumps_icntl_14 = -5``, passed through
    the scene like any MUMPS option) fails the factorization with INFOG(1) = -9 whatever
    the increment; the step is retried with ICNTL(14) doubled from MUMPS's 20 %, not cut,
    and gives the answer of a run without the option."""
    import numpy as np
    from fenicsx_mortar import load_scene
    from conftest import ROOT

    def run(petsc):
        scene = load_scene(ROOT / "demos/scenes/patch_test.toml")
        scene.solver.petsc = petsc
        return solve(scene, log=lambda s: None)

    from fenicsx_mortar import newton
    grown = []
    grow = newton.NewtonSolver.grow_workspace
    monkeypatch.setattr(newton.NewtonSolver, "grow_workspace",
                        lambda self: grown.append(grow(self)) or grown[-1])
    plain, starved = run({}), run({"-mat_mumps_icntl_14": -5})
    assert grown == [20]                    # one retry, from -5 to MUMPS's default margin
    assert starved.converged, starved.message
    assert [s["cuts"] for s in starved.steps] == [0]
    assert np.allclose(starved.pairs[0].interface()["pressure"],
                       plain.pairs[0].interface()["pressure"], rtol=0.0, atol=1e-12)


@pytest.mark.parametrize("scale", [1e-15, 1e-200])
def test_pseudo_time_is_only_a_label(scale):
    """Scaling every pseudo-time (the steps and the load curve's times) by ``scale`` leaves
    the load path, hence the solution, unchanged. Targets below 1e-14 used to be skipped as
    if reached at t = 0: 0 steps, no load, reported as converged."""
    import numpy as np
    from fenicsx_mortar import load_scene
    from fenicsx_mortar.scene import LoadCurve
    from conftest import ROOT

    def run(s):
        scene = load_scene(ROOT / "tests/bad_input/_base.toml")
        scene.curves = {"c": LoadCurve(t=[0.0, s], value=[0.0, 1.0])}
        scene.pressures[0].curve = "c"
        scene.steps.count, scene.steps.times = None, [0.5 * s, s]
        return solve(scene.validate(), log=lambda s: None)

    unit, scaled = run(1.0), run(scale)
    assert scaled.converged and len(scaled.steps) == len(unit.steps) == 2
    p, q = unit.pairs[0].interface(), scaled.pairs[0].interface()
    assert np.max(p["pressure"]) > 0.5             # the load did act
    assert np.allclose(q["pressure"], p["pressure"], rtol=0.0, atol=1e-12)


def test_a_displacement_far_beyond_the_mesh_is_not_a_solution():
    """E = 1e-12 under a pressure of 1: Newton converged to |u| = 1e14 with zero reactions
    (the follower load on a collapsed edge), which was accepted. The step guard refuses a
    displacement of more than FLOWN_OFF mesh diameters, and only that."""
    from fenicsx_mortar import load_scene
    from fenicsx_mortar.acceptance import FLOWN_OFF, Acceptance
    from fenicsx_mortar.scene.bulk import build_bulk
    from fenicsx_mortar.scene.meshing import build_domain
    from conftest import ROOT

    scene = load_scene(ROOT / "tests/bad_input/_base.toml")
    bulk = build_bulk(scene, build_domain(scene))
    guard = Acceptance(bulk.u)
    assert guard.size > 0
    bulk.u.x.array[:] = 0.5 * FLOWN_OFF * guard.size
    assert guard.flown_off() is None
    bulk.u.x.array[1] = 2.0 * FLOWN_OFF * guard.size
    assert "times the size of the mesh" in guard.flown_off()


@pytest.mark.parametrize("a, inverted", [(0.45, True), (0.55, False)])
def test_a_cell_inverted_only_at_a_corner_is_not_a_solution(a, inverted):
    """One Q1 cell, its corner (1, 1) moved to (a, a): J = 1 + 2(a − 1)·ξ on the diagonal
    ξ = η, negative at the corner for a < 1/2 but positive at the 2 × 2 Gauss points
    (ξ = 0.789) for a > 0.366. A folded slave converged that way (two blocks overlapping by
    two elements); J at the corners is the exact test (J is affine in ξ and η)."""
    import numpy as np
    from fenicsx_mortar import load_scene
    from fenicsx_mortar.acceptance import Acceptance
    from fenicsx_mortar.scene.bulk import build_bulk
    from fenicsx_mortar.scene.meshing import build_domain
    from conftest import ROOT

    scene = load_scene(ROOT / "tests/bad_input/_base.toml")
    scene.mesh.generator, scene.mesh.params = "block", {"nx": 1, "ny": 1}
    scene.contacts, scene.dirichlet[0].boundary, scene.dirichlet[1].boundary = [], "bottom", "left"
    scene.pressures[0].boundary = "top"
    scene.bodies = scene.bodies[:1]
    scene.bodies[0].name = "block"
    bulk = build_bulk(scene.validate(), build_domain(scene))
    bulk.u.interpolate(lambda x: np.vstack([(a - 1.0) * x[0] * x[1]] * 2))
    dom = bulk.domain
    guard = Acceptance(bulk.u, cell_tags=dom.cell_tags,
                       body_names={dom.cell_groups["block"]: "block"})
    why = guard.inverted()
    assert (why is not None) == inverted
    if inverted:
        assert "1 cell(s)" in why and "'block'" in why


def test_after_a_cut_the_increment_grows_from_the_second_converged_step():
    """Increments above 0.25 fail: from 1.0 the stepper cuts twice, takes 0.25 twice, then
    doubles (0.5 fails, cut, 0.25 twice). Doubling right after the cut would retry the
    size that just failed after every converged increment: four failures, not three."""
    from types import SimpleNamespace

    from fenicsx_mortar.newton import StepResult
    from fenicsx_mortar.stepping import LoadStepper
    loads, tried = [0.0], []

    def solve(max_augmentations):
        inc = loads[-1] - loads[-2]
        tried.append(inc)
        if inc > 0.25 + 1e-12:
            loads.pop()  # set_load(t) of the last converged state follows a failure
            return StepResult(converged=False, reason="too large")
        return StepResult(converged=True, iterations=3)

    newton = SimpleNamespace(should_stop=lambda: None, line_search="l2-full", pairs=[])
    problem = SimpleNamespace(newton=newton, solve=solve)
    stepper = LoadStepper(problem, loads.append, [1.0], on_event=None)

    def set_load(t):
        if t != loads[-1]:
            loads.append(t)
    stepper.set_load = set_load
    result = stepper.run()
    assert result.completed and result.time == 1.0
    assert tried == [1.0, 0.5, 0.25, 0.25, 0.5, 0.25, 0.25]
