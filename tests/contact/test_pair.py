"""The assembled system (UFL bulk + contact pair hook inserted into PETSc) has a consistent
tangent: the Taylor remainder ‖R(u + hδu) − R(u) − h K δu‖ falls as h² (docs/design.md §7),
for mortar and NTS, penalty and augmented Lagrangian, on a state with an active contact zone.
"""
import numpy as np
import pytest

from conftest import ROOT
from fenicsx_mortar import _dolfinx as dx
from fenicsx_mortar import load_scene
from fenicsx_mortar.scene.bulk import build_bulk
from fenicsx_mortar.contact.registry import SMOOTHINGS
from fenicsx_mortar.scene.meshing import build_domain
from fenicsx_mortar.problem import ContactProblem
from fenicsx_mortar.scene.runner import scene_pairs


def system(method: str, enforcement: str, mu: float = 0.0, smoothing: str = "none",
           basis: str | None = None):
    scene = load_scene(ROOT / "demos/scenes/patch_test.toml")
    scene.mesh.params = {"lower_nx": 8, "lower_ny": 4, "upper_nx": 10, "upper_ny": 2}
    c = scene.contacts[0]
    c.method, c.enforcement.type, c.enforcement.epsilon = method, enforcement, 1e4
    c.smoothing, c.basis = smoothing, basis
    if mu > 0:
        c.friction.law, c.friction.mu = "coulomb", mu
    dom = build_domain(scene)
    bulk = build_bulk(scene, dom)
    pairs = scene_pairs(scene, dom, bulk.V)
    problem = ContactProblem(bulk.residual, bulk.u, bulk.bcs, pairs, bulk.jacobian,
                             settings=scene.solver)
    bulk.set_time(1.0)
    solver = problem.newton
    solver.domain = dom  # for upper_block_state
    return solver, pairs[0]


def upper_block_state(solver, shift: float, rng) -> np.ndarray:
    """Upper block moved by (shift, −2e-3) plus 1e-5 noise; Dirichlet dofs at zero."""
    V, dom = solver.u.function_space, solver.domain
    X = dx.dof_coordinates(V)
    upper = np.unique(dx.cell_dofs(V)[dom.cells("upper")])
    state = np.zeros((len(X), 2))
    state[upper] = (shift, -2e-3)
    state += 1e-5 * rng.standard_normal(state.shape)
    # Dirichlet dofs at their prescribed values (zero here) and not perturbed: the SNES
    # residual's lifting term is consistent with the identity rows only there
    state = state.ravel()
    state[solver.bc_dofs] = 0.0
    return state


def taylor_remainders(solver, hook, rng, check):
    x = solver.x
    b = x.duplicate()
    solver.evaluate_residual(x, b)
    R0 = b.array.copy()
    check(hook.state)
    frozen = {"active": hook.state.active.copy()}
    if hook.state.tangential is not None:
        frozen["status"] = hook.state.tangential.status.copy()
    hook._first_jacobian = False
    solver.evaluate_jacobian(x, solver.A)
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
        solver.evaluate_residual(xh, b)
        # no switch of the active set or stick/slip state
        assert np.array_equal(hook.state.active, frozen["active"])
        if "status" in frozen:
            assert np.array_equal(hook.state.tangential.status, frozen["status"])
        rem.append(np.linalg.norm(b.array - R0 - h * Kd.array))
    return hs, np.array(rem)


def assert_second_order(hs, rem) -> None:
    """The Taylor remainders fall as h²: observed rates above 1.8."""
    rates = np.diff(np.log(rem)) / np.diff(np.log(hs))
    assert np.all(rates > 1.8), (rem, rates)


@pytest.mark.parametrize("smoothing", SMOOTHINGS.names())
@pytest.mark.parametrize("enforcement", ["penalty", "alm"])
@pytest.mark.parametrize("method", ["mortar", "nts"])
def test_taylor_remainder_is_second_order(method, enforcement, smoothing):
    solver, hook = system(method, enforcement, smoothing=smoothing)
    rng = np.random.default_rng(7)
    # sideways shift: no slave node on a master node (no kink); pressed 2e-3 deep, the 1e-5
    # perturbations keep the active set fixed
    solver.x.array[:] = upper_block_state(solver, 0.013, rng)
    if enforcement == "alm":  # a non-zero multiplier, as after an augmentation
        hook.enforcement.multiplier[:] = rng.uniform(0.5, 1.5, hook.slave.n)
    hs, rem = taylor_remainders(solver, hook, rng,
                                lambda st: st.active.sum() >= 5 or pytest.fail("few active"))
    assert_second_order(hs, rem)


@pytest.mark.parametrize("state", ["stick", "slip"])
@pytest.mark.parametrize("method", ["mortar", "nts"])
def test_taylor_remainder_with_friction(method, state):
    """Coulomb μ = 0.3: reference points anchored in the unshifted state, then the upper
    block slid by 1e-4 (every node sticks: ε_T g_T < μ p) or by 0.013 (every node slips)."""
    solver, hook = system(method, "alm", mu=0.3)
    rng = np.random.default_rng(3)
    x, b = solver.x, solver.x.duplicate()
    x.array[:] = upper_block_state(solver, 0.0005, rng)
    solver.evaluate_residual(x, b)  # anchors the reference points here
    hook.enforcement.multiplier[:] = rng.uniform(0.5, 1.5, hook.slave.n)
    x.array[:] = upper_block_state(solver, 0.0005 + (1e-4 if state == "stick" else 0.013), rng)
    want = 1 if state == "stick" else 2

    def check(st):
        on = st.active
        assert on.sum() >= 5 and np.all(st.tangential.status[on] == want)

    hs, rem = taylor_remainders(solver, hook, rng, check)
    assert_second_order(hs, rem)


def multiplier_state(solver, pair, shift: float, rng, lam_t: float = 0.0) -> None:
    """solver.x at :func:`upper_block_state` with multipliers λ_n ∈ [0.5, 1.5] (and λ_t of
    size ``lam_t``) on every slave node."""
    solver.u.x.array[:] = upper_block_state(solver, shift, rng)
    lam = np.column_stack([rng.uniform(0.5, 1.5, pair.slave.n),
                           lam_t * rng.uniform(-1.0, 1.0, pair.slave.n)])
    pair.set_multipliers(lam)
    solver.system.pull(solver.x)


@pytest.mark.parametrize("smoothing", ["none", "averaged-tangent", "hermite", "bspline"])
@pytest.mark.parametrize("basis", ["dual", "standard"])
def test_taylor_remainder_with_multipliers(basis, smoothing):
    """Lagrange multipliers as unknowns (mortar): the system over [u, λ] — the u-rows with
    the augmented pressure ⟨λ − ε g̃/A⟩₊, the multiplier rows s (λ − p) — has its exact
    tangent, the multiplier blocks included, for both bases."""
    solver, pair = system("mortar", "lagrange", smoothing=smoothing, basis=basis)
    assert pair.discretization.basis == basis
    rng = np.random.default_rng(11)
    multiplier_state(solver, pair, 0.013, rng)
    hs, rem = taylor_remainders(solver, pair, rng,
                                lambda st: st.active.sum() >= 5 or pytest.fail("few active"))
    assert_second_order(hs, rem)


def test_taylor_remainder_with_multipliers_nts():
    solver, pair = system("nts", "lagrange")
    rng = np.random.default_rng(12)
    multiplier_state(solver, pair, 0.013, rng)
    hs, rem = taylor_remainders(solver, pair, rng,
                                lambda st: st.active.sum() >= 5 or pytest.fail("few active"))
    assert_second_order(hs, rem)


@pytest.mark.parametrize("state", ["stick", "slip"])
@pytest.mark.parametrize("method", ["mortar", "nts"])
def test_taylor_remainder_with_multipliers_and_friction(method, state):
    """Coulomb μ = 0.3 with the tangential multiplier: the trial traction λ_t + ε_T g_T
    (g_T the slip since the anchoring), stick (all nodes) with a small λ_t and a small
    slide, slip (all nodes) with a large slide; the blocks of λ_t and the λ_n → t coupling
    of slip included."""
    solver, pair = system(method, "lagrange", mu=0.3)
    rng = np.random.default_rng(5)
    x, b = solver.x, solver.x.duplicate()
    multiplier_state(solver, pair, 0.0005, rng, lam_t=0.01)
    solver.evaluate_residual(x, b)  # anchors the reference points here
    multiplier_state(solver, pair, 0.0005 + (1e-9 if state == "stick" else 0.013), rng,
                     lam_t=0.01)
    want = 1 if state == "stick" else 2

    def check(st):
        on = st.active
        assert on.sum() >= 5 and np.all(st.tangential.status[on] == want)

    hs, rem = taylor_remainders(solver, pair, rng, check)
    assert_second_order(hs, rem)


@pytest.mark.parametrize("smoothing", ["none", "hermite", "bspline"])
@pytest.mark.parametrize("enforcement", ["lagrange", "alm"])
def test_taylor_remainder_with_two_sided_smoothing(enforcement, smoothing):
    """The slave's geometry from its own Hermite curve (two-sided smoothing): the gap
    depends on the slave segment's neighbours too; the tangent stays exact."""
    solver, pair = system("mortar", enforcement, smoothing=smoothing)
    pair.discretization.slave_smoothing = "hermite"
    rng = np.random.default_rng(9)
    if enforcement == "lagrange":
        multiplier_state(solver, pair, 0.013, rng)
    else:
        solver.x.array[:] = upper_block_state(solver, 0.013, rng)
    hs, rem = taylor_remainders(solver, pair, rng,
                                lambda st: st.active.sum() >= 5 or pytest.fail("few active"))
    assert pair.state.gap.tail_nodes is not None
    assert_second_order(hs, rem)


def test_frictionless_bspline_contact_does_not_depend_on_the_load_path():
    """Frictionless hyperelastic contact has no history: the state at t = 1.3 on the B3
    half-rings with a B-spline master (stability case c03) must not depend on the steps
    taken to it. It did (|Δu| 2.4e-4 of 1.5) while the B-spline's parametrization was rebuilt from
    each step's converged nodes (the curve then moved between the nodes at each step)."""
    from fenicsx_mortar import load_scene, solve
    from conftest import ROOT

    def run(times):
        scene = load_scene(ROOT / "demos/scenes/hard/c03_half_rings_bspline.toml")
        scene.steps.times = times
        scene.output.xdmf = scene.output.plots = False
        r = solve(scene, log=lambda s: None)
        assert r.converged
        return r.u.x.array.copy(), r.pairs[0].interface()["pressure"]

    u1, p1 = run([0.5, 1.0, 1.15, 1.3])
    u2, p2 = run([0.5, 1.0, 1.3])
    assert np.max(np.abs(u1 - u2)) <= 1e-8 * np.max(np.abs(u1))
    assert np.max(np.abs(p1 - p2)) <= 1e-7 * np.max(np.abs(p1))
