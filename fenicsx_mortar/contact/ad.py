"""Forward-mode automatic differentiation to second order, vectorized over a batch.

A :class:`Jet2` carries, for a batch of scalar functions f of the same m local variables,
the value ``val (...)``, the gradient ``grad (..., m)`` and the Hessian ``hess (..., m, m)``.
Arithmetic propagates them exactly (DESIGN.md §7: consistent tangents from forward-mode
differentiation of the local residual):

* sum:      ∇(a+b) = ∇a + ∇b,                H(a+b) = H(a) + H(b)
* product:  ∇(ab)  = a∇b + b∇a,              H(ab)  = aH(b) + bH(a) + ∇a⊗∇b + ∇b⊗∇a
* chain:    ∇f(a)  = f'(a)∇a,                H(f(a)) = f'(a)H(a) + f''(a)∇a⊗∇a

Three economies keep the (…, m, m) work small; none is visible through ``.grad``/``.hess``:

* static sparsity: a jet stores derivatives only over its *support* ``idx`` (the sorted
  variables it depends on, the same for the whole batch; e.g. a segment tangent depends
  on 4 of 12 local coordinates); binary operations work on the union of the supports;
* the Hessian is stored lazily: ``None`` means identically zero (independent variables and
  their linear combinations);
* derivatives are stored batch-last, ``_g (k, *batch)``, ``_h (k, k, *batch)``, so every
  elementwise operation and every scatter into a larger support runs over contiguous
  batch rows.

Operations never write into their operands (gradients may be broadcast views).
Plain numpy arrays and scalars mix with jets as constants; ``ndarray op Jet2`` is routed to
the jet's reflected operators through ``__array_ufunc__ = None``. Batch shapes broadcast
as numpy arrays do. :func:`substitute` applies the chain rule to a jet whose first
variables are themselves jets (used to differentiate Gauss-point sums through the
integration bounds once per pair instead of once per Gauss point).

Two-dimensional vectors are plain tuples ``(x, y)`` of jets or arrays; :func:`dot`,
:func:`cross`, :func:`perp`, :func:`norm`, … work on either.
"""
from __future__ import annotations

from typing import Sequence, Tuple, Union

import numpy as np

_EMPTY = np.zeros(0, dtype=np.int64)


def _lift(d: np.ndarray, nlead: int, nd: int) -> np.ndarray:
    """Give a derivative array (nlead leading axes + batch) a batch of nd axes (numpy rule)."""
    missing = nd - (d.ndim - nlead)
    if missing <= 0:
        return d
    return d.reshape(d.shape[:nlead] + (1,) * missing + d.shape[nlead:])


#: memoized support bookkeeping: the kernels combine the same few small supports over and
#: over (the same expression graph runs for every block of pairs), so the unions, their
#: positions, the contiguous runs and the flat Hessian positions are computed once per
#: distinct support and looked up afterwards (cached arrays are read-only)
_CACHE_MAX = 8192
_union_cache: dict = {}
_runs_cache: dict = {}
_flat_cache: dict = {}


def _key(a: np.ndarray):
    return a.dtype.num, a.tobytes()


def _frozen(a):
    if a is not None:
        a.setflags(write=False)
    return a


def _union(ia: np.ndarray, ib: np.ndarray):
    """Union of two supports and the positions of each in it (None: identical to the union)."""
    if ia is ib:
        return ia, None, None
    key = (_key(ia), _key(ib))
    hit = _union_cache.get(key)
    if hit is None:
        if ia.shape == ib.shape and np.array_equal(ia, ib):
            hit = (None, None, None)
        else:
            u = np.union1d(ia, ib)
            pa = None if u.shape == ia.shape else np.searchsorted(u, ia)
            pb = None if u.shape == ib.shape else np.searchsorted(u, ib)
            hit = (_frozen(u), _frozen(pa), _frozen(pb))
        if len(_union_cache) >= _CACHE_MAX:
            _union_cache.clear()
        _union_cache[key] = hit
    if hit[0] is None:
        return ia, None, None
    return hit


def _eg(g: np.ndarray, p, k: int) -> np.ndarray:
    """Embed a gradient (kp, *batch) at positions p of a support of size k."""
    if p is None:
        return g
    out = np.zeros((k,) + g.shape[1:])
    out[p] = g
    return out


def _runs(p: np.ndarray):
    """Contiguous runs of the positions p as (source slice, destination slice) pairs:
    block copies over contiguous batch rows are several times faster than fancy indexing.
    Memoized per p."""
    key = _key(p)
    runs = _runs_cache.get(key)
    if runs is None:
        brk = np.flatnonzero(np.diff(p) != 1) + 1
        starts = np.concatenate([[0], brk])
        ends = np.concatenate([brk, [p.shape[0]]])
        runs = tuple((slice(a, b), slice(p[a], p[a] + b - a))
                     for a, b in zip(starts.tolist(), ends.tolist()))
        if len(_runs_cache) >= _CACHE_MAX:
            _runs_cache.clear()
        _runs_cache[key] = runs
    return runs


def _flat(p: np.ndarray, k: int) -> np.ndarray:
    """Flat positions of the block [p, p] in a (k, k) array, row-major (memoized)."""
    key = (_key(p), k)
    f = _flat_cache.get(key)
    if f is None:
        f = _frozen((p[:, None] * k + p[None, :]).ravel())
        if len(_flat_cache) >= _CACHE_MAX:
            _flat_cache.clear()
        _flat_cache[key] = f
    return f


def _eh(h, p, k: int):
    """Embed a Hessian (kp, kp, *batch) at positions p of a support of size k."""
    if h is None or p is None:
        return h
    out = np.zeros((k, k) + h.shape[2:])
    runs = _runs(p)
    for si, di in runs:
        for sj, dj in runs:
            out[di, dj] = h[si, sj]
    return out


def _place(H: np.ndarray, h: np.ndarray, p, coef=None) -> None:
    """H[p, p] += coef · h (p None: the whole block)."""
    if p is None:
        H += h if coef is None else coef * h
        return
    runs = _runs(p)
    if len(runs) > 1 and H.flags.c_contiguous:
        # scattered support: one fancy-indexed update of the flattened (k·k, *batch) rows
        # instead of a Python loop over runs² blocks (positions are distinct: no clash)
        k, kp = H.shape[0], p.shape[0]
        H2 = H.reshape((k * k,) + H.shape[2:])
        src = h.reshape((kp * kp,) + h.shape[2:])
        H2[_flat(p, k)] += src if coef is None else coef * src
        return
    for si, di in runs:
        for sj, dj in runs:
            H[di, dj] += h[si, sj] if coef is None else coef * h[si, sj]


def _outer(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    return u[:, None] * v[None, :]


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
        self.idx = np.arange(m)
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
        return [cls._raw(values[..., i], one, None, np.array([i]), m) for i in range(m)]

    @classmethod
    def constant(cls, value, m: int) -> "Jet2":
        value = np.asarray(value, dtype=float)
        return cls._raw(value, np.zeros((0,) + value.shape), None, _EMPTY, m)

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
        h = None if self._h is None else self._h[(slice(None), slice(None)) + key]
        return Jet2._raw(self.val[key], self._g[(slice(None),) + key], h, self.idx, self._m)

    def sum(self, axis: int) -> "Jet2":
        """Sum over one batch axis."""
        axis = axis % self.val.ndim
        h = None if self._h is None else self._h.sum(axis + 2)
        return Jet2._raw(self.val.sum(axis), self._g.sum(axis + 1), h, self.idx, self._m)

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
        ha, hb = self._h, o._h
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
            hess = np.zeros((k, k) + val.shape)
            _place(hess, _lift(ha, 2, nd), pa)
            _place(hess, _lift(hb, 2, nd), pb, None if sign > 0 else -1.0)
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
            u, pa, pb = _union(self.idx, o.idx)
            k = u.shape[0]
            val = self.val * o.val
            nd = val.ndim
            ga, gb = _lift(_eg(self._g, pa, k), 1, nd), _lift(_eg(o._g, pb, k), 1, nd)
            grad = self.val * gb + o.val * ga
            hess = _outer(ga, gb)
            hess = hess + np.swapaxes(hess, 0, 1)
            if o._h is not None:
                _place(hess, _lift(o._h, 2, nd), pb, self.val)
            if self._h is not None:
                _place(hess, _lift(self._h, 2, nd), pa, o.val)
            return Jet2._raw(val, grad, hess, u, self._m)
        val = self.val * o
        nd = val.ndim
        h = None if self._h is None else _lift(self._h, 2, nd) * o
        return Jet2._raw(val, _lift(self._g, 1, nd) * o, h, self.idx, self._m)

    __rmul__ = __mul__

    def __truediv__(self, o) -> "Jet2":
        if isinstance(o, Jet2):
            return self * o.reciprocal()
        return self * (1.0 / np.asarray(o, dtype=float))

    def __rtruediv__(self, o) -> "Jet2":
        return self.reciprocal() * o

    # ------------------------------------------------------------------ unary functions
    def _chain(self, f: np.ndarray, d1: np.ndarray, d2: np.ndarray) -> "Jet2":
        """Jet of φ(self) from φ = f, φ' = d1, φ'' = d2 evaluated at self.val."""
        g = self._g
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


Scalar = Union[Jet2, np.ndarray, float]
Vec2 = Tuple[Scalar, Scalar]


# ---------------------------------------------------------------------- generic helpers
def value(a: Scalar) -> np.ndarray:
    """The value of a jet, or the array itself."""
    return a.val if isinstance(a, Jet2) else np.asarray(a)


def sqrt(a: Scalar) -> Scalar:
    return a.sqrt() if isinstance(a, Jet2) else np.sqrt(a)


def reciprocal(a: Scalar) -> Scalar:
    return a.reciprocal() if isinstance(a, Jet2) else 1.0 / np.asarray(a)


def where(cond, a: Scalar, b: Scalar) -> Scalar:
    """Elementwise choice between two jets/arrays by a real boolean condition on the batch.

    The derivatives are those of the chosen branch (the condition is frozen), which is the
    exact derivative wherever the branch does not switch.
    """
    if not isinstance(a, Jet2) and not isinstance(b, Jet2):
        return np.where(cond, a, b)
    m = a.m if isinstance(a, Jet2) else b.m
    a = a if isinstance(a, Jet2) else Jet2.constant(a, m)
    b = b if isinstance(b, Jet2) else Jet2.constant(b, m)
    cond = np.asarray(cond, dtype=bool)
    # one branch everywhere: that branch itself (same values and derivatives)
    if cond.all():
        sa = a.val.shape
        if (sa == cond.shape and b.val.shape in (sa, ())) or \
                sa == np.broadcast_shapes(cond.shape, sa, b.val.shape):
            return a
    elif not cond.any():
        sb = b.val.shape
        if (sb == cond.shape and a.val.shape in (sb, ())) or \
                sb == np.broadcast_shapes(cond.shape, a.val.shape, sb):
            return b
    u, pa, pb = _union(a.idx, b.idx)
    k = u.shape[0]
    val = np.where(cond, a.val, b.val)
    nd = val.ndim
    grad = np.where(cond, _lift(_eg(a._g, pa, k), 1, nd), _lift(_eg(b._g, pb, k), 1, nd))
    if a._h is None and b._h is None:
        hess = None
    else:
        ha = 0.0 if a._h is None else _lift(_eh(a._h, pa, k), 2, nd)
        hb = 0.0 if b._h is None else _lift(_eh(b._h, pb, k), 2, nd)
        hess = np.where(cond, ha, hb)
    return Jet2._raw(val, grad, hess, u, m)


def substitute(f: Jet2, inner: Sequence[Jet2]) -> Jet2:
    """Chain rule: f is a jet over (z_0 … z_{r−1}, x_0 … x_{m−1}) and z_i = inner[i] are jets
    over x (same batch); returns f(z(x), x) as a jet over x.

    With G = ∂z/∂x (r × m):  ∇F = f_x + Gᵀ f_z,
    H(F) = f_xx + Gᵀ f_zx + f_xz G + Gᵀ f_zz G + Σ_i f_{z_i} H(z_i)
         = f_xx + T + Tᵀ + Σ_i f_{z_i} H(z_i),   T = Gᵀ (f_zx + ½ f_zz G).
    """
    r = len(inner)
    m = f.m - r
    shape = f.shape
    fg = np.zeros((f.m,) + shape)
    fg[f.idx] = f._g
    fh = np.zeros((f.m, f.m) + shape)
    if f._h is not None:
        k = f.idx.shape[0]
        fh.reshape((f.m * f.m,) + shape)[_flat(f.idx, f.m)] = \
            np.broadcast_to(f._h, (k, k) + shape).reshape((k * k,) + shape)
    G = np.zeros((r, m) + shape)
    for i, z in enumerate(inner):
        G[i][z.idx] = z._g
    # r is tiny (2 for the integration bounds): explicit sums beat broadcast reductions
    grad = fg[r:].copy()
    T = np.zeros((m, m) + shape)
    for i in range(r):
        grad += fg[i] * G[i]
        C = fh[i, r:].copy()                                  # (f_zx + ½ f_zz G)_i
        for j in range(r):
            C += 0.5 * fh[i, j] * G[j]
        T += G[i][:, None] * C[None, :]
    hess = fh[r:, r:] + T + np.swapaxes(T, 0, 1)
    for i, z in enumerate(inner):
        if z._h is not None:
            _place(hess, z._h, z.idx if z.idx.shape[0] < m else None, fg[i])
    return Jet2._raw(f.val, grad, hess, np.arange(m), m)


def stack_values(jets: Sequence[Jet2]):
    """Concatenate value (K,), dense gradient (K, m) and Hessian (K, m, m) of jets with
    equal m and one batch axis."""
    val = np.concatenate([j.val for j in jets])
    grad = np.concatenate([j.grad for j in jets])
    hess = np.concatenate([j.hess for j in jets])
    return val, grad, hess


# ---------------------------------------------------------------------- 2D vectors
def add(u: Vec2, v: Vec2) -> Vec2:
    return (u[0] + v[0], u[1] + v[1])


def sub(u: Vec2, v: Vec2) -> Vec2:
    return (u[0] - v[0], u[1] - v[1])


def scale(u: Vec2, s: Scalar) -> Vec2:
    return (u[0] * s, u[1] * s)


def _dot_jets(u: Vec2, v: Vec2) -> Jet2:
    """u·v for four jets in one pass: the Hessian Σ_i (∇u_i ⊗ ∇v_i + ∇v_i ⊗ ∇u_i
    + u_i ∇²v_i + v_i ∇²u_i) symmetrized once over the common support (the same result as
    u[0] * v[0] + u[1] * v[1] up to round-off, with about half the array passes)."""
    a0, a1 = u
    b0, b1 = v
    m = a0._m
    k_idx = a0.idx
    for j in (a1, b0, b1):
        k_idx = _union(k_idx, j.idx)[0]
    k = k_idx.shape[0]
    val = a0.val * b0.val + a1.val * b1.val
    nd = val.ndim
    pos = [_union(k_idx, j.idx)[2] for j in (a0, b0, a1, b1)]
    ga0, gb0, ga1, gb1 = (_lift(_eg(j._g, p, k), 1, nd)
                          for j, p in zip((a0, b0, a1, b1), pos))
    grad = (a0.val * gb0 + b0.val * ga0) + (a1.val * gb1 + b1.val * ga1)
    T = _outer(ga0, gb0)
    T += _outer(ga1, gb1)
    hess = T + np.swapaxes(T, 0, 1)
    for j, p, coef in ((b0, pos[1], a0.val), (a0, pos[0], b0.val), (b1, pos[3], a1.val),
                       (a1, pos[2], b1.val)):
        if j._h is not None:
            _place(hess, _lift(j._h, 2, nd), p, coef)
    return Jet2._raw(val, grad, hess, k_idx, m)


def dot(u: Vec2, v: Vec2) -> Scalar:
    if (type(u[0]) is Jet2 and type(u[1]) is Jet2 and type(v[0]) is Jet2
            and type(v[1]) is Jet2):
        s0, s1 = u[0].val.shape, v[0].val.shape
        if ((s0 == s1 == u[1].val.shape == v[1].val.shape)
                or np.broadcast_shapes(s0, s1, u[1].val.shape, v[1].val.shape)
                == np.broadcast_shapes(s0, s1)):
            return _dot_jets(u, v)
    return u[0] * v[0] + u[1] * v[1]


def cross(u: Vec2, v: Vec2) -> Scalar:
    """Scalar 2D cross product u × v = u_x v_y − u_y v_x."""
    return u[0] * v[1] - u[1] * v[0]


def perp(u: Vec2) -> Vec2:
    """e3 × u = (−u_y, u_x): the outward normal direction for the chain orientation used here."""
    return (-u[1], u[0])


def norm(u: Vec2) -> Scalar:
    return sqrt(dot(u, u))


def unit(u: Vec2) -> Vec2:
    r = reciprocal(norm(u))
    return (u[0] * r, u[1] * r)
