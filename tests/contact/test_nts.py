"""Node-to-segment baseline (fenicsx_mortar.contact.nts): exact derivatives, the meaning of
its nodal quantities, and its known failure of the contact patch test."""
import numpy as np
import pytest

from _chains import assemble, chain, closed_master, curved_open, jittered, rates
from fenicsx_mortar.contact import nts
from fenicsx_mortar.contact.curves import Polyline, make_curve
from fenicsx_mortar.contact.kernel import nodal_sum
from fenicsx_mortar.contact.registry import SMOOTHINGS
from fenicsx_mortar.contact.search import candidate_pairs
from test_mortar import smoothed_taylor_check


def flat(delta, slave_from=3.3, slave_to=0.6, seed=2):
    rng = np.random.default_rng(seed)
    xm_ = jittered(0.0, 4.0, 9, rng, 0.4)
    xs_ = jittered(slave_from, slave_to, 12, rng, 0.4)
    xm, sm = chain(np.c_[xm_, np.zeros_like(xm_)])
    xs, ss = chain(np.c_[xs_, np.full_like(xs_, delta)])
    return xs, ss, xm, sm


def _nts(xs, ss, xm, sm, radius=0.3):
    return nts.node_gaps(xs, ss, xm, sm, Polyline(xm, sm), candidate_pairs(xs, ss, xm, sm, radius))


@pytest.mark.parametrize("config", [curved_open, closed_master])
def test_taylor_weighted_gap_and_area(config):
    xs, ss, xm, sm = config()
    rng = np.random.default_rng(1)
    ns, nm = len(xs), len(xm)
    X0 = np.concatenate([xs.ravel(), xm.ravel()])
    dX = rng.uniform(-1.0, 1.0, X0.shape) * 0.01
    weights = rng.uniform(0.5, 1.5, ns)

    def evaluate(X):
        out = _nts(X[:2 * ns].reshape(ns, 2), ss, X[2 * ns:].reshape(nm, 2), sm)
        return [assemble(c, ns, nm, weights) for c in out], [c.node.tolist() for c in out]

    base, nodes = evaluate(X0)
    assert len(nodes[0]) > 5
    hs = 10.0 ** -np.arange(2.0, 5.5, 0.5)
    for q, (G0, g0, H0) in enumerate(base):
        r0, r1 = [], []
        for h in hs:
            out, new_nodes = evaluate(X0 + h * dX)
            assert new_nodes == nodes
            G, g, _ = out[q]
            r0.append(abs(G - G0 - h * g0 @ dX))
            r1.append(np.linalg.norm(g - g0 - h * H0 @ dX))
        assert np.all((rates(hs, np.array(r0)) > 1.8) & (rates(hs, np.array(r0)) < 2.2)), r0
        assert np.all((rates(hs, np.array(r1)) > 1.8) & (rates(hs, np.array(r1)) < 2.2)), r1


def test_point_gap_and_nodal_area():
    delta = 0.037
    xs, ss, xm, sm = flat(delta, slave_from=4.6, slave_to=0.6)
    gap, area = _nts(xs, ss, xm, sm)
    # nodes beyond the master's end (x > 4) get no contribution
    assert set(gap.node.tolist()) == set(np.flatnonzero(xs[:, 0] <= 4.0).tolist())
    lengths = np.linalg.norm(xs[ss[:, 1]] - xs[ss[:, 0]], axis=1)
    A_ref = np.zeros(len(xs))
    np.add.at(A_ref, ss[:, 0], 0.5 * lengths)
    np.add.at(A_ref, ss[:, 1], 0.5 * lengths)
    assert np.allclose(area.value, A_ref[area.node], rtol=0, atol=1e-15)
    assert np.allclose(gap.value / area.value, delta, rtol=0, atol=1e-15)
    assert np.allclose(nodal_sum(gap, len(xs))[gap.node], gap.value)


def test_chain_end_slots():
    # the slave's last node (x = 0.6, inside the master) has no next neighbour: its slot
    # repeats the node and must carry zero derivative
    xs, ss, xm, sm = flat(0.02)
    gap, area = _nts(xs, ss, xm, sm)
    end = len(xs) - 1
    k = np.flatnonzero(gap.node == end)[0]
    assert gap.slave_nodes[k].tolist() == [end - 1, end, end]
    for c in (gap, area):
        assert np.all(c.grad[k, 4:6] == 0.0) and np.all(c.hess[k, 4:6] == 0.0)
    # and the area derivative is that of ½|x_end − x_prev| only
    d = xs[end] - xs[end - 1]
    assert np.allclose(area.grad[k, 2:4], 0.5 * d / np.linalg.norm(d), atol=1e-15)


def test_closest_segment_on_closed_master():
    # with a radius reaching across the disk, the far side's segments are candidates too;
    # the near side (smallest |g|, ξ ∈ [0, 1]) must win: compare with brute force
    xs, ss, xm, sm = closed_master()
    gap, area = _nts(xs, ss, xm, sm, radius=2.5)
    g = gap.value / area.value
    c, d = xm[sm[:, 0]], xm[sm[:, 1]]
    a = d - c
    n = np.stack([-a[:, 1], a[:, 0]], axis=1) / np.linalg.norm(a, axis=1)[:, None]
    far = 0
    for j, gj in zip(gap.node, g):
        xi = np.einsum("ij,ij->i", xs[j] - c, a) / np.einsum("ij,ij->i", a, a)
        gaps = np.einsum("ij,ij->i", xs[j] - c, n)
        ok = (xi >= 0) & (xi <= 1)
        far += np.any(gaps[ok] < -1.5)                            # the far side qualifies too
        k = np.flatnonzero(ok)[np.argmin(np.abs(gaps[ok]))]
        if nts.BLEND <= xi[k] <= 1.0 - nts.BLEND:
            assert abs(gj - gaps[k]) < 1e-14
        else:
            # next to a master node the gap blends into the one along the node's averaged
            # normal n̄ = (n_k + n_neighbour)/|…|: it lies between the two
            end = 0 if xi[k] < 0.5 else 1
            nb = np.flatnonzero(sm[:, 1 - end] == sm[k, end])[0]
            nbar = (n[k] + n[nb]) / np.linalg.norm(n[k] + n[nb])
            g_node = (xs[j] - xm[sm[k, end]]) @ nbar
            assert min(gaps[k], g_node) - 1e-14 <= gj <= max(gaps[k], g_node) + 1e-14
        assert gj > 0.0
    assert far >= len(g) // 2


def test_nts_fails_the_patch_test():
    # touching flat interface, uniform pressure p: the master-side NTS forces are the
    # slave nodal forces p A_j interpolated at the projection points, not the consistent
    # loads p ∫ N̂_l dx (the known failure of NTS; mortar passes, see test_mortar.py)
    p = 1.7
    slave_from, slave_to = 3.3, 0.6
    xs, ss, xm, sm = flat(0.0, slave_from, slave_to)
    gap, _ = _nts(xs, ss, xm, sm)
    ns, nm = len(xs), len(xm)
    _, f, _ = assemble(gap, ns, nm, np.full(ns, p))
    fs, fm = f[:2 * ns].reshape(ns, 2), f[2 * ns:].reshape(nm, 2)
    consistent = np.zeros(nm)
    s, w = np.polynomial.legendre.leggauss(2)
    for c, d in sm:                                               # ∫ N̂_l over the overlap
        u0, u1 = max(xm[c, 0], slave_to), min(xm[d, 0], slave_from)
        if u1 > u0:
            q = 0.5 * (u0 + u1) + 0.5 * (u1 - u0) * s
            t = (q - xm[c, 0]) / (xm[d, 0] - xm[c, 0])
            consistent[c] += 0.5 * (u1 - u0) * w @ (1 - t)
            consistent[d] += 0.5 * (u1 - u0) * w @ t
    consistent *= -p
    assert np.allclose(fs.sum(0) + fm.sum(0), 0.0, atol=1e-13)     # balanced ...
    assert np.allclose(fm[:, 0], 0.0, atol=1e-15)
    deviation = np.abs(fm[:, 1] - consistent).max() / np.abs(consistent).max()
    assert deviation > 1e-3                                        # ... but not consistent


# ---------------------------------------------------------------- smoothed master curves
@pytest.mark.parametrize("smoothing", SMOOTHINGS.names())
@pytest.mark.parametrize("config", [curved_open, closed_master])
def test_taylor_smoothed_master(config, smoothing):
    xs, ss, xm, sm = config()

    def kernel(curve, xs, xm):
        return nts.node_gaps(xs, ss, xm, sm, curve, candidate_pairs(xs, ss, xm, sm, 0.3))
    assert smoothed_taylor_check(kernel, xs, ss, xm, sm, smoothing) > 5


@pytest.mark.parametrize("smoothing", SMOOTHINGS.names())
def test_flat_point_gap_with_smoothing(smoothing):
    delta = 0.037
    xs, ss, xm, sm = flat(delta, slave_from=4.6, slave_to=0.6)
    curve = make_curve(smoothing, xm, sm)
    gap, area = nts.node_gaps(xs, ss, xm, sm, curve, candidate_pairs(xs, ss, xm, sm, 0.3))
    assert set(gap.node.tolist()) == set(np.flatnonzero(xs[:, 0] <= 4.0).tolist())
    assert np.allclose(gap.value / area.value, delta, rtol=0, atol=1e-14)


@pytest.mark.parametrize("smoothing", ["hermite", "bspline", "averaged-tangent"])
def test_smooth_gap_continuous_across_master_nodes(smoothing):
    # a slave node moved across a master node: with a smoothed master the point gap is
    # continuous (no jump between the adjacent segments' gaps)
    xs, ss, xm, sm = closed_master()
    curve = make_curve(smoothing, xm, sm)
    k = 3
    nrm = xm[k] / np.linalg.norm(xm[k])
    tan = np.array([-nrm[1], nrm[0]])
    gaps = []
    for s in np.linspace(-1e-7, 1e-7, 5):
        x1 = np.array([xm[k] + 0.05 * nrm + s * tan, xm[k] + 0.05 * nrm + (s + 0.01) * tan])
        gap, area = nts.node_gaps(x1, np.array([[0, 1]]), xm, sm, curve,
                                  candidate_pairs(x1, np.array([[0, 1]]), xm, sm, 0.3))
        gaps.append((gap.value / area.value)[gap.node == 0][0])
    assert np.ptp(gaps) < 1e-8
