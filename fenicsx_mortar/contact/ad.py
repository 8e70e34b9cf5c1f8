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

:class:`Jet2` and its arithmetic are in :mod:`.jet`, the support bookkeeping in
:mod:`._jet_sparse`; this module re-exports the public names, so import from here.
"""
from __future__ import annotations

from typing import Sequence, Tuple, Union

import numpy as np

from ._jet_sparse import _FRESH, _cached, _eg, _eh, _hessian, _intern, _lift, _outer, _union
from .jet import Jet2, _chain2, second_order
from .jet import gradients_only  # noqa: F401  (re-exported)


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
    if not second_order():
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
    if not second_order():
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
