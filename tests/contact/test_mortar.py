"""Mortar segment-to-segment kernel (fenicsx_mortar.contact.mortar): exact derivatives
(Taylor tests), the contact patch test at kernel level, exact tiling of the segmentation,
and vectorized cost."""
import time

import numpy as np
import pytest

from _chains import assemble, chain, closed_master, curved_open, jittered, rates
from fenicsx_mortar.contact import mortar
from fenicsx_mortar.contact.curves import Polyline, make_curve
from fenicsx_mortar.contact.kernel import nodal_sum
from fenicsx_mortar.contact.registry import SMOOTHINGS
from fenicsx_mortar.contact.search import candidate_pairs


def _mortar(xs, ss, xm, sm, n_gauss=2):
    """(gap, area, D, M) on the polyline master."""
    curve = Polyline(xm, sm)
    pairs = candidate_pairs(xs, ss, xm, sm, 0.3)
    return (*mortar.weighted_gaps(xs, ss, xm, sm, curve, pairs, n_gauss),
            *mortar.mortar_matrices(xs, ss, xm, curve, pairs, n_gauss))


def taylor_check(kernel, xs, ss, xm, sm, seed=0):
    """Second-order Taylor remainders of G = Σ w_j q_j for each returned quantity q."""
    rng = np.random.default_rng(seed)
    ns, nm = len(xs), len(xm)
    X0 = np.concatenate([xs.ravel(), xm.ravel()])
    dX = rng.uniform(-1.0, 1.0, X0.shape) * 0.01
    weights = rng.uniform(0.5, 1.5, ns)

    def evaluate(X):
        out = kernel(X[:2 * ns].reshape(ns, 2), ss, X[2 * ns:].reshape(nm, 2), sm)
        return [assemble(c, ns, nm, weights) for c in out], [c.size for c in out]

    base, sizes = evaluate(X0)
    hs = 10.0 ** -np.arange(2.0, 5.5, 0.5)
    for q, (G0, g0, H0) in enumerate(base):
        r0, r1 = [], []
        for h in hs:
            (out, new_sizes) = evaluate(X0 + h * dX)
            assert new_sizes == sizes                  # no switch of pairs in the h range
            G, g, _ = out[q]
            r0.append(abs(G - G0 - h * g0 @ dX))
            r1.append(np.linalg.norm(g - g0 - h * H0 @ dX))
        r0, r1 = np.array(r0), np.array(r1)
        assert np.all((rates(hs, r0) > 1.8) & (rates(hs, r0) < 2.2)), (q, r0)
        assert np.all((rates(hs, r1) > 1.8) & (rates(hs, r1) < 2.2)), (q, r1)
    return sizes


@pytest.mark.parametrize("config", [curved_open, closed_master])
@pytest.mark.parametrize("n_gauss", [2, 3])
def test_taylor_weighted_gap_and_area(config, n_gauss):
    xs, ss, xm, sm = config()

    def kernel(xs, ss, xm, sm):
        return _mortar(xs, ss, xm, sm, n_gauss)[:2]
    sizes = taylor_check(kernel, xs, ss, xm, sm)
    assert sizes[0] > 10


def test_open_end_stencil_derivative_slots():
    # at a master chain end the stencil repeats the end node; its own slot must carry zero
    # derivative (the end node's derivative sits in the real slot)
    xs, ss, xm, sm = curved_open()
    gap, area, _, _ = _mortar(xs, ss, xm, sm)
    last = len(xm) - 1
    rows = gap.master_nodes[:, 3] == gap.master_nodes[:, 2]
    assert np.any(rows) and np.all(gap.master_nodes[rows, 2] == last)
    for c in (gap, area):
        assert np.all(c.grad[rows][:, 4 + 6:4 + 8] == 0.0)
        assert np.all(c.hess[rows][:, 4 + 6:4 + 8, :] == 0.0)



class _JetPolyline(Polyline):
    """The polyline through the general jet path (the kernel's closed form serves only the
    Polyline class itself)."""


@pytest.mark.parametrize("config", [curved_open, closed_master])
@pytest.mark.parametrize("basis", ["standard", "dual"])
def test_polyline_closed_form_equals_the_jets(config, basis):
    # the closed-form polyline kernel against the jets' Gauss rule (exact for its quadratic
    # integrand): values, gradients, full and pair-weighted Hessians, open chain ends and
    # clamped bounds included
    xs, ss, xm, sm = config()
    pairs = candidate_pairs(xs, ss, xm, sm, 0.3)
    closed = mortar.weighted_gaps(xs, ss, xm, sm, Polyline(xm, sm), pairs, 2, basis=basis)
    jets = mortar.weighted_gaps(xs, ss, xm, sm, _JetPolyline(xm, sm), pairs, 2, basis=basis)
    rng = np.random.default_rng(3)
    for a, b in zip(closed, jets):
        assert np.array_equal(a.node, b.node) and a.size > 10
        for x, y in ((a.value, b.value), (a.grad, b.grad), (a.hess, b.hess)):
            assert np.abs(x - y).max() <= 1e-13 * np.abs(y).max()
        h = a.size // 2
        wa, wb = rng.normal(size=h), rng.normal(size=h)
        some = np.flatnonzero(rng.random(h) < 0.4)
        for sel in (slice(0, h), some):
            x, y = a.pair_hessian(wa[sel], wb[sel], sel), b.pair_hessian(wa[sel], wb[sel], sel)
            assert np.abs(x - y).max() <= 1e-13 * np.abs(y).max()

# ---------------------------------------------------------------- flat patch test
def flat(delta, slave_from, slave_to, seed=2):
    """Master y = 0 on x ∈ [0, 4] (+x, 9 nodes), slave y = δ traversed −x, both spaced
    randomly (non-matching)."""
    rng = np.random.default_rng(seed)
    xm_ = jittered(0.0, 4.0, 9, rng, 0.4)
    xs_ = jittered(slave_from, slave_to, 12, rng, 0.4)
    xm, sm = chain(np.c_[xm_, np.zeros_like(xm_)])
    xs, ss = chain(np.c_[xs_, np.full_like(xs_, delta)])
    return xs, ss, xm, sm


def hat_integrals(x, seg, a, b):
    """∫_a^b N_l dx of the piecewise linear hats of a straight horizontal chain."""
    out = np.zeros(len(x))
    s, w = np.polynomial.legendre.leggauss(2)
    for c, d in seg:
        x0, x1 = sorted((x[c, 0], x[d, 0]))
        u0, u1 = max(x0, a), min(x1, b)
        if u1 <= u0:
            continue
        q = 0.5 * (u0 + u1) + 0.5 * (u1 - u0) * s
        t = (q - x[c, 0]) / (x[d, 0] - x[c, 0])
        out[c] += 0.5 * (u1 - u0) * w @ (1 - t)
        out[d] += 0.5 * (u1 - u0) * w @ t
    return out


OVERLAPS = [(3.3, 0.6), (4.5, 1.0), (4.6, -0.7)]   # inside, beyond one end, beyond both


@pytest.mark.parametrize("slave_from,slave_to", OVERLAPS)
def test_flat_gap_area_and_mortar_sums(slave_from, slave_to):
    delta = 0.037
    xs, ss, xm, sm = flat(delta, slave_from, slave_to)
    gap, area, D, M = _mortar(xs, ss, xm, sm)
    G, A = nodal_sum(gap, len(xs)), nodal_sum(area, len(xs))
    overlap = min(slave_from, 4.0) - max(slave_to, 0.0)
    assert np.allclose(G, delta * A, rtol=0, atol=1e-13)
    assert abs(A.sum() - overlap) < 1e-13
    assert abs(D.vals.sum() - overlap) < 1e-13 and abs(M.vals.sum() - overlap) < 1e-13
    # D rows sum to the nodal areas; M columns to the master hats' integrals
    assert np.allclose(np.bincount(D.rows, D.vals, len(xs)), A, atol=1e-14)
    a, b = max(slave_to, 0.0), min(slave_from, 4.0)
    assert np.allclose(np.bincount(M.cols, M.vals, len(xm)), hat_integrals(xm, sm, a, b),
                       atol=1e-14)


def _forces(gap, ns, nm, p):
    """f = Σ_j p ∇g̃_j over [slave coords, master coords], as (node, 2) arrays."""
    _, f, _ = assemble(gap, ns, nm, np.full(ns, p))
    return f[:2 * ns].reshape(ns, 2), f[2 * ns:].reshape(nm, 2)


@pytest.mark.parametrize("slave_from,slave_to", OVERLAPS)
def test_patch_test_consistent_nodal_forces(slave_from, slave_to):
    # touching interface (the converged state of the patch test): the contact forces of a
    # uniform pressure must be the consistent nodal loads on both sides
    p = 1.7
    xs, ss, xm, sm = flat(0.0, slave_from, slave_to)
    gap, _, _, _ = _mortar(xs, ss, xm, sm)
    fs, fm = _forces(gap, len(xs), len(xm), p)
    a, b = max(slave_to, 0.0), min(slave_from, 4.0)
    n_m = np.array([0.0, 1.0])                        # master normal, into the slave
    assert np.allclose(fs, p * hat_integrals(xs, ss, a, b)[:, None] * n_m, rtol=0, atol=1e-13)
    assert np.allclose(fm, -p * hat_integrals(xm, sm, a, b)[:, None] * n_m, rtol=0, atol=1e-13)
    assert np.allclose(fs.sum(0) + fm.sum(0), 0.0, atol=1e-13)
    assert abs(fs[:, 1].sum() - p * (b - a)) < 1e-13


# ---------------------------------------------------------------- segmentation tiling
def test_segmentation_tiles_slave_segments():
    rng = np.random.default_rng(4)
    xm_ = jittered(0.0, 3.0, 25, rng)
    xm, sm = chain(np.c_[xm_, 0.3 * np.sin(2.0 * xm_)])          # convex and concave
    # long slave segments, each spanning several master segments; the chain runs past
    # the master's right end (x = 3) and stops inside its span at the left
    xs_ = jittered(3.4, 0.3, 6, rng, 0.2)
    xs, ss = chain(np.c_[xs_, 0.3 * np.sin(2.0 * xs_) + 0.05])
    curve = Polyline(xm, sm)
    ps = np.repeat(np.arange(len(ss)), len(sm))
    pm = np.tile(np.arange(len(sm)), len(ss))
    lo, hi, keep = mortar.segmentation(xs, ss, curve, (ps, pm))
    # the shadow of the master's last node: its perpendicular (end tangent = own segment's)
    c, d = xm[-2], xm[-1]
    t = (d - c) / np.linalg.norm(d - c)
    pieces = []
    for s in range(len(ss)):
        mine = keep & (ps == s)
        order = np.argsort(lo[mine])
        l, h, m = lo[mine][order], hi[mine][order], pm[mine][order]
        pieces.append(len(l))
        assert np.all(np.diff(m) == -1)                             # consecutive, −x order
        assert np.allclose(l[1:], h[:-1], rtol=0, atol=1e-14)       # no gap, no overlap
        xa, xb = xs[ss[s, 0]], xs[ss[s, 1]]
        z_end = (d - xa) @ t / ((xb - xa) @ t)
        covered = 1.0 - max(z_end, 0.0)                            # part under the master
        assert abs((h - l).sum() - covered) < 1e-14
        assert abs(h[-1] - 1.0) < 1e-15
    assert min(pieces) >= 1 and max(pieces) >= 4


# ---------------------------------------------------------------- cost
def test_vectorized_cost_scales_linearly():
    def run(N):
        t = np.linspace(0.0, 1.0, N + 1)
        xs, ss = chain(np.c_[1.0 - t, 0.3 / N + 0.1 * np.sin(6.0 * (1.0 - t))])
        u = np.linspace(0.0, 1.0, int(0.77 * N) + 1)
        xm, sm = chain(np.c_[u, 0.1 * np.sin(6.0 * u)])
        best = np.inf
        for _ in range(5):  # the fastest of five: a busy neighbour once made it 10.6x
            t0 = time.perf_counter()
            curve = Polyline(xm, sm)
            pairs = candidate_pairs(xs, ss, xm, sm, 1.0 / N)
            gap, _ = mortar.weighted_gaps(xs, ss, xm, sm, curve, pairs)
            best = min(best, time.perf_counter() - t0)
        assert gap.size > N
        return best

    run(500)                                          # warm-up
    t1, t4 = run(5000), run(20000)
    print(f"\nmortar kernel: 5000 slave segments {t1:.3f} s, 20000: {t4:.3f} s")
    assert t4 / t1 < 8.0


# ---------------------------------------------------------------- smoothed master curves
def to_node_space(g, H, ns, point_map):
    """Map a gradient/Hessian over [slave coords, curve-point coords] to [slave coords,
    master node coords] with the curve's point map (B-spline: P = point_map @ X)."""
    if point_map is None:
        return g, H
    T = np.zeros((g.shape[0], 2 * (ns + point_map.shape[1])))
    T[:2 * ns, :2 * ns] = np.eye(2 * ns)
    T[2 * ns:, 2 * ns:] = np.kron(point_map.toarray(), np.eye(2))
    return T.T @ g, T.T @ H @ T


def smoothed_taylor_check(kernel_of_curve, xs, ss, xm, sm, smoothing, seed=0):
    """Taylor test over slave and master *node* coordinates; the curve (and for the
    B-spline its parametrization: parameters, knots, point map) is built once at the base
    point and frozen; only the coordinates passed to the kernel are perturbed."""
    curve = make_curve(smoothing, xm, sm)
    pmap = curve.point_map
    rng = np.random.default_rng(seed)
    ns, nm = len(xs), len(xm)
    npts = nm if pmap is None else pmap.shape[0]
    X0 = np.concatenate([xs.ravel(), xm.ravel()])
    dX = rng.uniform(-1.0, 1.0, X0.shape) * 0.01
    weights = rng.uniform(0.5, 1.5, ns)

    def evaluate(X):
        out = kernel_of_curve(curve, X[:2 * ns].reshape(ns, 2), X[2 * ns:].reshape(nm, 2))
        res = []
        for c in out:
            G, g, H = assemble(c, ns, npts, weights)
            res.append((G,) + to_node_space(g, H, ns, pmap))
        return res, [c.node.tolist() for c in out]

    base, nodes = evaluate(X0)
    hs = 10.0 ** -np.arange(2.0, 5.1, 0.5)             # three decades
    for q, (G0, g0, H0) in enumerate(base):
        r0, r1 = [], []
        for h in hs:
            out, new_nodes = evaluate(X0 + h * dX)
            assert new_nodes == nodes
            G, g, _ = out[q]
            r0.append(abs(G - G0 - h * g0 @ dX))
            r1.append(np.linalg.norm(g - g0 - h * H0 @ dX))
        for r in (np.array(r0), np.array(r1)):
            # least-squares slope over the three decades, and no pairwise rate far off
            # (the first pair may be pre-asymptotic)
            slope = np.polyfit(np.log(hs), np.log(r), 1)[0]
            assert 1.9 < slope < 2.1 and np.all(rates(hs, r) > 1.6), (q, r)
    return len(nodes[0])


@pytest.mark.parametrize("smoothing", SMOOTHINGS.names())
@pytest.mark.parametrize("config", [curved_open, closed_master])
def test_taylor_smoothed_master(config, smoothing):
    xs, ss, xm, sm = config()

    def kernel(curve, xs, xm):
        pairs = candidate_pairs(xs, ss, xm, sm, 0.3)
        return mortar.weighted_gaps(xs, ss, xm, sm, curve, pairs, 2)[:2]
    assert smoothed_taylor_check(kernel, xs, ss, xm, sm, smoothing) > 10


def test_bspline_rebuilt_parametrization_is_first_order():
    # what the frozen parametrization buys: rebuilding parameters and knots from the
    # perturbed nodes adds an O(h) change the tangent does not contain
    xs, ss, xm, sm = closed_master()
    rng = np.random.default_rng(0)
    ns, nm = len(xs), len(xm)
    dxm = rng.uniform(-1.0, 1.0, xm.shape) * 0.01
    w = rng.uniform(0.5, 1.5, ns)

    def G(xm_, curve):
        pairs = candidate_pairs(xs, ss, xm_, sm, 0.3)
        gap = mortar.weighted_gaps(xs, ss, xm_, sm, curve, pairs, 2)[0]
        return gap
    curve = make_curve("bspline", xm, sm)
    c0 = G(xm, curve)
    G0, g0, _ = assemble(c0, ns, nm, w)
    g0, _ = to_node_space(g0, np.zeros((g0.size, g0.size)), ns, curve.point_map)
    hs = np.array([1e-3, 1e-4, 1e-5])
    frozen, rebuilt = [], []
    for h in hs:
        xm_h = xm + h * dxm
        lin = G0 + h * g0[2 * ns:] @ dxm.ravel()
        frozen.append(abs(assemble(G(xm_h, curve), ns, nm, w)[0] - lin))
        rebuilt.append(abs(assemble(G(xm_h, make_curve("bspline", xm_h, sm)), ns, nm, w)[0]
                           - lin))
    assert np.all(rates(hs, np.array(frozen)) > 1.8)
    assert np.all(np.abs(rates(hs, np.array(rebuilt)) - 1.0) < 0.1)


@pytest.mark.parametrize("smoothing", SMOOTHINGS.names())
@pytest.mark.parametrize("slave_from,slave_to", OVERLAPS)
def test_flat_patch_property_with_smoothing(smoothing, slave_from, slave_to):
    # straight master: every smoothing reproduces the straight line, so g̃ = δA exactly,
    # the slave receives the consistent loads and the forces balance
    delta, p = 0.037, 1.7
    xs, ss, xm, sm = flat(delta, slave_from, slave_to)
    curve = make_curve(smoothing, xm, sm)
    pairs = candidate_pairs(xs, ss, xm, sm, 0.3)
    gap, area = mortar.weighted_gaps(xs, ss, xm, sm, curve, pairs)
    G, A = nodal_sum(gap, len(xs)), nodal_sum(area, len(xs))
    overlap = min(slave_from, 4.0) - max(slave_to, 0.0)
    assert np.allclose(G, delta * A, rtol=0, atol=1e-13)
    assert abs(A.sum() - overlap) < 1e-13

    xs, ss, xm, sm = flat(0.0, slave_from, slave_to)
    gap, _ = mortar.weighted_gaps(xs, ss, xm, sm, curve, pairs)
    ns, nm = len(xs), len(xm)
    npts = nm if curve.point_map is None else curve.point_map.shape[0]
    _, f, _ = assemble(gap, ns, npts, np.full(ns, p))
    f, _ = to_node_space(f, np.zeros((f.size, f.size)), ns, curve.point_map)
    fs, fm = f[:2 * ns].reshape(ns, 2), f[2 * ns:].reshape(nm, 2)
    a, b = max(slave_to, 0.0), min(slave_from, 4.0)
    n_m = np.array([0.0, 1.0])
    assert np.allclose(fs, p * hat_integrals(xs, ss, a, b)[:, None] * n_m, rtol=0, atol=1e-13)
    assert np.allclose(fs.sum(0) + fm.sum(0), 0.0, atol=1e-13)
    consistent = -p * hat_integrals(xm, sm, a, b)[:, None] * n_m
    deviation = np.abs(fm - consistent).max()
    if smoothing in ("hermite", "bspline"):
        # the variation of the smoothed curve, p ∫ ∂x̂/∂X_l, depends on the nodes through
        # the averaged tangents (Hermite) or globally (B-spline): not the consistent loads
        # p ∫ N̂_l of the bulk's linear boundary on a non-uniform master — which is why these
        # curves test the traction with N̂ (mortar.py) ...
        assert deviation > 1e-3
        # ... and those test vectors give exactly the consistent loads on both sides
        T = gap.test
        ft = np.zeros(2 * (ns + nm))
        np.add.at(ft, T.global_indices(ns), p * T.grad)
        fts, ftm = ft[:2 * ns].reshape(ns, 2), ft[2 * ns:].reshape(nm, 2)
        assert np.allclose(fts, fs, rtol=0, atol=1e-13)
        assert np.allclose(ftm, consistent, rtol=0, atol=1e-13)
    else:
        # averaged normals keep the polyline geometry: consistent master loads
        assert gap.test is None and deviation < 1e-13


@pytest.mark.parametrize("smoothing", ["hermite", "bspline"])
@pytest.mark.parametrize("config", [curved_open, closed_master])
def test_master_test_vectors(config, smoothing):
    """Test vectors T_j on curved masters: the slave and master forces balance (Σ N_j N_k =
    Σ N_j N̂_l pointwise), and ∂T/∂x is their exact derivative (Taylor remainder O(h²))."""
    xs, ss, xm, sm = config()
    curve = make_curve(smoothing, xm, sm)
    pmap = curve.point_map
    ns, nm = len(xs), len(xm)
    npts = nm if pmap is None else pmap.shape[0]
    rng = np.random.default_rng(3)
    w = rng.uniform(0.5, 1.5, ns)

    def force_and_jacobian(xs_, xm_):
        pairs = candidate_pairs(xs_, ss, xm_, sm, 0.3)
        gap = mortar.weighted_gaps(xs_, ss, xm_, sm, curve, pairs, 2)[0]
        T = gap.test
        rows = T.global_indices(ns)
        f = np.zeros(2 * (ns + nm))
        np.add.at(f, rows, w[gap.node][:, None] * T.grad)
        K = np.zeros((2 * (ns + nm), 2 * (ns + npts)))
        np.add.at(K, (rows[:, :, None], gap.global_indices(ns)[:, None, :]),
                  w[gap.node][:, None, None] * T.jac)
        if pmap is not None:                          # columns: curve points → master nodes
            M = np.zeros((2 * (ns + npts), 2 * (ns + nm)))
            M[:2 * ns, :2 * ns] = np.eye(2 * ns)
            M[2 * ns:, 2 * ns:] = np.kron(pmap.toarray(), np.eye(2))
            K = K @ M
        return f, K, gap.size

    f0, K0, size = force_and_jacobian(xs, xm)
    assert size > 10
    assert np.abs(f0.reshape(-1, 2).sum(0)).max() < 1e-13 * np.abs(f0).max()
    X0 = np.concatenate([xs.ravel(), xm.ravel()])
    dX = rng.uniform(-1.0, 1.0, X0.shape) * 0.01
    hs = 10.0 ** -np.arange(2.0, 5.1, 0.5)
    rem = []
    for h in hs:
        X = X0 + h * dX
        f, _, s = force_and_jacobian(X[:2 * ns].reshape(ns, 2), X[2 * ns:].reshape(nm, 2))
        assert s == size
        rem.append(np.linalg.norm(f - f0 - h * K0 @ dX))
    slope = np.polyfit(np.log(hs), np.log(rem), 1)[0]
    assert 1.9 < slope < 2.1, rem
