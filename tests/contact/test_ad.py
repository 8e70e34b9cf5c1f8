"""Exactness of the second-order forward-mode jets (fenicsx_mortar.contact.ad)."""
import numpy as np
import pytest

from fenicsx_mortar.contact import ad
from fenicsx_mortar.contact.ad import Jet2


def _fd_grad(f, x, h=1e-6):
    """Central differences of a batched scalar function f(x (..., m)) -> (...)."""
    g = np.zeros(x.shape)
    for i in range(x.shape[-1]):
        e = np.zeros(x.shape[-1])
        e[i] = h
        g[..., i] = (f(x + e) - f(x - e)) / (2 * h)
    return g


def _jet_fn(expr):
    """Values of expr evaluated on plain arrays: the same code path as the jets."""
    def f(x):
        return np.asarray(expr([x[..., i] for i in range(x.shape[-1])]))
    return f


def _jet_eval(expr, x):
    return expr(Jet2.variables(x))


def _composition(v):
    # mixes every operation: +, -, *, /, unary minus, sqrt, reciprocal, square, where,
    # plain arrays and scalars on both sides
    a, b, c, d, e = v
    r = ad.sqrt(a * a + 2.0 * b * b + 1.0)
    q = (c - 0.3) / (1.5 + d * d) - 2.0 * e
    s = 1.0 / (r + e * e) + (3.0 - a) * b
    t = ad.where(ad.value(q) > 0.1, q * s, -s + c * 0.5)
    de = d * e
    return t * r - ad.reciprocal(2.0 + a * a) + (de.square() if isinstance(de, Jet2) else de * de)


@pytest.fixture
def points():
    rng = np.random.default_rng(7)
    return rng.uniform(-1.0, 1.0, size=(4, 3, 5))


def test_gradient_and_hessian_match_finite_differences(points):
    jet = _jet_eval(_composition, points)
    f = _jet_fn(_composition)
    assert np.allclose(jet.val, f(points), rtol=0, atol=1e-14)
    assert np.allclose(jet.grad, _fd_grad(f, points), rtol=0, atol=1e-8)

    def grad_i(i):
        return lambda x: _jet_eval(_composition, x).grad[..., i]
    fd_h = np.stack([_fd_grad(grad_i(i), points) for i in range(5)], axis=-2)
    assert np.allclose(jet.hess, fd_h, rtol=0, atol=1e-7)
    assert np.allclose(jet.hess, np.swapaxes(jet.hess, -1, -2), rtol=0, atol=1e-14)


def test_analytic_derivatives():
    rng = np.random.default_rng(1)
    x = rng.uniform(0.5, 2.0, size=(6, 3))
    v = Jet2.variables(x)
    x0, x1, x2 = x[:, 0], x[:, 1], x[:, 2]

    # f = x0 x1 / x2:  ∇f = (x1/x2, x0/x2, −x0x1/x2²)
    f = v[0] * v[1] / v[2]
    assert np.allclose(f.grad, np.stack([x1 / x2, x0 / x2, -x0 * x1 / x2**2], 1), atol=1e-14)
    H = np.zeros((6, 3, 3))
    H[:, 0, 1] = H[:, 1, 0] = 1 / x2
    H[:, 0, 2] = H[:, 2, 0] = -x1 / x2**2
    H[:, 1, 2] = H[:, 2, 1] = -x0 / x2**2
    H[:, 2, 2] = 2 * x0 * x1 / x2**3
    assert np.allclose(f.hess, H, rtol=1e-14, atol=1e-14)

    # r = |x|: ∇r = x/r, H = (I − x xᵀ/r²)/r
    r = ad.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
    rv = np.linalg.norm(x, axis=1)
    assert np.allclose(r.grad, x / rv[:, None], atol=1e-14)
    Hr = (np.eye(3) - x[:, :, None] * x[:, None, :] / rv[:, None, None] ** 2) / rv[:, None, None]
    assert np.allclose(r.hess, Hr, atol=1e-14)

    # 1/x0: second derivative 2/x0³;  sqrt(x0): −1/(4 x0^{3/2})
    assert np.allclose(v[0].reciprocal().hess[:, 0, 0], 2 / x0**3, atol=1e-13)
    assert np.allclose(v[0].sqrt().hess[:, 0, 0], -0.25 * x0**-1.5, atol=1e-14)
    # a linear combination has a zero Hessian
    lin = 2.0 * v[0] - v[1] + 3.0
    assert np.all(lin.hess == 0.0) and np.allclose(lin.grad, [2.0, -1.0, 0.0])


def test_sparse_supports_and_batch_ops():
    rng = np.random.default_rng(3)
    x = rng.uniform(0.5, 1.5, size=(5, 6))
    v = Jet2.variables(x)
    a = v[0] * v[4]                  # support {0, 4}
    b = v[1] * v[5] + v[4]           # support {1, 4, 5}
    c = a * b - a / b
    assert c.support.tolist() == [0, 1, 4, 5]
    dense = Jet2.variables(x)
    # same expression through dense jets (all supports full) must agree exactly
    full = [Jet2(d.val, d.grad, d.hess) for d in dense]
    a2 = full[0] * full[4]
    b2 = full[1] * full[5] + full[4]
    c2 = a2 * b2 - a2 / b2
    assert np.allclose(c.grad, c2.grad, atol=1e-15) and np.allclose(c.hess, c2.hess, atol=1e-14)

    # broadcasting a per-pair jet (K,) against a Gauss axis (n, 1) and summing it back
    s = np.array([0.25, 0.75])[:, None]
    g = (c * s + a).sum(0)
    ref = c * 1.0 + a * 2.0
    assert np.allclose(g.val, ref.val) and np.allclose(g.grad, ref.grad)
    assert np.allclose(g.hess, ref.hess, atol=1e-14)

    # indexing the batch keeps derivatives
    assert np.allclose(c[1:3].hess, c.hess[1:3])
    assert np.allclose(c[(slice(None), None)].grad[:, 0], c.grad)

    # where picks value and derivatives of the chosen branch, plain constants allowed
    cond = np.array([True, False, True, False, True])
    w = ad.where(cond, c, 2.0)
    assert np.allclose(w.val, np.where(cond, c.val, 2.0))
    assert np.allclose(w.grad[~cond], 0.0) and np.allclose(w.hess[cond], c.hess[cond])


def test_broadcasting_batches_of_different_rank():
    # a per-pair jet (K,) with a Hessian meets a (n, K) jet without one; K = n = k = 2 so
    # that a misaligned broadcast of the derivative axes could not hide behind a shape error
    rng = np.random.default_rng(5)
    x = rng.uniform(0.5, 1.5, size=(2, 2))
    s = np.array([[0.3], [0.9]])
    v = Jet2.variables(x)
    c = v[0] * v[0] * v[1] + v[1] * s            # (2,) + (2, 1) -> (2, 2)
    c2 = (v[1] * s) - v[0] * v[0] * v[1] * -1.0
    xb = np.broadcast_to(x, (2, 2, 2))
    w = Jet2.variables(xb)
    ref = w[0] * w[0] * w[1] + w[1] * s
    for got in (c, c2):
        assert got.shape == (2, 2)
        assert np.allclose(got.val, ref.val) and np.allclose(got.grad, ref.grad)
        assert np.allclose(got.hess, ref.hess)


def test_substitute_is_the_chain_rule():
    rng = np.random.default_rng(11)
    x = rng.uniform(0.5, 1.5, size=(7, 4))
    v = Jet2.variables(x)
    z0 = v[0] * v[1] + ad.sqrt(v[2])                 # inner functions of x
    z1 = v[3] / (v[0] + 1.0)

    def f(z0, z1, xs):
        return z0 * z0 * xs[2] + z1 / z0 + z1 * xs[3] * xs[0]

    direct = f(z0, z1, v)
    w = Jet2.variables(np.concatenate([z0.val[:, None], z1.val[:, None], x], axis=1))
    composed = ad.substitute(f(w[0], w[1], w[2:]), (z0, z1))
    assert np.allclose(composed.val, direct.val, atol=1e-15)
    assert np.allclose(composed.grad, direct.grad, atol=1e-14)
    assert np.allclose(composed.hess, direct.hess, atol=1e-13)


def test_sum_of_jets_with_different_supports_and_batch_ranks():
    # a Hessian-carrying jet of batch (k,) plus one of batch (n, k) with another support
    # (the projection's jets meet the Gauss batch): the Hessians must be lifted, not
    # broadcast against the support axes
    rng = np.random.default_rng(9)
    x = rng.uniform(0.5, 1.5, size=(3, 4))
    s = np.array([[0.2], [0.7]])
    v = Jet2.variables(x)
    a = v[0] * v[1]                                   # (3,), support {0, 1}
    b = v[2] * v[3] * s                               # (2, 3), support {2, 3}
    c = a + b
    w = Jet2.variables(np.broadcast_to(x, (2, 3, 4)))
    ref = w[0] * w[1] + w[2] * w[3] * s
    assert c.shape == (2, 3)
    assert np.allclose(c.grad, ref.grad) and np.allclose(c.hess, ref.hess)
    d = b - a
    assert np.allclose(d.hess, (w[2] * w[3] * s - w[0] * w[1]).hess)
