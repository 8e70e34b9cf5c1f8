"""Slave nodes at the master's edge (fenicsx_mortar.contact.boundary): the hand-over of the
weak nodes' rows moves them to supported nodes only, keeps every total, and leaves the
weighted gap of a uniform gap exact (Σ ψ = 1 on the supported part)."""
import numpy as np
import pytest

from _chains import chain, jittered
from fenicsx_mortar.contact import boundary, mortar
from fenicsx_mortar.contact.curves import Polyline
from fenicsx_mortar.contact.kernel import nodal_sum
from fenicsx_mortar.contact.search import candidate_pairs

DELTA = 0.037


def handed_over(xs_, basis):
    """Master y = 0 on x ∈ [0, 4] (+x, 9 jittered nodes), slave y = δ through the nodes
    ``xs_`` (traversed −x): (A, g̃, A_full) before and after the hand-over."""
    rng = np.random.default_rng(3)
    xm_ = jittered(0.0, 4.0, 9, rng, 0.4)
    xm, sm = chain(np.c_[xm_, np.zeros_like(xm_)])
    xs, ss = chain(np.c_[xs_, np.full_like(xs_, DELTA)])
    pairs = candidate_pairs(xs, ss, xm, sm, 0.3)
    gap, area = mortar.weighted_gaps(xs, ss, xm, sm, Polyline(xm, sm), pairs, 2, basis=basis)
    n = len(xs)
    A, A_full = nodal_sum(area, n), boundary.full_areas(xs, ss, n)
    weak = boundary.unsupported(A, A_full)
    supported = A >= boundary.SUPPORT_THRESHOLD * A_full
    nb = boundary.chain_neighbours(ss, n)
    gap2, area2 = (boundary.hand_over(c, weak, supported, nb) for c in (gap, area))
    return dict(A=A, G=nodal_sum(gap, n), A2=nodal_sum(area2, n), G2=nodal_sum(gap2, n),
                weak=weak, supported=supported, overlap=4.0 - min(xs_))


@pytest.mark.parametrize("basis", ["standard", "dual"])
def test_two_weak_nodes_side_by_side_hand_on_to_the_supported_one(basis):
    # node 2 (x = 5.9) sees the master on 0.1 of its long segment (f ≈ 0.002), node 3
    # (x = 3.9, on the long segment's inner end) just under half of its support (f ≈ 0.4)
    r = handed_over(np.array([7.9, 6.9, 5.9, 3.9, 2.9, 1.9, 0.9]), basis)
    assert list(np.flatnonzero(r["weak"])) == [2, 3]
    assert r["A"][2] == pytest.approx(0.0025, rel=1e-12)
    carry = r["A2"] > 0
    assert np.all(r["supported"][carry]) and not carry[2] and not carry[3]
    assert r["A2"].sum() == pytest.approx(r["overlap"], abs=1e-13)
    assert r["A2"][4] == pytest.approx(r["A"][2] + r["A"][3] + r["A"][4], abs=1e-13)
    # a uniform gap is still measured exactly: g̃_j = δ A_j at every node
    assert np.allclose(r["G2"], DELTA * r["A2"], rtol=0, atol=1e-14)
    assert r["G2"].sum() == pytest.approx(r["G"].sum(), abs=1e-14)


def test_one_weak_node_hands_to_its_neighbour():
    # uniform spacing, the master's end 0.05 inside the node at x = 4.05: the node beyond
    # keeps a sliver on its inner segment, its neighbour on the end is supported
    r = handed_over(np.arange(7.05, -0.5, -1.0), "dual")
    assert list(np.flatnonzero(r["weak"])) == [3]
    assert r["A2"][3] == 0.0
    assert r["A2"][4] == pytest.approx(r["A"][3] + r["A"][4], abs=1e-14)
    assert np.allclose(r["G2"], DELTA * r["A2"], rtol=0, atol=1e-14)


def test_no_supported_node_reachable_keeps_the_terms():
    # a master shorter than the slave's two segments (10 long): all three nodes see it on
    # less than half their support, no node is supported, so nothing moves
    r = handed_over(np.array([12.0, 2.0, -8.0]), "standard")
    assert r["weak"].all() and not r["supported"].any()
    assert np.array_equal(r["A2"], r["A"])
