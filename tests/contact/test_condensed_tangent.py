"""The condensed tangent is consistent (fenicsx_mortar/condensation/, docs/condensation.md): along a
displacement direction δu off the rows P, lifted to [δu, δλ] by the recoveries with a
zero right-hand side (δu_P from the linearized constraints, δλ from the rows P), the
residual's change R(x + h d) − R(x) equals h × (Kc δu) on the displacement rows outside
P and vanishes on the rows P and on the multipliers' rows, up to O(h²): the Taylor
remainders fall as h². Frictionless, sticking (two multipliers per node) and slipping
(the λ_t row coupled to λ_n) states of the patch test with multipliers, dual basis."""
import numpy as np
import pytest

from conftest import ROOT
from fenicsx_mortar import load_scene
from fenicsx_mortar.condensation import CondensedSystem
from fenicsx_mortar.problem import ContactProblem
from fenicsx_mortar.scene.bulk import build_bulk
from fenicsx_mortar.scene.meshing import build_domain
from fenicsx_mortar.scene.runner import scene_pairs
from test_pair import assert_second_order, multiplier_state


def condensed_system(mu: float = 0.0):
    scene = load_scene(ROOT / "demos/scenes/patch_test.toml")
    scene.mesh.params = {"lower_nx": 8, "lower_ny": 4, "upper_nx": 10, "upper_ny": 2}
    scene.solver.linear_solver = "condensed-mumps"
    c = scene.contacts[0]
    c.enforcement.type, c.enforcement.epsilon = "lagrange", 1e4
    if mu > 0:
        c.friction.law, c.friction.mu = "coulomb", mu
    dom = build_domain(scene)
    bulk = build_bulk(scene, dom)
    pairs = scene_pairs(scene, dom, bulk.V)
    problem = ContactProblem(bulk.residual, bulk.u, bulk.bcs, pairs, bulk.jacobian,
                             settings=scene.solver)
    bulk.set_time(1.0)
    solver = problem.newton
    solver.domain = dom
    assert isinstance(solver.system, CondensedSystem)
    return solver, pairs[0]


def sets(st) -> np.ndarray:
    """Active set and stick/slip status (the sign of a sticking traction may change: the
    tangent is smooth there)."""
    status = st.tangential.status if st.tangential is not None else 0
    return st.active.astype(int) + 4 * np.asarray(status)


def condensed_remainders(solver, pair, rng, check):
    system = solver.system
    x = solver.x
    b = x.duplicate()
    solver.evaluate_residual(x, b)
    R0 = b.array.copy()
    check(pair.state)
    frozen = sets(pair.state)
    pair._first_jacobian = False
    solver.evaluate_jacobian(x, solver.A)
    elim = system._elim
    du, Kdu = system.Kc.createVecs()
    du.array[:] = 1e-4 * rng.standard_normal(du.array.size)
    du.array[solver.bc_dofs[solver.bc_dofs < du.array.size]] = 0.0
    du.array[elim.p_rows] = 0.0
    system.Kc.mult(du, Kdu)
    d = system.lift(du)
    # J d along d: Kc δu on the displacement rows outside P, zero on the rows P and on
    # the multipliers' rows (d keeps the linearized constraints and eliminated rows)
    n_u = system.n_u
    want = np.zeros(x.array.size)
    want[:n_u] = Kdu.array
    want[elim.p_rows] = 0.0
    hs = np.array([1.0, 1e-1, 1e-2, 1e-3])
    rem = []
    for h in hs:
        xh = x.copy()
        xh.axpy(h, d)
        solver.evaluate_residual(xh, b)
        assert np.array_equal(sets(pair.state), frozen)   # no switch of the sets
        rem.append(np.linalg.norm(b.array - R0 - h * want))
    return hs, np.array(rem), elim


def test_condensed_tangent_frictionless():
    solver, pair = condensed_system()
    rng = np.random.default_rng(21)
    multiplier_state(solver, pair, 0.013, rng)
    hs, rem, elim = condensed_remainders(
        solver, pair, rng, lambda st: st.active.sum() >= 5 or pytest.fail("few active"))
    assert len(elim.H) >= 5
    assert_second_order(hs, rem)


@pytest.mark.parametrize("state", ["stick", "slip"])
def test_condensed_tangent_with_friction(state):
    solver, pair = condensed_system(mu=0.3)
    rng = np.random.default_rng(22)
    x, b = solver.x, solver.x.duplicate()
    multiplier_state(solver, pair, 0.0005, rng, lam_t=0.01)
    solver.evaluate_residual(x, b)  # anchors the reference points here
    multiplier_state(solver, pair, 0.0005 + (1e-9 if state == "stick" else 0.013), rng,
                     lam_t=0.01)
    want = 1 if state == "stick" else 2

    def check(st):
        on = st.active
        assert on.sum() >= 5 and np.all(st.tangential.status[on] == want)

    hs, rem, elim = condensed_remainders(solver, pair, rng, check)
    n_active = int(pair.state.active.sum())
    # sticking: both multipliers of every active node are condensed through its two rows
    assert len(elim.H) == (2 * n_active if state == "stick" else n_active)
    assert_second_order(hs, rem)
