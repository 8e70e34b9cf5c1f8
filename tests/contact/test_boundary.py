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


def master(pieces=((0.0, 4.0),)):
    """Master y = 0 on the x intervals ``pieces`` (+x, 9 jittered nodes each, one chain
    per piece)."""
    rng = np.random.default_rng(3)
    xm, sm = [], []
    for x0, x1 in pieces:
        x, s = chain(np.c_[jittered(x0, x1, 9, rng, 0.4), np.zeros(9)])
        sm.append(s + sum(len(p) for p in xm))
        xm.append(x)
    return np.vstack(xm), np.vstack(sm)


def kernel(xs, ss, xm, sm, basis, segments=None):
    """The mortar contributions of the slave segments ``segments`` (default all)."""
    pairs = candidate_pairs(xs, ss, xm, sm, 0.3)
    if segments is not None:
        keep = segments[pairs[0]]
        pairs = (pairs[0][keep], pairs[1][keep])
    return mortar.weighted_gaps(xs, ss, xm, sm, Polyline(xm, sm), pairs, 2, basis=basis)


def decide(A, xs, ss):
    """(weak, supported, A_full, chain neighbours) of the nodal areas A."""
    A_full = boundary.full_areas(xs, ss, len(xs))
    return (*boundary.classify(A, A_full), A_full, boundary.chain_neighbours(ss, len(xs)))


def handed_over(xs_, basis, pieces=((0.0, 4.0),)):
    """Slave y = δ through the nodes ``xs_`` (traversed −x) over :func:`master`: nodal
    areas and weighted gaps before and after the hand-over."""
    xm, sm = master(pieces)
    xs, ss = chain(np.c_[xs_, np.full_like(xs_, DELTA)])
    gap, area = kernel(xs, ss, xm, sm, basis)
    n = len(xs)
    A = nodal_sum(area, n)
    weak, supported, A_full, nb = decide(A, xs, ss)
    gap2, area2 = boundary.hand_over((gap, area), A, weak, supported, nb)
    return dict(A=A, G=nodal_sum(gap, n), A2=nodal_sum(area2, n), G2=nodal_sum(gap2, n),
                weak=weak, supported=supported,
                overlap=sum(max(0.0, min(b, xs_.max()) - max(a, xs_.min())) for a, b in pieces))


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


def test_a_gap_in_the_master_is_not_crossed():
    # master in two pieces, [0, 4] and [6.5, 10]: the weak nodes at 5.9 (over the gap's
    # sliver of piece one) and 3.9 hand the rows of their shared segment to 2.9, beside
    # the better supported one, not to 6.9 over the other piece
    xs_ = np.array([8.9, 7.9, 6.9, 5.9, 3.9, 2.9, 1.9, 0.9])
    r = handed_over(xs_, "dual", pieces=((0.0, 4.0), (6.5, 10.0)))
    i59, i39, i29 = 3, 4, 5
    assert r["weak"][i59] and r["weak"][i39] and r["supported"][i29]
    assert r["A2"][i59] == 0.0 and r["A2"][i39] == 0.0
    # the part of the segment (5.9, 3.9) over piece one is [3.9, 4.0]: it belongs to 2.9's
    # side; 6.9 keeps what it sees of piece two, plus 5.9's rows on (6.9, 5.9) only
    seg_part = 0.1                                   # |[3.9, 4.0]|
    assert r["A2"][i29] - r["A"][i29] == pytest.approx(
        seg_part + 0.5, abs=1e-12)                   # + node 3.9's half of (3.9, 2.9)
    assert r["A2"].sum() == pytest.approx(r["A"].sum(), abs=1e-13)
    assert np.allclose(r["G2"], DELTA * r["A2"], rtol=0, atol=1e-14)


@pytest.mark.parametrize("split", [2, 3, 4, 5])
def test_partitioned_integration_gives_the_serial_sums(split):
    """MPI as each rank does it (pair.py, discretization.py), emulated: a rank integrates
    :func:`boundary.segments_to_integrate` of the nodes it owns, the nodal areas are the
    owners' sums, and after the hand-over each node's value is its owner's. Every split of
    the side-by-side chain must give the serial nodal areas and weighted gaps."""
    xs_ = np.array([7.9, 6.9, 5.9, 3.9, 2.9, 1.9, 0.9])
    xm, sm = master()
    xs, ss = chain(np.c_[xs_, np.full_like(xs_, DELTA)])
    n = len(xs)
    serial = handed_over(xs_, "dual")
    owners = [np.arange(n) < split, np.arange(n) >= split]
    nb = boundary.chain_neighbours(ss, n)
    parts = [kernel(xs, ss, xm, sm, "dual", boundary.segments_to_integrate(o, ss, nb))
             for o in owners]
    A = sum(np.where(o, nodal_sum(area, n), 0.0) for o, (_, area) in zip(owners, parts))
    weak, supported, _, nb = decide(A, xs, ss)
    A2 = G2 = 0.0
    for o, part in zip(owners, parts):
        gap, area = boundary.hand_over(part, A, weak, supported, nb)
        A2 = A2 + np.where(o, nodal_sum(area, n), 0)
        G2 = G2 + np.where(o, nodal_sum(gap, n), 0)
    assert np.allclose(A2, serial["A2"], rtol=0, atol=1e-14)
    assert np.allclose(G2, serial["G2"], rtol=0, atol=1e-14)
