"""Cattaneo–Mindlin partial slip at the benchmark's coarsest level (h = a/10;
benchmarks/cattaneo_mindlin.py runs three levels): two cylinders of one material pressed,
then sheared by Q < μP. Against Johnson's analytic solution (contact frame): the stick
zone c/a = √(1 − Q/(μP)) and the traction q(x); exact facts: slipping nodes on the cone,
sticking ones inside it, the stick zone central, Cartesian equilibrium of the upper body;
the augmented Lagrangian reaching the multipliers' answer; no traction left by the press."""
from __future__ import annotations

import math
import sys

import numpy as np
import pytest

from conftest import ROOT

sys.path.insert(0, str(ROOT))
from benchmarks import cattaneo_mindlin as cm  # noqa: E402

MU = 0.3


def run(enforcement: str, level: int = 0, times=None, smoothing: str = "none"):
    from fenicsx_mortar import solve
    scene = cm.scene_for(level, enforcement, smoothing)
    if times is not None:
        scene.steps.times = times
    states = {}

    def on_step(rec, state):
        d = state.pairs[0].interface()
        states[round(rec["time"], 9)] = (rec, {k: np.array(v) for k, v in d.items()})
    res = solve(scene, log=lambda s: None, on_step=on_step)
    assert res.converged, res.message
    return scene, states


@pytest.fixture(scope="module")
def multipliers():
    return run("lagrange")


def shear_states(states):
    return [(t, *states[t]) for t in cm.SHEAR_TIMES]


def test_partial_slip_against_the_analytic_solution(multipliers):
    scene, states = multipliers
    k = cm.constants(scene)
    for t, rec, d in shear_states(states):
        c = rec["contact"]["cm"]
        T, N = abs(c["tangential_force"]), c["normal_force"]
        sign = np.sign(c["tangential_force"])
        x, p, q, status = d["x"], d["pressure"], sign * d["t_tangential"], d["status"]
        on = p > 0
        # the applied Q is what the contact carries along x (the upper body's equilibrium)
        fx = c["force_on_slave"][0] + c["tangential_force_on_slave"][0]
        assert -fx == pytest.approx(k["Q_max"] * cm.shear_fraction(t), rel=1e-8)
        # slipping nodes on the cone, sticking ones inside, the stick zone in the middle
        slip, stick = on & (status == "slip"), on & (status == "stick")
        assert slip.sum() >= 2 and stick.sum() >= 2
        assert np.allclose(q[slip], MU * p[slip], rtol=1e-10)
        assert np.all(np.abs(q[stick]) < MU * p[stick])
        xc = x - np.sum(x[on] * p[on]) / np.sum(p[on])
        assert np.abs(xc[stick]).max() < np.abs(xc[slip]).min()
        m = cm.metrics(x, p, q, status, N, T, MU, k["R_star"], k["E_star"])
        # coarsest mesh (a/10): c/a within 5 %, the traction within 13 % in L2 (the
        # benchmark's table: both fall under refinement)
        assert m["c_fit"] == pytest.approx(m["c_exact"], rel=0.05)
        assert m["l2"] < 0.13


def test_the_press_leaves_no_tangential_traction():
    """Mirror-symmetric bodies: the continuum press has no tangential traction. Nodes that
    close during a step were held at their open-gap anchors: after a two-step press at
    h = a/20, 0.255 μp₀ was left. What remains now is a discretization residue of the two
    non-matching meshes that neither more press steps nor the next mesh level remove: 0.03 to
    0.08 μp₀ over 2-16 press steps, a/20 and a/40, and the meshes of gmsh 4.8 and 4.13
    (docs/friction.md); bounded here by 0.1 μp₀."""
    _, states = run("lagrange", level=1, times=[0.5, 1.0])
    rec, d = states[1.0]
    a = cm.half_width(rec["contact"]["cm"]["normal_force"], 0.5, 1000 / (2 * (1 - 0.09)))
    p0 = 2 * rec["contact"]["cm"]["normal_force"] / (math.pi * a)
    assert np.abs(d["t_tangential"]).max() < 0.1 * MU * p0


@pytest.fixture(scope="module")
def augmented():
    return run("alm-stick:dual")


@pytest.mark.parametrize("basis", ["dual", "standard"])
def test_augmented_lagrangian_reaches_the_multipliers_answer(basis, multipliers, augmented):
    """The Uzawa ALM with the tangential traction augmented ('alm-stick') converges to the
    state of the multipliers with the same mortar basis (the same discrete equations),
    stick zone included (the penalty-regularized stick of 'alm' has c/a off by +13 to
    +29 %); at Q = 0.9 μP too, where the first solve after an update slid the whole zone
    away. With the standard basis (the ALM's default) both have L2(q) 1.6-2.2× the dual
    basis' at this level: the basis' discretization, not the ALM's."""
    if basis == "dual":
        (_, states), (_, ref) = augmented, multipliers
    else:
        (_, states), (_, ref) = run("alm-stick"), run("lagrange:standard")
    for t in cm.SHEAR_TIMES:
        (rec, d), (_, d_ref) = states[t], ref[t]
        p0 = d_ref["pressure"].max()
        assert np.abs(d["t_tangential"] - d_ref["t_tangential"]).max() < 1e-6 * MU * p0
        assert np.abs(d["pressure"] - d_ref["pressure"]).max() < 1e-6 * p0
        assert np.array_equal(d["status"], d_ref["status"])
        assert rec["augmentations"] >= 1


@pytest.mark.parametrize("smoothing", ["none", "bspline"])
def test_augmented_lagrangian_cost(smoothing, augmented):
    """Issue 31's target for the ALM at every level, here at a/10: ≤ 12 Newton iterations
    a step on average over the seven steps (every solve of a step: the inexact ones before
    an update and the converged last), no step cut, and the stick zone within 5 % of
    √(1 − Q/(μP)). Measured 10.6 (at most 14) with 7.7 updates a step; 26 (29) with plain
    Uzawa updates at ε ≤ 100 ε₀ and converged solves (docs/friction.md). With the B-spline
    master the first press step took 30 updates (23 iterations; mean 13.1) while the
    friction's KKT test asked of a sticking node's slip more than Newton's tolerance
    resolves at its ε_T: now 11.3 a step."""
    scene, states = augmented if smoothing == "none" else run("alm-stick:dual",
                                                                smoothing=smoothing)
    k = cm.constants(scene)
    recs = [rec for rec, _ in states.values()]
    assert len(recs) == len(scene.steps.times) and all(r["cuts"] == 0 for r in recs)
    newton = [r["newton_iterations"] for r in recs]
    assert np.mean(newton) <= 12 and max(newton) <= 16
    for t, rec, d in shear_states(states):
        c = rec["contact"]["cm"]
        sign = np.sign(c["tangential_force"])
        m = cm.metrics(d["x"], d["pressure"], sign * d["t_tangential"], d["status"],
                       c["normal_force"], abs(c["tangential_force"]), MU, k["R_star"],
                       k["E_star"])
        assert m["c_fit"] == pytest.approx(m["c_exact"], rel=0.05)


def test_mesh_generator_facts():
    """meshes/cattaneo_mindlin.py: two half-disks on their circles, touching at (0, 0) with
    a node each, contact sizes h and 1.37 h (non-matching), the cell estimate right to 2x."""
    pytest.importorskip("gmsh")
    from test_meshes import built, extract
    from fenicsx_mortar.meshes import cattaneo_mindlin as gen
    h = 0.0034
    with built("cattaneo_mindlin", h_contact=h) as model:
        mesh = extract(model)
    assert set(mesh.bodies) == {"upper", "lower"}
    assert set(mesh.facets) == {"upper_arc", "upper_top", "lower_arc", "lower_bottom"}
    cells = sum(len(tags) for tags, _ in mesh.bodies.values())
    assert 0.5 < gen.cells(h_contact=h) / cells < 2.0
    for arc, centre, body in (("upper_arc", (0, 1), "upper"), ("lower_arc", (0, -1), "lower")):
        edges = mesh.facets[arc]
        r = np.linalg.norm(mesh.x[np.unique(edges)] - centre, axis=1)
        assert np.allclose(r, 1.0, atol=1e-12)
        nodes = np.unique(mesh.bodies[body][1])
        assert np.any(np.all(np.abs(mesh.x[nodes]) < 1e-12, axis=1))   # a node at (0, 0)
        mid = 0.5 * (mesh.x[edges[:, 0]] + mesh.x[edges[:, 1]])
        near = np.abs(mid[:, 0]) < 0.03
        size = np.linalg.norm(mesh.x[edges[near, 0]] - mesh.x[edges[near, 1]], axis=1)
        expect = h if body == "upper" else 1.37 * h
        assert np.all(np.abs(size / expect - 1) < 0.1)
    with pytest.raises(ValueError, match="master_ratio"):
        gen.cells(master_ratio=10.0)
    with pytest.raises(ValueError, match="h_far"):
        gen.cells(h_contact=0.2)
