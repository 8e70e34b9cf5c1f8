"""The tangential force of a slave node is weighted by the load area of its pressure,
W_j = ∫ψ_j over the supported part (issue 31, item 3): with the dual basis and a slave
segment only partly over the master, ∫ψ_j ≠ A_j, and weighting friction by A_j made the
contact-frame T differ from μN with every node slipping (B3: 0.297–0.303 for μ = 0.3)."""
from __future__ import annotations

import numpy as np
import pytest

from conftest import ROOT
from fenicsx_mortar import Dirichlet, Friction, load_scene, solve
from test_pair import assert_second_order, multiplier_state, taylor_remainders, upper_block_state


def overhanging_slide(push: float):
    """Patch test with the master cut to x in [1, 3] (under the upper block), the upper
    block pressed (t ≤ 1), then pushed along x by ``push`` on its left edge (t = 1.5, 2):
    its right end slides past the master's."""
    scene = load_scene(ROOT / "demos/scenes/patch_test.toml")
    c = scene.contacts[0]
    c.master = "lower_top_middle"
    c.friction = Friction(law="coulomb", mu=0.3)
    scene.dirichlet = [d for d in scene.dirichlet if d.body != "upper"]   # the push holds x
    scene.dirichlet.append(Dirichlet(name="push", boundary="upper_left", x=push,
                                     curve="slide"))
    from fenicsx_mortar import LoadCurve
    scene.curves["slide"] = LoadCurve(t=[0.0, 1.0, 2.0], value=[0.0, 0.0, 1.0])
    scene.pressures[0].curve = "press"
    scene.pressures[0].follower = False    # a dead load: the push balances the contact
    scene.curves["press"] = LoadCurve(t=[0.0, 1.0, 2.0], value=[0.0, 1.0, 1.0])
    scene.steps.count, scene.steps.times = None, [1.0, 1.5, 2.0]
    scene.output.xdmf = scene.output.plots = False
    return scene


def test_sliding_past_the_masters_end_carries_mu_times_the_normal_force():
    # the slave's end node 0.03 past the master's (segments 0.1): 70 % of its support
    # supported, it keeps its row (below 1/2 it would hand it over, and W = A again)
    res = solve(overhanging_slide(0.03), log=lambda s: None)
    assert res.converged, res.message
    pair = res.pairs[0]
    st = pair.state
    W, A = st.tangential.load, st.A
    on = st.p > 0
    assert np.abs(W - A)[on].max() > 1e-3 * A[on].max()     # a partly supported node
    d = pair.interface()
    assert np.all(d["status"][on] == "slip")
    c = res.steps[-1]["contact"]["interface"]
    assert abs(c["tangential_force"]) == pytest.approx(0.3 * c["normal_force"], rel=1e-10)
    # the push is what the interface carries along x
    fx = c["force_on_slave"][0] + c["tangential_force_on_slave"][0]
    assert res.steps[-1]["reactions"]["push"]["x"] == pytest.approx(-fx, rel=1e-8)


def middle_master_system(enforcement: str):
    """test_pair.system's patch test (coarse, ε = 1e4, μ = 0.3, dual basis) with the
    master cut to x in [1, 3]."""
    from fenicsx_mortar.scene.bulk import build_bulk
    from fenicsx_mortar.scene.meshing import build_domain
    from fenicsx_mortar.problem import ContactProblem
    from fenicsx_mortar.scene.runner import scene_pairs
    scene = load_scene(ROOT / "demos/scenes/patch_test.toml")
    scene.mesh.params = {"lower_nx": 8, "lower_ny": 4, "upper_nx": 10, "upper_ny": 2}
    c = scene.contacts[0]
    c.master, c.enforcement.type, c.enforcement.epsilon = "lower_top_middle", enforcement, 1e4
    c.basis = "dual"
    c.friction = Friction(law="coulomb", mu=0.3)
    dom = build_domain(scene)
    bulk = build_bulk(scene, dom)
    pairs = scene_pairs(scene, dom, bulk.V)
    problem = ContactProblem(bulk.residual, bulk.u, bulk.bcs, pairs, bulk.jacobian,
                             settings=scene.solver)
    bulk.set_time(1.0)
    solver = problem.newton
    solver.domain = dom
    return solver, pairs[0]


@pytest.mark.parametrize("state", ["stick", "slip"])
@pytest.mark.parametrize("enforcement", ["lagrange", "alm", "alm-stick"])
def test_taylor_with_a_partly_supported_node(enforcement, state):
    """The tangent of W_j t_j ∇g_T,j through ∇W_j: the upper block's right end 0.03 and
    0.043 past the master's end (a segment is 0.2 long), the dual basis."""
    solver, pair = middle_master_system(enforcement)
    rng = np.random.default_rng(17)
    x, b = solver.x, solver.x.duplicate()
    if enforcement == "lagrange":
        multiplier_state(solver, pair, 0.03, rng, lam_t=0.01)
    else:
        x.array[:] = upper_block_state(solver, 0.03, rng)
        pair.enforcement.multiplier[:] = rng.uniform(0.5, 1.5, pair.slave.n)
    solver.evaluate_residual(x, b)                  # anchors the reference points here
    shift = 0.03 + (1e-9 if state == "stick" else 0.013)
    if enforcement == "lagrange":
        multiplier_state(solver, pair, shift, rng, lam_t=0.01)
    else:
        x.array[:] = upper_block_state(solver, shift, rng)
    want = 1 if state == "stick" else 2

    def check(st):
        on = st.active
        assert on.sum() >= 5 and np.all(st.tangential.status[on] == want)
        assert np.abs(st.tangential.load - st.A)[on].max() > 1e-3 * st.A.max()

    hs, rem = taylor_remainders(solver, pair, rng, check)
    assert_second_order(hs, rem)
