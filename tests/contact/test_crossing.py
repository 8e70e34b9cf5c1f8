"""Slave nodes passing through the master within one increment (contact/crossing.py)."""
from __future__ import annotations

import numpy as np
import pytest

from fenicsx_mortar.contact.crossing import initial_overlap, passed_through, signed_distance

# a master chain along y = 0 from x = 0 to 4, outward normal +y (e3 x t with t = +x)
XM = np.array([[0.0, 0.0], [1.0, 0.0], [2.0, 0.0], [3.0, 0.0], [4.0, 0.0]])
SEG = np.array([[0, 1], [1, 2], [2, 3], [3, 4]])


def test_signed_distance_is_the_height_above_the_chain():
    x = np.array([[0.5, 0.3], [2.0, -0.7], [3.2, 1e-3], [-1.0, -0.5], [5.0, 0.2]])
    d, inside = signed_distance(x, XM, SEG)
    assert np.allclose(d[:3], [0.3, -0.7, 1e-3], rtol=0.0, atol=1e-15)
    assert inside.tolist() == [True, True, True, False, False]   # past the open ends: no body


def test_signed_distance_at_a_corner_takes_the_side_of_the_corner():
    # (0, 2) down to (0, 0), then to (2, 0); outward normals e3 x t = (1, 0), then (0, 1):
    # the body is all but the quadrant x > 0, y > 0 (a re-entrant corner at the origin)
    xm = np.array([[0.0, 2.0], [0.0, 0.0], [2.0, 0.0]])
    seg = np.array([[0, 1], [1, 2]])
    d, inside = signed_distance(np.array([[0.3, 0.3], [0.3, -0.3], [-0.2, -0.3]]), xm, seg)
    assert inside.all()
    assert d[:2] == pytest.approx([0.3, -0.3])               # in the free quadrant; inside
    assert d[2] == pytest.approx(-0.5 / np.sqrt(2.0))       # the vertex: the mean normal


def test_the_closest_segment_is_found_past_nearer_nodes_of_another_side():
    """A thin closed plate (thickness 0.1): one segment on top, 40 underneath. A point 0.02
    above the top's middle is nearer to many bottom nodes than to the top's two: searching
    only the segments at the nearest nodes gave d = -0.12."""
    bottom = np.c_[np.linspace(0.0, 4.0, 41), np.zeros(41)]
    xm = np.vstack([bottom, [[4.0, 0.1], [0.0, 0.1]]])
    n = len(xm)
    seg = np.array([[i, i + 1] for i in range(n - 1)] + [[n - 1, 0]])[:, ::-1]  # clockwise
    d, inside = signed_distance(np.array([[2.0, 0.12], [2.05, 0.03]]), xm, seg)
    assert inside.all() and d == pytest.approx([0.02, -0.03])


def test_only_nodes_crossing_from_the_front_are_reported():
    r = np.full(4, 0.2)
    xs0 = np.array([[1.5, 0.1], [2.5, -1.0], [3.5, 0.1], [4.5, 0.1]])
    xs1 = np.array([[1.5, -0.5], [2.5, -1.5], [3.5, -0.1], [4.5, -0.5]])
    nodes, depth = passed_through(xs0, XM, xs1, XM, SEG, r)
    # node 0 crossed; 1 was behind already; 2 is within the search radius; 3 is past the end
    assert nodes.tolist() == [0] and depth == pytest.approx([0.5])


def test_one_step_through_a_gap_finds_the_contact_of_many_steps():
    """A block driven 0.3 down onto a block 0.05 below it: in one step Newton carried the
    slave past the master beyond the search radius and the step converged with no contact
    (the blocks 0.25 inside each other). Now the step is cut until the search sees the
    contact, and the end state is the 20-step run's: frictionless hyperelastic contact
    does not depend on the load path."""
    from fenicsx_mortar import solve
    from fenicsx_mortar.scene import Body, Contact, Dirichlet, Material, MeshSource, Scene
    from fenicsx_mortar.scene import OutputSettings, Steps

    def run(count):
        scene = Scene(
            mesh=MeshSource(generator="stacked_blocks",
                            params=dict(upper_nx=32, upper_ny=2, lower_nx=8, lower_ny=2,
                                        gap=0.05)),
            bodies=[Body(name=n, material=Material(model="neo-hooke", E=1000.0, nu=0.3))
                    for n in ("lower", "upper")],
            dirichlet=[Dirichlet(boundary="lower_bottom", x=0.0, y=0.0),
                       Dirichlet(boundary="upper_top", x=0.0, y=-0.3)],
            contacts=[Contact(name="c", slave="upper_bottom", master="lower_top")],
            steps=Steps(count=count), output=OutputSettings(xdmf=False, plots=False))
        return solve(scene.validate(), log=lambda s: None)

    one, many = run(1), run(20)
    assert one.converged and many.converged
    assert sum(s["cuts"] for s in one.steps) > 0
    force = [r.steps[-1]["contact"]["c"]["normal_force"] for r in (one, many)]
    assert force[1] > 1.0
    assert force[0] == pytest.approx(force[1], rel=1e-8)


def test_a_deep_node_the_search_still_sees_is_not_refused():
    """A soft penalty (ε = 2) lets the block sink 0.505 into the slab, more than the search
    radius 0.5, but the search (boxes inflated by the radius on both sides) still pairs
    those nodes' segments with the master: the contact acts there, the step stands."""
    import warnings

    from conftest import ROOT
    from fenicsx_mortar import load_scene, solve

    scene = load_scene(ROOT / "tests/bad_input/_base.toml")
    scene.contacts[0].enforcement.type = "penalty"
    scene.contacts[0].enforcement.epsilon = 2.0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        r = solve(scene, log=lambda s: None)
    assert r.converged, r.message
    pair = r.pairs[0]
    st = pair.state
    depth = -np.where(st.A > 0, st.g / np.where(st.A > 0, st.A, 1.0), 0.0)
    assert depth.max() > pair._node_radius.max()


def _block_bottom(depth: float, h: float = 0.25, x0: float = 1.0, width: float = 1.0):
    """A slave chain on y = −depth from x0 + width to x0 (outward normal −y: facing the
    master XM from below its front)."""
    n = int(round(width / h))
    xs = np.c_[np.linspace(x0 + width, x0, n + 1), np.full(n + 1, -depth)]
    return xs, np.c_[np.arange(n), np.arange(1, n + 1)]


@pytest.mark.parametrize("depth, reported", [(0.2, 0), (0.3, 5), (0.6, 5)])
def test_an_initial_overlap_deeper_than_the_elements_is_reported(depth, reported):
    xs, seg = _block_bottom(depth)
    nodes, d, size = initial_overlap(xs, seg, XM, SEG)
    assert nodes.size == reported
    assert np.allclose(d, depth) and np.allclose(size, 0.25)


def test_an_initial_overlap_is_not_the_far_side_of_a_thin_body():
    """A slave facing away from the master's front (a clamp's lower jaw under a plate whose
    top is the master), or past the master's open end, is not inside it."""
    xs, seg = _block_bottom(0.6)
    nodes, _, _ = initial_overlap(xs, seg[:, ::-1], XM, SEG)      # normal +y: facing away
    assert nodes.size == 0
    xs, seg = _block_bottom(0.6, x0=5.0)                           # beyond x = 4
    assert initial_overlap(xs, seg, XM, SEG)[0].size == 0
