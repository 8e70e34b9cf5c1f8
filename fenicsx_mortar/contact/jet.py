"""The :class:`Jet2` type and its arithmetic; :mod:`.ad` describes the AD and is where
the rest of the package imports it from."""
from __future__ import annotations

import contextlib

import numpy as np

from ._jet_sparse import (_FRESH, _add_block, _eg, _eh, _hessian, _intern, _lift, _outer,
                          _sum_axis, _union)

#: False inside :func:`gradients_only`: operations build no Hessians
_second_order = True


@contextlib.contextmanager
def gradients_only():
    """Within this block jets are built without Hessians (they read as zero): values and
    gradients at first-order cost, for results whose Hessians are formed later, or never."""
    global _second_order
    saved, _second_order = _second_order, False
    try:
        yield
    finally:
        _second_order = saved


def second_order() -> bool:
    """Whether jets carry Hessians here (False inside :func:`gradients_only`)."""
    return _second_order


#: the supports {i} of the independent variables
_singles: list = []


def _product(a: "Jet2", b: "Jet2") -> "Jet2":
    """a·b: ∇ = b∇a + a∇b, H = b H(a) + a H(b) + ∇a ⊗ ∇b + ∇b ⊗ ∇a, each term added on its
    own block of the union support (the outer products over the operands' supports only)."""
    u, pa, pb = _union(a.idx, b.idx)
    k = u.shape[0]
    val = a.val * b.val
    nd = val.ndim
    ga, gb = _lift(a._g, 1, nd), _lift(b._g, 1, nd)
    grad = b.val * _eg(ga, pa, k) + a.val * _eg(gb, pb, k)
    if not _second_order:
        return Jet2._raw(val, grad, None, u, a._m)
    O = _outer(ga, gb)
    if pa is None and pb is None:
        terms = [(O + np.swapaxes(O, 0, 1), None, None, _FRESH)]
    else:
        terms = [(O, pa, pb, None), (np.swapaxes(O, 0, 1), pb, pa, None)]
    if a._h is not None:
        terms.append((_lift(a._h, 2, nd), pa, pa, b.val))
    if b._h is not None:
        terms.append((_lift(b._h, 2, nd), pb, pb, a.val))
    return Jet2._raw(val, grad, _hessian(k, val.shape, terms), u, a._m)


class Jet2:
    """Value, gradient and Hessian of a batch of scalar functions of m local variables."""

    __slots__ = ("val", "_g", "_h", "idx", "_m")
    __array_ufunc__ = None  # ndarray (op) Jet2 -> Jet2.__rop__

    def __init__(self, val, grad, hess=None):
        """A jet from a dense gradient ``grad (..., m)`` and Hessian ``hess (..., m, m)``
        (None: zero). Internally built jets use :meth:`_raw`."""
        self.val = np.asarray(val, dtype=float)
        grad = np.asarray(grad, dtype=float)
        m = grad.shape[-1]
        self._m = m
        self.idx = _intern(np.arange(m))
        self._g = np.moveaxis(grad, -1, 0)
        if hess is not None:
            hess = np.moveaxis(np.asarray(hess, dtype=float), (-2, -1), (0, 1))
        self._h = hess

    @classmethod
    def _raw(cls, val, g, h, idx, m) -> "Jet2":
        """Jet from batch-last derivatives over the support idx (broadcast to val's batch)."""
        self = cls.__new__(cls)
        val = np.asarray(val, dtype=float)
        k = idx.shape[0]
        if not _second_order:
            h = None
        if g.shape[1:] != val.shape:
            g = np.broadcast_to(_lift(g, 1, val.ndim), (k,) + val.shape)
        if h is not None and h.shape[2:] != val.shape:
            h = np.broadcast_to(_lift(h, 2, val.ndim), (k, k) + val.shape)
        self.val, self._g, self._h, self.idx, self._m = val, g, h, idx, m
        return self

    # ------------------------------------------------------------------ construction
    @classmethod
    def variables(cls, values: np.ndarray) -> list:
        """m independent variables from ``values (..., m)``: jet i has gradient e_i."""
        values = np.asarray(values, dtype=float)
        m = values.shape[-1]
        one = np.broadcast_to(1.0, (1,) + values.shape[:-1])
        while len(_singles) < m:
            _singles.append(_intern([len(_singles)]))
        return [cls._raw(values[..., i], one, None, _singles[i], m) for i in range(m)]

    @classmethod
    def constant(cls, value, m: int) -> "Jet2":
        value = np.asarray(value, dtype=float)
        return cls._raw(value, np.zeros((0,) + value.shape), None, _intern([]), m)

    # ------------------------------------------------------------------ access
    @property
    def m(self) -> int:
        return self._m

    @property
    def shape(self) -> tuple:
        return self.val.shape

    @property
    def support(self) -> np.ndarray:
        """The variables this jet depends on (derivatives elsewhere are zero)."""
        return self.idx

    @property
    def grad(self) -> np.ndarray:
        """Dense gradient (..., m)."""
        if self.idx.shape[0] == self._m:  # full support (sorted): a transposed copy
            return np.ascontiguousarray(np.moveaxis(self._g, 0, -1))
        out = np.zeros(self.val.shape + (self._m,))
        if self.idx.shape[0]:
            out[..., self.idx] = np.moveaxis(self._g, 0, -1)
        return out

    @property
    def hess(self) -> np.ndarray:
        """Dense Hessian (..., m, m)."""
        if self._h is not None and self.idx.shape[0] == self._m:
            return np.ascontiguousarray(np.moveaxis(self._h, (0, 1), (-2, -1)))
        out = np.zeros(self.val.shape + (self._m, self._m))
        if self._h is not None:
            out[..., self.idx[:, None], self.idx] = np.moveaxis(self._h, (0, 1), (-2, -1))
        return out

    def __getitem__(self, key) -> "Jet2":
        """Index the batch axes (basic or advanced indexing; no Ellipsis)."""
        key = key if isinstance(key, tuple) else (key,)
        h = None
        if self._h is not None and _second_order:
            h = self._h[(slice(None), slice(None)) + key]
        return Jet2._raw(self.val[key], self._g[(slice(None),) + key], h, self.idx, self._m)

    def sum(self, axis: int) -> "Jet2":
        """Sum over one batch axis."""
        axis = axis % self.val.ndim
        h = None
        if self._h is not None and _second_order:
            h = _sum_axis(self._h, axis + 2)
        return Jet2._raw(_sum_axis(self.val, axis), _sum_axis(self._g, axis + 1), h, self.idx,
                         self._m)

    def __repr__(self) -> str:
        return f"Jet2(shape={self.shape}, m={self.m}, support={self.idx.tolist()})"

    # ------------------------------------------------------------------ arithmetic
    def __neg__(self) -> "Jet2":
        h = None if self._h is None else -self._h
        return Jet2._raw(-self.val, -self._g, h, self.idx, self._m)

    def __pos__(self) -> "Jet2":
        return self

    def _lincomb(self, o: "Jet2", sign: float) -> "Jet2":
        """self + sign·o."""
        u, pa, pb = _union(self.idx, o.idx)
        k = u.shape[0]
        val = self.val + o.val if sign > 0 else self.val - o.val
        nd = val.ndim
        ga, gb = _lift(_eg(self._g, pa, k), 1, nd), _lift(_eg(o._g, pb, k), 1, nd)
        grad = ga + gb if sign > 0 else ga - gb
        ha, hb = (self._h, o._h) if _second_order else (None, None)
        if ha is None and hb is None:
            hess = None
        elif hb is None:
            hess = _eh(ha, pa, k)
        elif ha is None:
            hess = _eh(hb, pb, k)
            hess = hess if sign > 0 else -hess
        elif pa is None and pb is None:
            ha, hb = _lift(ha, 2, nd), _lift(hb, 2, nd)
            hess = ha + hb if sign > 0 else ha - hb
        else:
            hess = _hessian(k, val.shape, [(_lift(ha, 2, nd), pa, pa, None),
                                           (_lift(hb, 2, nd), pb, pb, None if sign > 0 else -1.0)])
        return Jet2._raw(val, grad, hess, u, self._m)

    def __add__(self, o) -> "Jet2":
        if isinstance(o, Jet2):
            return self._lincomb(o, 1.0)
        val = self.val + o
        return Jet2._raw(val, self._g, self._h, self.idx, self._m)

    __radd__ = __add__

    def __sub__(self, o) -> "Jet2":
        if isinstance(o, Jet2):
            return self._lincomb(o, -1.0)
        val = self.val - o
        return Jet2._raw(val, self._g, self._h, self.idx, self._m)

    def __rsub__(self, o) -> "Jet2":
        val = o - self.val
        h = None if self._h is None else -_lift(self._h, 2, val.ndim)
        return Jet2._raw(val, -_lift(self._g, 1, val.ndim), h, self.idx, self._m)

    def __mul__(self, o) -> "Jet2":
        if isinstance(o, Jet2):
            return _product(self, o)
        val = self.val * o
        nd = val.ndim
        h = None if self._h is None else _lift(self._h, 2, nd) * o
        return Jet2._raw(val, _lift(self._g, 1, nd) * o, h, self.idx, self._m)

    __rmul__ = __mul__

    def __truediv__(self, o) -> "Jet2":
        if isinstance(o, Jet2):
            # φ(a, b) = a/b in one pass: φ_a = 1/b, φ_b = −φ/b, φ_ab = −1/b², φ_bb = 2φ/b²
            r = 1.0 / o.val
            f = self.val * r           # the value of self * o.reciprocal(), to the last bit
            fb = -f * r
            return _chain2(self, o, f, r, fb, None, -r * r, -2.0 * fb * r)
        return self * (1.0 / np.asarray(o, dtype=float))

    def __rtruediv__(self, o) -> "Jet2":
        return self.reciprocal() * o

    # ------------------------------------------------------------------ unary functions
    def _chain(self, f: np.ndarray, d1: np.ndarray, d2: np.ndarray) -> "Jet2":
        """Jet of φ(self) from φ = f, φ' = d1, φ'' = d2 evaluated at self.val."""
        g = self._g
        hess = None
        if _second_order:
            hess = _outer(d2 * g, g)
            if self._h is not None:
                hess += d1 * self._h
        return Jet2._raw(f, d1 * g, hess, self.idx, self._m)

    def square(self) -> "Jet2":
        v = self.val
        return self._chain(v * v, 2.0 * v, np.full_like(v, 2.0))

    def sqrt(self) -> "Jet2":
        r = np.sqrt(self.val)
        d1 = 0.5 / r
        return self._chain(r, d1, -0.5 * d1 / self.val)

    def reciprocal(self) -> "Jet2":
        r = 1.0 / self.val
        r2 = r * r
        return self._chain(r, -r2, 2.0 * r2 * r)


def _chain2(u: Jet2, v: Jet2, f, fu, fv, fuu, fuv, fvv) -> Jet2:
    """Jet of φ(u, v) from φ and its partial derivatives at the values of u and v
    (``fuu`` None: zero):

        ∇φ = φ_u ∇u + φ_v ∇v,
        H(φ) = φ_u H(u) + φ_v H(v) + ∇u ⊗ (φ_uu ∇u + φ_uv ∇v) + ∇v ⊗ (φ_uv ∇u + φ_vv ∇v).

    One fused step instead of the chain of products, reciprocals and roots φ is made of
    (two outer products in all)."""
    k_idx, pa, pb = _union(u.idx, v.idx)
    k = k_idx.shape[0]
    f = np.asarray(f, dtype=float)
    nd = f.ndim
    gu, gv = _lift(_eg(u._g, pa, k), 1, nd), _lift(_eg(v._g, pb, k), 1, nd)
    grad = fu * gu + fv * gv
    if not _second_order:
        return Jet2._raw(f, grad, None, k_idx, u._m)
    a = fuv * gv if fuu is None else fuu * gu + fuv * gv
    hess = _outer(gu, a)
    hess += _outer(gv, fuv * gu + fvv * gv)
    if u._h is not None:
        _add_block(hess, _lift(u._h, 2, nd), pa, pa, fu)
    if v._h is not None:
        _add_block(hess, _lift(v._h, 2, nd), pb, pb, fv)
    return Jet2._raw(f, grad, hess, k_idx, u._m)
