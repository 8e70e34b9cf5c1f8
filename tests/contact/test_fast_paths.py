"""The contact core's shortcuts give the numbers of the plain computation (issue 7): fused
jet operations, the chain rule with mixed bounds, Hessians formed on demand (weighted per
pair, in blocks), the segmentation's end frames, and the reused search."""
import numpy as np
import pytest

from fenicsx_mortar.contact import ad, mortar, search
from fenicsx_mortar.contact.ad import Jet2
from fenicsx_mortar.contact.assembly import _hessian_triplets, _test_jacobian_triplets
from fenicsx_mortar.contact.curves import make_curve

from test_mortar import closed_master, curved_open


def _composed_unit(u):
    r = ad.reciprocal(ad.sqrt(u[0] * u[0] + u[1] * u[1]))
    return u[0] * r, u[1] * r


def test_fused_operations_match_their_compositions():
    rng = np.random.default_rng(4)
    v = Jet2.variables(rng.uniform(0.5, 1.5, size=(7, 6)))
    u = (v[0] * v[1] - v[2], v[3] + v[4] * v[4])          # Hessian-carrying, mixed supports
    w = (v[5] - v[0], v[2] * v[3])
    for got, ref in ((ad.unit(u), _composed_unit(u)),
                     ((ad.norm(u),), (ad.sqrt(u[0] * u[0] + u[1] * u[1]),)),
                     ((ad.div(ad.dot(u, w), u[1]),), ((u[0] * w[0] + u[1] * w[1])
                                                     * u[1].reciprocal(),))):
        for a, b in zip(got, ref):
            assert np.allclose(a.val, b.val, rtol=1e-15, atol=0)
            assert np.allclose(a.grad, b.grad, rtol=1e-14, atol=1e-14)
            assert np.allclose(a.hess, b.hess, rtol=1e-13, atol=1e-13)
    # without Hessians: the same values and gradients
    with ad.gradients_only():
        q = ad.dot(ad.unit(u), w) * u[0]
    ref = ad.dot(ad.unit(u), w) * u[0]
    assert np.array_equal(q.val, ref.val) and np.array_equal(q.grad, ref.grad)
    assert np.all(q.hess == 0.0)


def test_substitute_with_a_mix_of_inner_jets():
    # z_0 = m00 a + m01 b, z_1 = m11 b (+ constants): 0/1 masks select per batch entry
    rng = np.random.default_rng(8)
    x = rng.uniform(0.5, 1.5, size=(9, 3))
    v = Jet2.variables(x)
    a, b = v[0] * v[1] + ad.sqrt(v[2]), v[2] / (v[0] + 1.0)
    m00, m01 = rng.integers(0, 2, 9) * 1.0, rng.integers(0, 2, 9) * 1.0
    m11 = rng.integers(0, 2, 9) * 1.0
    z0, z1 = a * m00 + b * m01 + 0.25, b * m11 + 0.5

    def f(z0, z1, xs):
        return z0 * z0 * xs[2] + z1 / (z0 + 2.0) + z1 * xs[1] * xs[0]

    direct = f(z0, z1, v)
    w = Jet2.variables(np.concatenate([z0.val[:, None], z1.val[:, None], x], axis=1))
    composed = ad.substitute(f(w[0], w[1], w[2:]), (a, b), ((m00, m01), (None, m11)))
    assert np.allclose(composed.grad, direct.grad, atol=1e-14)
    assert np.allclose(composed.hess, direct.hess, atol=1e-13)


@pytest.mark.parametrize("smoothing", ["none", "averaged-tangent", "hermite", "bspline"])
@pytest.mark.parametrize("config", [curved_open, closed_master])
def test_deferred_hessians(config, smoothing):
    """Weighted pair Hessians (what the tangent asks for) = the same sums of the full
    Hessians, in one block of pairs or many; the values, gradients and the tangent's
    Hessian part do not depend on the blocks."""
    xs, ss, xm, sm = config()
    curve = make_curve(smoothing, xm, sm)
    pairs = search.candidate_pairs(xs, ss, xm, sm, 0.3)
    ns = len(xs)
    rng = np.random.default_rng(2)
    weight = np.where(rng.uniform(size=ns) < 0.3, rng.uniform(0.5, 2.0, ns), 0.0)
    results = []
    for block in (2048, 5):
        gap, area = mortar.weighted_gaps(xs, ss, xm, sm, curve, pairs, 3, block=block)
        deferred = gap._hess if gap.test is None else gap.test._jac
        trip = _hessian_triplets if gap.test is None else _test_jacobian_triplets
        r, c, val = trip(gap, weight, ns)
        K = np.zeros((r.max() + 1, c.max() + 1))
        np.add.at(K, (r, c), val)
        full = gap.hess if gap.test is None else gap.test.jac
        w = weight[gap.node]
        h = gap.size // 2
        keep = np.flatnonzero((w[:h] != 0) | (w[h:] != 0))
        ref = full[:h][keep] * w[:h][keep, None, None] + full[h:][keep] * w[h:][keep, None, None]
        assert np.allclose(deferred.weighted(w[:h][keep], w[h:][keep], keep), ref,
                           rtol=1e-13, atol=1e-13 * np.abs(ref).max())
        results.append((gap.value, gap.grad, area.grad, area.hess, K, full))
    for a, b in zip(*results):
        assert np.allclose(a, b, rtol=1e-13, atol=1e-13 * np.abs(a).max())


def test_reused_search_equals_a_fresh_one():
    rng = np.random.default_rng(1)
    xs, ss, xm, sm = curved_open()
    radius = 0.2
    search._supersets.clear()
    for step in range(12):
        # small moves (the superset serves), now and then a large one (a new search)
        move = 0.3 if step % 5 == 4 else 0.01
        xs = xs + rng.uniform(-move, move, xs.shape)
        got = search.candidate_pairs(xs, ss, xm, sm, radius)
        cs, hs = search.segment_boxes(xs, ss)
        cm, hm = search.segment_boxes(xm, sm)
        ref = search._search(cs, hs, cm, hm, radius)
        assert np.array_equal(got[0], ref[0]) and np.array_equal(got[1], ref[1])


@pytest.mark.parametrize("smoothing", ["none", "averaged-simple", "averaged-weighted",
                                       "averaged-tangent", "hermite", "bspline"])
def test_end_frame_is_node_points_and_tangents(smoothing):
    xs, ss, xm, sm = curved_open()
    curve = make_curve(smoothing, xm, sm)
    seg = np.arange(len(sm))
    P = curve.split_points(curve.local_points(seg))
    xc, xd = curve.node_points(seg, P)
    tc, td = curve.node_tangents(seg, P)
    at_d = np.arange(len(sm)) % 3 == 1
    x, t = curve.end_frame(seg, P, at_d)
    for got, c, d in ((x, xc, xd), (t, tc, td)):
        for i in range(2):
            assert np.array_equal(got[i], np.where(at_d, d[i], c[i]))
