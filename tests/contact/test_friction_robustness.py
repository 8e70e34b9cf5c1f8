"""Frictional contact that only friction holds along the surface (issue 31): an exactly
touching start, the step guard against a solution out of contact, and no tangential traction
left by a press where the continuum has none."""
from __future__ import annotations

import numpy as np
import pytest

from conftest import ROOT
from fenicsx_mortar import Dirichlet, Friction, load_scene, solve
from fenicsx_mortar import _dolfinx as dx


def friction_held_hertz(times=(0.1, 0.2)):
    """B2's half-disk on the block, exactly touching at (0, 0), pressed by u_y on its flat
    top; nothing but friction holds it along x (the issue's exact-touch start: its first
    iterate has the touching node at p ≈ −7e-18 with a round-off slip)."""
    scene = load_scene(ROOT / "demos/scenes/hertz.toml")
    scene.mesh.params = {"h_contact": 0.004814, "h_far": 0.1, "refine_radius": 0.08,
                         "grade_to": 0.6}
    scene.dirichlet = [d for d in scene.dirichlet if d.body != "disk"]
    scene.dirichlet.append(Dirichlet(name="press", boundary="disk_top", y=-0.0045))
    scene.tractions = []
    scene.contacts[0].friction = Friction(law="coulomb", mu=0.3)
    scene.steps.count, scene.steps.times = None, list(times)
    scene.output.xdmf = scene.output.plots = False
    return scene


def test_exact_touch_held_by_friction_converges_pressed():
    res = solve(friction_held_hertz(), log=lambda s: None)
    assert res.converged, res.message
    for rec in res.steps:
        c = rec["contact"]["hertz"]
        # the contact carries the press (the disk stayed on the block, not thrown aside)
        assert c["active_nodes"] >= 3
        fy = c["force_on_slave"][1] + c["tangential_force_on_slave"][1]
        assert fy == pytest.approx(-rec["reactions"]["press"]["y"], rel=1e-8)
    u = res.u.x.array.reshape(-1, 2)
    assert np.abs(u[:, 0]).max() < 1e-3           # no rigid sideways motion


def test_touching_node_at_zero_pressure_sticks_with_stiffness():
    """A node at p = 0 within round-off (p < 0 by 1e-17, trial traction at round-off) gets
    the stick stiffness instead of a slip without any."""
    from fenicsx_mortar.contact.friction import SLIP, STICK, Coulomb
    law = Coulomb(0.3, 1e4, 3)
    law.resolution = 1e4 * 1e-14
    trial = np.array([3e-13, -2e-13, 1e-3])
    p = np.array([-7e-18, 0.0, 0.0])
    t, status, dt_dtrial, _ = law.traction(trial, p, np.ones(3, bool))
    assert list(status) == [STICK, STICK, SLIP]
    assert list(dt_dtrial) == [1.0, 1.0, 0.0]
    assert t[2] == 0.0                              # a real slip at p = 0 carries nothing


def guard_and_pair():
    from fenicsx_mortar.acceptance import Acceptance
    from fenicsx_mortar.scene.bulk import build_bulk
    from fenicsx_mortar.scene.meshing import build_domain
    from fenicsx_mortar.scene.runner import scene_pairs
    scene = friction_held_hertz()
    dom = build_domain(scene)
    bulk = build_bulk(scene, dom)
    pairs = scene_pairs(scene, dom, bulk.V)
    guard = Acceptance(bulk.u, pairs, cell_tags=dom.cell_tags, bcs=bulk.bcs,
                       body_names={dom.cell_groups[b.group]: b.name for b in scene.bodies})
    return guard, pairs[0], bulk, dom


def test_guard_refuses_a_body_out_of_contact_along_a_free_direction():
    guard, pair, bulk, dom = guard_and_pair()
    assert guard.free[dom.cell_groups["disk"]] == {0}        # x: friction alone
    assert guard.free[dom.cell_groups["block"]] == set()
    V = bulk.V
    disk = np.unique(dx.cell_dofs(V)[dom.cells("disk")])
    u = bulk.u.x.array.reshape(-1, 2)
    u[disk] = (0.0, -1e-3)                                   # pressed: in contact
    pair.update(bulk.u)
    assert pair.state.active.sum() >= 3 and guard.unsupported() is None
    u[disk] = (9.0, -1e-3)                                   # thrown aside: out of contact
    pair.update(bulk.u)
    assert not pair.state.active.any()
    why = guard.unsupported()
    assert why is not None and "'disk'" in why and "along x" in why


@pytest.mark.parametrize("state", ["stick", "slip"])
@pytest.mark.parametrize("enforcement", ["lagrange", "alm-stick"])
def test_taylor_remainder_of_nodes_closing_in_the_step(enforcement, state):
    """Nodes out of contact at the step's start and in contact now: penalty stick in the
    step they close (no multiplier), or slip; the tangent stays exact."""
    from fenicsx_mortar.contact.friction import CLOSING, SLIP
    from test_pair import assert_second_order, system, taylor_remainders, upper_block_state
    solver, pair = system("mortar", enforcement, mu=0.3)
    rng = np.random.default_rng(21)
    x, b = solver.x, solver.x.duplicate()

    def set_u(state):
        solver.u.x.array[:] = state
        solver.system.pull(x)
    lifted = upper_block_state(solver, 0.0, rng)
    y = np.arange(1, len(lifted), 2)
    upper = y[lifted[y] < -1e-3]
    lifted[upper] += 0.014                              # the upper block 0.012 above: open
                                                        # (beyond "nearly touching", 1 % of h)
    set_u(lifted)
    solver.evaluate_residual(x, b)                        # the step's start: anchors, open set
    assert not pair.state.active.any()
    pair.enforcement.multiplier[:] = rng.uniform(0.5, 1.5, pair.slave.n)
    if enforcement == "lagrange":
        pair.enforcement.lam[:, 1] = 0.01 * rng.uniform(-1.0, 1.0, pair.slave.n)
    set_u(upper_block_state(solver, 5e-6 if state == "stick" else 0.013, rng))
    want = CLOSING if state == "stick" else SLIP

    def check(st):
        on = st.active
        assert on.sum() >= 5 and np.all(st.tangential.status[on] == want)

    hs, rem = taylor_remainders(solver, pair, rng, check)
    assert_second_order(hs, rem)
