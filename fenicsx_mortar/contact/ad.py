"""Forward-mode automatic differentiation to second order, vectorized over a batch.

A :class:`Jet2` carries, for a batch of scalar functions f of the same m local variables,
the value ``val (...)``, the gradient ``grad (..., m)`` and the Hessian ``hess (..., m, m)``.
Arithmetic propagates them exactly (docs/design.md §7: consistent tangents from forward-mode
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

The cost is per-operation overhead and memory traffic, not flops (issue 7), hence: each
term of a Hessian is added only on its own block of the union support (an outer product
of two small supports stays small, :func:`_hessian`); quotients, norms and unit vectors
are single fused steps (:func:`_chain2`) instead of chains of products, roots and
reciprocals; and :func:`gradients_only` skips the Hessians where they are not needed.

Operations never write into their operands (gradients may be broadcast views).
Plain numpy arrays and scalars mix with jets as constants; ``ndarray op Jet2`` is routed to
the jet's reflected operators through ``__array_ufunc__ = None``. Batch shapes broadcast
as numpy arrays do. :func:`substitute` applies the chain rule to a jet whose first
variables are themselves jets, or 0/1 mixes of jets (used to differentiate Gauss-point
sums through the integration bounds once per pair instead of once per Gauss point).

Two-dimensional vectors are plain tuples ``(x, y)`` of jets or arrays; :func:`dot`,
:func:`cross`, :func:`perp`, :func:`norm`, … work on either.
"""
from __future__ import annotations

import contextlib
from typing import Sequence, Tuple, Union

import numpy as np

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


def _lift(d: np.ndarray, nlead: int, nd: int) -> np.ndarray:
    """Give a derivative array (nlead leading axes + batch) a batch of nd axes (numpy rule)."""
    missing = nd - (d.ndim - nlead)
    if missing <= 0:
        return d
    return d.reshape(d.shape[:nlead] + (1,) * missing + d.shape[nlead:])


#: memoized support bookkeeping: the kernels combine the same few small supports over and
#: over (the same expression graph runs for every block of pairs), so the unions, their
#: positions, the contiguous runs and the flat Hessian positions are computed once per
#: distinct support and looked up afterwards. Supports are *interned* (one read-only array
#: per distinct content), so these lookups are keyed by object identity; every cache entry
#: keeps its key arrays alive, so an id is never reused while its entry exists.
_CACHE_MAX = 8192
_interned: dict = {}
_union_cache: dict = {}
_runs_cache: dict = {}
_flat_cache: dict = {}


def _frozen(a):
    if a is not None:
        a.setflags(write=False)
    return a


def _intern(a: np.ndarray) -> np.ndarray:
    """The canonical read-only int64 array with the contents of a."""
    a = np.asarray(a, dtype=np.int64)
    key = a.tobytes()
    hit = _interned.get(key)
    if hit is None:
        if len(_interned) >= _CACHE_MAX:
            _interned.clear()
        hit = _interned[key] = _frozen(a.copy())
    return hit


def _cached(cache: dict, key, make):
    """cache[key] (key: ids of the arrays in entry[0]), made by make() on a miss."""
    hit = cache.get(key)
    if hit is None:
        if len(cache) >= _CACHE_MAX:
            cache.clear()
        hit = cache[key] = make()
    return hit[1]


def _union(ia: np.ndarray, ib: np.ndarray):
    """Union of two supports and the positions of each in it (None: identical to the union)."""
    if ia is ib:
        return ia, None, None

    def make():
        if ia.shape == ib.shape and np.array_equal(ia, ib):
            return (ia, ib), (ia, None, None)
        u = np.union1d(ia, ib)
        pa = None if u.shape == ia.shape else _frozen(np.searchsorted(u, ia))
        pb = None if u.shape == ib.shape else _frozen(np.searchsorted(u, ib))
        return (ia, ib), (_intern(u), pa, pb)

    return _cached(_union_cache, (id(ia), id(ib)), make)


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
    def make():
        brk = np.flatnonzero(np.diff(p) != 1) + 1
        starts = np.concatenate([[0], brk])
        ends = np.concatenate([brk, [p.shape[0]]])
        return p, tuple((slice(a, b), slice(p[a], p[a] + b - a))
                        for a, b in zip(starts.tolist(), ends.tolist()))

    return _cached(_runs_cache, id(p), make)


def _flat(pr: np.ndarray, pc: np.ndarray, k: int) -> np.ndarray:
    """Flat positions of the block [pr, pc] in a (k, k) array, row-major (memoized)."""
    return _cached(_flat_cache, (id(pr), id(pc), k),
                   lambda: ((pr, pc), _frozen((pr[:, None] * k + pc[None, :]).ravel())))


_ALL = ((slice(None), slice(None)),)


def _add_block(H: np.ndarray, blk: np.ndarray, pr, pc, coef=None) -> None:
    """H[pr, pc] += coef · blk for a block (kr, kc, *batch) at row positions pr and column
    positions pc of H (None: all rows / all columns)."""
    src = blk if coef is None else coef * blk
    if pr is None and pc is None:
        H += src
        return
    rr = _ALL if pr is None else _runs(pr)
    rc = _ALL if pc is None else _runs(pc)
    if len(rr) * len(rc) > 3 and H.flags.c_contiguous:
        # scattered block: one fancy-indexed update of the flattened (k·k, *batch) rows
        # instead of a Python loop over the runs (positions are distinct: no clash)
        k = H.shape[0]
        pr = _intern(np.arange(k)) if pr is None else pr
        pc = _intern(np.arange(k)) if pc is None else pc
        H2 = H.reshape((k * k,) + H.shape[2:])
        H2[_flat(pr, pc, k)] += src.reshape((pr.shape[0] * pc.shape[0],) + src.shape[2:])
        return
    for si, di in rr:
        for sj, dj in rc:
            H[di, dj] += src[si, sj]


def _eh(h, p, k: int):
    """Embed a Hessian (kp, kp, *batch) at positions p of a support of size k."""
    if h is None or p is None:
        return h
    out = np.zeros((k, k) + h.shape[2:])
    _add_block(out, h, p, p)
    return out


#: coefficient marking a Hessian term that is a fresh array of the caller's: it may become
#: the sum itself
_FRESH = "fresh"


def _hessian(k: int, shape: tuple, terms) -> np.ndarray:
    """Σ of Hessian terms over a support of size k and batch ``shape``: each term
    (block (kr, kc, *batch), row positions, column positions, coefficient or None) adds
    coef · block at [rows, columns]. A full-size term (positions None) starts the sum — a
    ``_FRESH`` one as it is, else coef · block — so no zero array is written and read
    again."""
    full = (k, k) + shape
    start = [n for n, (blk, pr, pc, coef) in enumerate(terms)
             if pr is None and pc is None
             and blk.shape[:2] + np.broadcast_shapes(blk.shape[2:], np.shape(coef)) == full]
    start.sort(key=lambda n: terms[n][3] is not _FRESH)
    if start:
        blk, _, _, coef = terms[start[0]]
        out = blk if coef is _FRESH else blk.copy() if coef is None else coef * blk
        terms = terms[:start[0]] + terms[start[0] + 1:]
    else:
        out = np.zeros(full)
    for blk, pr, pc, coef in terms:
        _add_block(out, blk, pr, pc, None if coef is _FRESH else coef)
    return out


def _sum_axis(a: np.ndarray, axis: int) -> np.ndarray:
    """a.sum(axis); over a short axis (Gauss points, nodes) as a sum of slices, which is
    faster than numpy's reduction over an inner axis."""
    n = a.shape[axis]
    if n == 0 or n > 8:
        return a.sum(axis)
    lead = (slice(None),) * axis
    out = a[lead + (0,)].copy() if n == 1 else a[lead + (0,)] + a[lead + (1,)]
    for i in range(2, n):
        out += a[lead + (i,)]
    return out


def _outer(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    return u[:, None] * v[None, :]


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


def _norm_jets(x: Jet2, y: Jet2) -> Jet2:
    """|(x, y)| in one step: ∇r = n, H(r) = (I − n nᵀ)/r over (x, y)."""
    r = np.sqrt(x.val * x.val + y.val * y.val)
    nx, ny = x.val / r, y.val / r
    return _chain2(x, y, r, nx, ny, ny * ny / r, -nx * ny / r, nx * nx / r)


def _unit_jets(x: Jet2, y: Jet2):
    """(x, y)/|(x, y)| in one step per component: with n = u/r,
    ∂n_i/∂u_j = (δ_ij − n_i n_j)/r and
    ∂²n_i/∂u_j∂u_k = −(δ_ij n_k + δ_ik n_j + δ_jk n_i − 3 n_i n_j n_k)/r²."""
    r = np.sqrt(x.val * x.val + y.val * y.val)
    ir = 1.0 / r
    nx, ny = x.val * ir, y.val * ir         # as u · (1/|u|) on plain arrays, to the last bit
    ir2 = ir * ir
    cxy = -nx * ny * ir                                     # ∂n_x/∂y = ∂n_y/∂x
    ax = -ny * (1.0 - 3.0 * nx * nx) * ir2                  # ∂²n_x/∂x∂y = ∂²n_y/∂x²
    ay = -nx * (1.0 - 3.0 * ny * ny) * ir2                  # ∂²n_x/∂y² = ∂²n_y/∂x∂y
    ux = _chain2(x, y, nx, ny * ny * ir, cxy, -3.0 * nx * ny * ny * ir2, ax, ay)
    uy = _chain2(x, y, ny, cxy, nx * nx * ir, ax, ay, -3.0 * ny * nx * nx * ir2)
    return ux, uy


Scalar = Union[Jet2, np.ndarray, float]
Vec2 = Tuple[Scalar, Scalar]


# ---------------------------------------------------------------------- generic helpers
def value(a: Scalar) -> np.ndarray:
    """The value of a jet, or the array itself."""
    return a.val if isinstance(a, Jet2) else np.asarray(a)


def div(a: Scalar, b: Scalar) -> Scalar:
    """a/b as a · (1/b) (the same value whether a, b are jets or arrays)."""
    if isinstance(b, Jet2):
        return a / b if isinstance(a, Jet2) else b.reciprocal() * a
    return a * (1.0 / np.asarray(b))


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


_shift_cache: dict = {}
#: the supports {i} of the independent variables
_singles: list = []


def substitute(f: Jet2, inner: Sequence[Jet2], mix=None) -> Jet2:
    """Chain rule: f is a jet over (z_0 … z_{r−1}, x_0 … x_{m−1}) and the z_i are functions of
    x: z_i = inner[i] (jets over x, batches broadcasting to f's), or with ``mix`` (r × r'
    nested sequence of coefficient arrays over the batch, None for zero)
    z_i = Σ_j mix[i][j] inner[j] + a constant (e.g. 0/1 masks that select, per batch entry,
    which jet a clamped bound is). Returns f(z(x), x) as a jet over x.

    With G = ∂z/∂x (r × m):  ∇F = f_x + Gᵀ f_z,
    H(F) = f_xx + Gᵀ f_zx + f_xz G + Gᵀ f_zz G + Σ_i f_{z_i} H(z_i)
         = f_xx + T + Tᵀ + Σ_i f_{z_i} H(z_i),   T = Σ_i G_i ⊗ (f_{z_i x} + ½ Σ_j f_{z_i z_j} G_j),
    all over the union of f's x-support and the inner supports (never densified to m);
    with ``mix``, Σ_i f_{z_i} H(z_i) = Σ_j (Σ_i f_{z_i} mix[i][j]) H(inner[j]).
    """
    r = len(inner) if mix is None else len(mix)
    m = f.m - r
    nd = f.val.ndim
    fi = f.idx
    nz = int(np.searchsorted(fi, r))          # supports are sorted: f's z variables first
    # f's x-support as variables of x (memoized per support)
    xs = _cached(_shift_cache, (id(fi), r), lambda: (fi, _intern(fi[nz:] - r)))
    u = xs
    for z in inner:
        u = _union(u, z.idx)[0]
    k = u.shape[0]
    shape = np.broadcast_shapes(f.val.shape, *(z.val.shape for z in inner))
    px = _union(u, xs)[2]
    pw = [_union(u, z.idx)[2] for z in inner]
    slot = {int(z): j for j, z in enumerate(fi[:nz].tolist())}   # z_i -> row in f's support
    if mix is not None:        # a z_i mixing no jet is a constant: no chain-rule terms
        slot = {i: si for i, si in slot.items() if any(c is not None for c in mix[i])}
    Gw = [_lift(_eg(z._g, p, k), 1, nd) for z, p in zip(inner, pw)]
    if mix is None:
        G = {i: Gw[i] for i in slot}
    else:
        G = {i: sum(mix[i][j] * Gw[j] for j in range(len(inner)) if mix[i][j] is not None)
             for i in slot}
    fg = _lift(f._g, 1, nd)
    grad = _eg(fg[nz:], px, k)
    for i, si in slot.items():
        grad = grad + fg[si] * G[i]
    if not _second_order:
        return Jet2._raw(f.val, grad, None, u, m)
    fh = None if f._h is None else _lift(f._h, 2, nd)
    T = None
    for i, si in (slot.items() if fh is not None else ()):
        C = _eg(fh[si, nz:], px, k)                             # f_{z_i x} + ½ Σ_j f_{z_i z_j} G_j
        for j, sj in slot.items():
            C = C + (0.5 * fh[si, sj]) * G[j]
        t = _outer(G[i], C)
        T = t if T is None else T + t
    terms = []
    if T is not None:
        terms.append((T + np.swapaxes(T, 0, 1), None, None, _FRESH))
    if fh is not None and nz < fi.shape[0]:
        terms.append((fh[nz:, nz:], px, px, None))
    for j, z in enumerate(inner):
        if z._h is None:
            continue
        if mix is None:
            coef = fg[slot[j]] if j in slot else None
        else:
            terms_j = [fg[si] * mix[i][j] for i, si in slot.items() if mix[i][j] is not None]
            coef = sum(terms_j) if terms_j else None
        if coef is not None:
            terms.append((_lift(z._h, 2, nd), pw[j], pw[j], coef))
    hess = _hessian(k, shape, terms) if terms else None
    return Jet2._raw(f.val, grad, hess, u, m)


# ---------------------------------------------------------------------- 2D vectors
def add(u: Vec2, v: Vec2) -> Vec2:
    return (u[0] + v[0], u[1] + v[1])


def sub(u: Vec2, v: Vec2) -> Vec2:
    return (u[0] - v[0], u[1] - v[1])


def scale(u: Vec2, s: Scalar) -> Vec2:
    return (u[0] * s, u[1] * s)


def _dot_jets(u: Vec2, v: Vec2) -> Jet2:
    """u·v for four jets in one pass: the Hessian Σ_i (∇u_i ⊗ ∇v_i + ∇v_i ⊗ ∇u_i
    + u_i ∇²v_i + v_i ∇²u_i), every term added on its own block of the common support (the
    same result as u[0] * v[0] + u[1] * v[1] up to round-off, in fewer array passes)."""
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
    g = [_lift(j._g, 1, nd) for j in (a0, b0, a1, b1)]
    grad = ((a0.val * _eg(g[1], pos[1], k) + b0.val * _eg(g[0], pos[0], k))
            + (a1.val * _eg(g[3], pos[3], k) + b1.val * _eg(g[2], pos[2], k)))
    if not _second_order:
        return Jet2._raw(val, grad, None, k_idx, m)
    terms = []
    for i in (0, 2):                                  # ∇a_i ⊗ ∇b_i and its transpose
        O = _outer(g[i], g[i + 1])
        terms += [(O, pos[i], pos[i + 1], None), (np.swapaxes(O, 0, 1), pos[i + 1], pos[i], None)]
    for j, p, coef in ((b0, pos[1], a0.val), (a0, pos[0], b0.val), (b1, pos[3], a1.val),
                       (a1, pos[2], b1.val)):
        if j._h is not None:
            terms.append((_lift(j._h, 2, nd), p, p, coef))
    return Jet2._raw(val, grad, _hessian(k, val.shape, terms), k_idx, m)


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


def _both_jets(u: Vec2) -> bool:
    return type(u[0]) is Jet2 and type(u[1]) is Jet2


def norm(u: Vec2) -> Scalar:
    if _both_jets(u):
        return _norm_jets(u[0], u[1])
    return sqrt(dot(u, u))


def unit(u: Vec2) -> Vec2:
    if _both_jets(u):
        return _unit_jets(u[0], u[1])
    r = reciprocal(norm(u))
    return (u[0] * r, u[1] * r)
