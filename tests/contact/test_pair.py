"""The assembled system (UFL bulk + contact pair hook inserted into PETSc) has a consistent
tangent: the Taylor remainder ‖R(u + hδu) − R(u) − h K δu‖ falls as h² (DESIGN.md §7),
for mortar and NTS, penalty and augmented Lagrangian, on a state with an active contact zone.
"""
import numpy as np
import pytest

from conftest import ROOT
from fenicsx_mortar import load_scene
from fenicsx_mortar.bulk import build_bulk
from fenicsx_mortar.contact.pair import build_contact
from fenicsx_mortar.meshing import build_domain
from fenicsx_mortar.solver import NewtonSolver, Timings


def system(method: str, enforcement: str):
    scene = load_scene(ROOT / "demos/scenes/patch_test.toml")
    scene.mesh.params = {"lower_nx": 8, "lower_ny": 4, "upper_nx": 10, "upper_ny": 2}
    c = scene.contacts[0]
    c.method, c.enforcement.type, c.enforcement.epsilon = method, enforcement, 1e4
    dom = build_domain(scene)
    bulk = build_bulk(scene, dom)
    timings = Timings()
    hooks, A = build_contact(scene, dom, bulk, timings)
    solver = NewtonSolver(bulk, scene.solver, hooks, timings, A)
    bulk.set_time(1.0)
    return solver, hooks[0]


@pytest.mark.parametrize("enforcement", ["penalty", "alm"])
@pytest.mark.parametrize("method", ["mortar", "nts"])
def test_taylor_remainder_is_second_order(method, enforcement):
    solver, hook = system(method, enforcement)
    X = solver.bulk.V.tabulate_dof_coordinates()[:, :2]
    rng = np.random.default_rng(7)
    # upper block shifted sideways (no slave node on a master node: no kink) and pressed
    # 2e-3 into the lower one; random perturbation 1e-5 keeps the active set fixed below
    V, dom = solver.bulk.V, solver.bulk.domain
    cells = dom.cells("upper")
    upper = np.unique(V.dofmap.list.array.reshape(-1, V.dofmap.dof_layout.num_dofs)[cells])
    state = np.zeros((len(X), 2))
    state[upper] = (0.013, -2e-3)
    state += 1e-5 * rng.standard_normal(state.shape)
    # Dirichlet dofs at their prescribed values (zero here) and not perturbed: the SNES
    # residual's lifting term is consistent with the identity rows only there
    state = state.ravel()
    state[solver.bc_dofs] = 0.0
    x = solver.x
    x.array[:] = state
    if enforcement == "alm":  # a non-zero multiplier, as after an augmentation
        hook.enforcement.multiplier[:] = rng.uniform(0.5, 1.5, hook.slave.n)
    b = x.duplicate()
    solver._residual(None, x, b)
    R0 = b.array.copy()
    active = hook.state["active"].copy()
    assert active.sum() >= 5
    hook._first_jacobian = False
    solver._jacobian(None, x, solver.A, solver.A)
    d = x.duplicate()
    d.array[:] = 1e-4 * rng.standard_normal(x.array.size)
    d.array[solver.bc_dofs] = 0.0
    Kd = x.duplicate()
    solver.A.mult(d, Kd)
    hs = np.array([1.0, 1e-1, 1e-2, 1e-3])
    rem = []
    for h in hs:
        xh = x.copy()
        xh.axpy(h, d)
        solver._residual(None, xh, b)
        assert np.array_equal(hook.state["active"], active)
        rem.append(np.linalg.norm(b.array - R0 - h * Kd.array))
    rates = np.diff(np.log(rem)) / np.diff(np.log(hs))
    print(method, enforcement, "remainders", np.array(rem), "rates", rates)
    assert np.all(rates > 1.8), (rem, rates)
