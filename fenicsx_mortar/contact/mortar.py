"""Mortar segment-to-segment integrals: weighted gaps, nodal areas, D and M (docs/design.md §4).

For a candidate pair (slave segment s = [x_a, x_b], master segment m = [x_c, x_d]):

1. Segmentation on the slave segment, x_s(ζ) = (1−ζ) x_a + ζ x_b. The shadow of the
   master segment ends where the slave point lies on the line through a master end node
   perpendicular to the curve's nodal tangent t̄ there (:meth:`MasterCurve.node_tangents`,
   for the polyline the averaged tangent of docs/design.md eq. 3.4):
       (x_s(ζ) − x_c)·t̄_c = 0  ⇒  ζ_c = (x_c − x_a)·t̄_c / ((x_b − x_a)·t̄_c),   same for d.
   Integration domain [ζ_lo, ζ_hi] = [0, 1] ∩ [min(ζ_c, ζ_d), max(ζ_c, ζ_d)]; empty → the
   pair is dropped. Adjacent master segments share t̄ at their common node, so their
   domains tile the slave segment without gap or overlap.
   This assumes the nodal perpendiculars do not cross between master and slave (gap small
   against the master's radius of curvature), as in any contact configuration.
   Pairs whose slave and master do not face each other, (x_b − x_a)·t̄ ≥ 0 at either master
   node (outward normals less than 90° apart), are dropped too: they are no contact
   configuration (e.g. the back side of a closed master) and would divide by ~0.
2. Gauss–Legendre points ζ_g on [ζ_lo, ζ_hi]; projection ξ_g of x_s(ζ_g) onto the master
   segment's curve (:meth:`MasterCurve.project`: closed form for the polyline, the
   safeguarded Newton of :mod:`.projection` with exact jet derivatives for the smoothed
   curves — closest point, or along the smoothed normal for averaged normals); gap
   g = (x_s − x_m(ξ))·n_m(ξ) (:meth:`MasterCurve.gap`; n_m = e3 × a/|a|, or the
   interpolated averaged normal). With the smoothed curves the node tangents are the
   curve's, so a Gauss point in the shadow of a segment projects into ξ ∈ [0, 1] of it
   (up to the gap-over-radius approximation of the segmentation).
   Number of points: the scene's ``n_gauss``, by default ``curve.gauss_points`` — 2 for
   the polyline, whose integrand N_j g is quadratic (exact), 4 for the smoothed curves:
   their integrand is not polynomial, and the derivative of a Gauss sum with respect to
   the mortar segment's end is then not the integrand there, so g̃_j has a slope jump
   when a slave node passes a master node's segmentation line (7e-6 with 2 points on a
   curved arc, 1e-8 with 3, < 1e-10 with 4) — enough to stall Newton at 2 points.
3. With dΓ = |x_b − x_a| dζ (current configuration), for j ∈ {a, b}:
       g̃_j += ∫ N_j g dΓ,   A_j += ∫ N_j dΓ   over [ζ_lo, ζ_hi].
   The nodal area A_j counts only the part of the slave segment that has a master. That is
   the boundary treatment for a slave surface extending beyond the master's end: there is
   nothing to be in contact with, so g̃_j/A_j stays the average gap over the supported part
   and a node without any master support has A_j = 0 (and no contribution at all).
   A_j is integrated exactly (closed form); g̃_j with the Gauss rule.
4. Mortar matrices (values only): D_jk = ∫ N_j N_k dΓ, M_jl = ∫ N_j N̂_l(ξ) dΓ with the
   master's linear shape functions N̂ = (1−ξ, ξ) on the segment's nodes (c, d).

Master-side test functions (curves with ``hat_test``: Hermite, B-spline). The variational
force −p_j ∇g̃_j tests the traction with the variation of the *smoothed* curve, δx_m(ξ) =
Σ ∂x_m/∂P δP, whose averaged tangents reach the neighbouring nodes: on a flat master these
terms do not cancel where the contact zone ends or the segment lengths change, and the
contact patch test fails (σ_yy error 2e-2, docs/smoothing.md). The master body's own
displacement along its boundary is linear between its nodes, so these curves are used for
the geometry only (ξ, n, and g̃_j, hence p_j) and the traction is tested with the master's
linear shape functions, as in the standard mortar force f = D p n − Mᵀ p n:

    R = −Σ_j p_j T_j,   T_j = ∫ N_j (δx_s − N̂_c(ξ) δx_c − N̂_d(ξ) δx_d)·n dΓ,
    K = Σ_j T_j ⊗ ∇p_j + p_j ∂T_j/∂x     (unsymmetric; exact, by the same jets).

On a flat master the smoothed curve is the polyline with its linear parametrization, so
T_j is the polyline's and the patch test is passed exactly; the forces on slave and master
still balance (Σ N = Σ N̂ = 1). T_j and ∂T_j/∂x come from Ψ_j = T_j·v, differentiated with
v as 8 extra variables (∂T/∂x = ∂²Ψ/∂v∂x): :class:`~.kernel.MasterTest`.

All of g̃_j and A_j is computed with :class:`~.ad.Jet2` over the pair's local coordinates
[x_a, y_a, x_b, y_b, then the L stencil points of the master segment (nodes, or the
B-spline's control points)], vectorized over
pairs and Gauss points (batch (n_gauss, n_pairs), in blocks of pairs). The Gauss-point
integrand is differentiated with ζ_lo, ζ_hi as extra independent variables and their
dependence on the coordinates is applied afterwards by the chain rule (exact, cheaper).

Cost (issues 7, 31). A float pass over all candidates first finds the contributing pairs
and which end of the shadow each bound is (ζ_lo, ζ_hi are the ends ζ_c, ζ_d or clamped at
0, 1); only the ends in use get jets. The nodal integrals' values and gradients are
formed at once, with jets that carry no Hessians; the Hessians, which the tangent needs
only as Σ_j p_j ∇²g̃_j over the pairs with a node in contact, when it asks: the jets of
just those pairs are formed again with second derivatives (:class:`_Deferred`, one
weighted sum per pair; Hertz a/20: 82 of 332 pairs). On the polyline (the default) the
integrals are closed-form polynomials in five intermediates and the derivatives dense
chain rules over them (:mod:`.polyline_mortar`), equal to the jets' to round-off. The
segmentation and its float pass: :mod:`.segmentation`.
"""
from __future__ import annotations

from typing import NamedTuple, Tuple

import numpy as np

from . import ad
from .ad import Jet2
from .curves import MasterCurve, Polyline
from .kernel import MasterTest, NodalContributions, Triplets
from .polyline_mortar import PolylineDeferred, PolylineGeometry
from .segmentation import Bounds, Ends, columns, gauss_legendre_01, layout, prepass
from .segmentation import segmentation  # noqa: F401  (the module's API: tests, benchmarks)


class _Integrand(NamedTuple):
    """What the Gauss-point stage of a block of pairs leaves for the nodal integrals
    ∫ N_j f dΓ = J Σ_g w_g N_j(ζ_g) f(ζ_g): the integrand f (jet over [ζ_lo, ζ_hi, local
    coordinates], batch (n_gauss, K)), the length element J (batch (K,)), ζ_g, the Gauss
    weights (n_gauss, 1) and the bounds (their dependence on the coordinates)."""

    f: Jet2
    J: Jet2
    zeta: Jet2
    w: np.ndarray
    bounds: Bounds


#: N_a = 1 − ζ, N_b = ζ as ζ·(−1, 1) + (1, 0) over a leading node axis
_SIGN = np.array([-1.0, 1.0]).reshape(2, 1, 1)
_ONE_ZERO = np.array([1.0, 0.0]).reshape(2, 1, 1)


def _nodal(q: _Integrand, pairs=None, weights=None) -> Jet2:
    """∫ N_j f dΓ as a jet over the local coordinates (the bounds substituted): for nodes a
    and b stacked, batch (2, K); or, with ``weights`` = (w_a, w_b) for the block's
    ``pairs`` (index array or slice), the one combination w_a ∫ N_a f dΓ + w_b ∫ N_b f dΓ
    per pair (what the tangent needs, :meth:`.kernel.NodalContributions.pair_hessian`)."""
    f, J, zeta = q.f, q.J, q.zeta
    if pairs is not None:
        f, J, zeta = f[:, pairs], J[pairs], zeta[:, pairs]
    inner, mix = q.bounds.inner(pairs)
    if weights is None:
        return ad.substitute(J * (f * ((zeta * _SIGN + _ONE_ZERO) * q.w)).sum(1), inner, mix)
    wa, wb = weights
    return ad.substitute(J * (f * ((zeta * (wb - wa) + wa) * q.w)).sum(0), inner, mix)


class _Block:
    """The inputs of :func:`_pair_block` for one block of pairs, so that its jets can be
    formed again with Hessians for the pairs the tangent asks for (:class:`_Deferred`): the
    update forms values and gradients only, for every pair."""

    def __init__(self, X, pm, curve, n_gauss, ends, test, slave):
        self.X, self.pm, self.curve, self.n_gauss = X, pm, curve, n_gauss
        self.ends, self.test, self.slave = ends, test, slave
        self._last = None

    def integrands(self, part=None):
        """:func:`_pair_block` of the pairs ``part`` (slice or index array into the block;
        None: all), with Hessians unless inside :func:`.ad.gradients_only`; the last result
        is kept (the gap Hessians and the test Jacobians of one tangent share it)."""
        key = (ad.second_order(), None if part is None else
               (part.start, part.stop) if isinstance(part, slice) else part.tobytes())
        if self._last is not None and self._last[0] == key:
            return self._last[1]
        if part is None:
            X, pm, ends, slave = self.X, self.pm, self.ends, self.slave
        else:
            X, pm, ends = self.X[part], self.pm[part], self.ends.subset(part)
            slave = None if self.slave is None else (self.slave[0], self.slave[1][part])
        out = _pair_block(X, pm, self.curve, self.n_gauss, ends, self.test, slave)
        self._last = (key, out)
        return out


class _Deferred:
    """A block [rows, cols] of the Hessians of the kernel's contributions ∫ N_j f dΓ
    (node-a rows, then node-b rows) of the integrands ``kind`` (0: weighted gaps, 1: test
    functionals) of the blocks of pairs (:class:`_Block`), formed on demand: all of them
    (call), or one weighted sum per pair (:meth:`weighted`). Newton's tangent needs only
    the latter, and only for the pairs with a node in contact (Hertz: a quarter of them):
    their jets are formed again, with Hessians, for just those pairs."""

    def __init__(self, K: int, blocks: list, kind: int, rows: slice, cols: slice,
                 shape: tuple):
        self.K, self.blocks, self.kind = K, blocks, kind
        self.rows, self.cols, self.shape = rows, cols, shape

    def __call__(self) -> np.ndarray:
        out = np.empty((2, self.K) + self.shape)
        for b0, b1, blk in self.blocks:
            out[:, b0:b1] = _nodal(blk.integrands()[self.kind]).hess[..., self.rows, self.cols]
        return out.reshape((2 * self.K,) + self.shape)

    def weighted(self, wa: np.ndarray, wb: np.ndarray, pairs) -> np.ndarray:
        """wa H_a + wb H_b of the pairs (index array or slice into [0, K))."""
        idx = np.arange(self.K)[pairs]
        out = np.empty((idx.shape[0],) + self.shape)
        for b0, b1, blk in self.blocks:
            here = np.flatnonzero((idx >= b0) & (idx < b1))
            if here.shape[0] == 0:
                continue
            sel = slice(here[0], here[-1] + 1)
            part = (slice(0, b1 - b0) if here.shape[0] == b1 - b0 else idx[sel] - b0)
            q = blk.integrands(part)[self.kind]
            out[sel] = _nodal(q, None, (wa[sel], wb[sel])).hess[..., self.rows, self.cols]
        return out


def _dual(q: np.ndarray) -> np.ndarray:
    """Node-a and node-b parts (leading axis of 2) of the standard-basis integrals →
    those of the dual basis: Φ_a = 2N_a − N_b, Φ_b = 2N_b − N_a."""
    return np.stack([2.0 * q[0] - q[1], 2.0 * q[1] - q[0]])


class _Dual:
    """The deferred Hessians (or test Jacobians) of the dual-basis integrals from those of
    the standard basis (linear in them, :func:`_dual`):

        wa H(Φ_a) + wb H(Φ_b) = (2 wa − wb) H(N_a) + (2 wb − wa) H(N_b)."""

    def __init__(self, standard: _Deferred):
        self.standard = standard

    def __call__(self) -> np.ndarray:
        H = self.standard()
        h = H.shape[0] // 2
        return np.concatenate([2.0 * H[:h] - H[h:], 2.0 * H[h:] - H[:h]])

    def weighted(self, wa: np.ndarray, wb: np.ndarray, pairs) -> np.ndarray:
        return self.standard.weighted(2.0 * wa - wb, 2.0 * wb - wa, pairs)


def _pair_block(X: np.ndarray, pm: np.ndarray, curve: MasterCurve, n_gauss: int,
                ends: Ends, test: bool = False, slave: tuple | None = None):
    """Jet kernel for a block of contributing pairs with local coordinates X (K, m) and
    the bounds of their integration intervals (:class:`Ends`).

    Returns the integrands of the weighted gaps and, with ``test``, of the Petrov–Galerkin
    test functionals Ψ_a, Ψ_b (module docstring; else None) (:class:`_Integrand`, which
    carries the bounds, :class:`Bounds`). The nodal areas follow from the
    bounds in closed form (:func:`_areas`). With ``test`` the jets run over [X, v] with 8
    virtual displacements v = (v_a, v_b, v_c, v_d) appended (value 0). With ``slave`` =
    (slave curve, slave segments) the slave points of the Gauss stage lie on that curve
    (two-sided smoothing): X then ends with the coordinates of the slave curve's stencil
    nodes before a and after b.
    """
    L = curve.stencil_size
    m = X.shape[1]
    if test:
        X = np.concatenate([X, np.zeros((X.shape[0], 8))], axis=1)
    # ζ of the shadow's ends in use (:func:`.segmentation.interval` for one end per entry), over the
    # local coordinates of the entry's pair; the pairs pass the facing test (float pass)
    pair, at_d, entry, on = ends.entries()
    v = Jet2.variables(X.take(pair, axis=0))
    xa, xb = (v[0], v[1]), (v[2], v[3])
    P = [(v[4 + 2 * i], v[5 + 2 * i]) for i in range(L)]
    x_n, t_n = curve.end_frame(pm.take(pair), P, at_d)
    z_end = ad.div(ad.dot(ad.sub(x_n, xa), t_n), ad.dot(ad.sub(xb, xa), t_n))
    lo, hi = ends.lo, ends.hi
    bounds = Bounds(lo, hi, z_end, entry, on)

    # Gauss-point stage over the variables z = [ζ_lo, ζ_hi, local coordinates]: there the
    # integrand only touches the few coordinates the curve evaluation needs (sparse jets),
    # and the dependence through ζ_lo, ζ_hi (on all of them) is applied once per pair by
    # the chain rule (ad.substitute), not per Gauss point.
    Z = np.concatenate([lo[:, None], hi[:, None], X], axis=1)
    vz = Jet2.variables(Z)
    z_lo, z_hi = vz[0], vz[1]
    xa, xb = (vz[2], vz[3]), (vz[4], vz[5])
    P = [(vz[6 + 2 * i], vz[7 + 2 * i]) for i in range(L)]
    width = z_hi - z_lo
    J = ad.norm(ad.sub(xb, xa)) * width          # ∫_lo^hi f dΓ = J Σ_g w_g f(ζ_g)

    s, w = gauss_legendre_01(n_gauss)
    # Gauss batch (n_gauss, K): the Gauss axis first, so per-pair quantities (K,) broadcast
    # and the Gauss sums add contiguous slabs
    s, w = s[:, None], w[:, None]
    zeta = z_lo + width * s
    if slave is None:
        x_s = ad.add(xa, ad.scale(ad.sub(xb, xa), zeta))
    else:
        # the same ζ on the slave's own curve through (prev(a), a, b, next(b)); the
        # segmentation, the measure and the test functions stay those of the chord
        slave_curve, ps = slave
        t0 = 6 + 2 * L
        x_s = slave_curve.derivatives(ps[None, :], zeta, [(vz[t0], vz[t0 + 1]), xa, xb,
                                                         (vz[t0 + 2], vz[t0 + 3])], 0)[0]
    if test:
        g, xi, n = curve.gap_frame(pm[None, :], x_s, P)
    else:
        g, xi = curve.gap(pm[None, :], x_s, P)
    gaps = _Integrand(g, J, zeta, w, bounds)
    tests = None
    if test:
        va, vb, vc, vd = [(vz[2 + m + 2 * i], vz[3 + m + 2 * i]) for i in range(4)]
        # δx_s(ζ) − Σ N̂_l(ξ) δx_l with δx → v: linear in v
        dv = ad.sub(ad.add(va, ad.scale(ad.sub(vb, va), zeta)),
                    ad.add(vc, ad.scale(ad.sub(vd, vc), xi)))
        tests = _Integrand(ad.dot(dv, n), J, zeta, w, bounds)
    return gaps, tests


def _area_jets(X: np.ndarray, lo: Jet2, hi: Jet2):
    """Jets of the nodal areas A_a, A_b of the pairs (exact: ∫ N_j dΓ over [ζ_lo, ζ_hi])."""
    v = Jet2.variables(X)
    J = ad.norm(ad.sub((v[2], v[3]), (v[0], v[1]))) * (hi - lo)
    area_b = J * (lo + hi) * 0.5                 # ∫ ζ dζ over [lo, hi], exact
    return J - area_b, area_b


def _areas(X: np.ndarray, bounds: Bounds):
    """Values (2, K) and gradients (2, K, m) of the nodal areas A_a, A_b of the pairs,

        J = |x_b − x_a| (ζ_hi − ζ_lo),   A_b = J (ζ_lo + ζ_hi)/2,   A_a = J − A_b,

    by the product rule from the bounds (the same as :func:`_area_jets`, without the
    Hessian work)."""
    K, m = X.shape
    d = X[:, 2:4] - X[:, 0:2]
    e = np.sqrt(d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1])
    de = np.zeros((K, m))
    de[:, 2:4] = d / e[:, None]
    de[:, 0:2] = -de[:, 2:4]
    lv, hv = bounds.lo, bounds.hi
    lg, hg = bounds.grads(m)
    width = hv - lv
    J = e * width
    dJ = width[:, None] * de + e[:, None] * (hg - lg)
    ssum = lv + hv
    Ab = J * ssum * 0.5
    dAb = 0.5 * (ssum[:, None] * dJ + J[:, None] * (lg + hg))
    return np.stack([J - Ab, Ab]), np.stack([dJ - dAb, dAb])


def weighted_gaps(slave_x: np.ndarray, slave_seg: np.ndarray, master_x: np.ndarray,
                  master_seg: np.ndarray, curve: MasterCurve,
                  pairs: Tuple[np.ndarray, np.ndarray], n_gauss: int = 2,
                  block: int = 2048, basis: str = "standard",
                  slave_curve: MasterCurve | None = None
                  ) -> Tuple[NodalContributions, NodalContributions]:
    """Mortar weighted gaps g̃_j and nodal areas A_j with exact derivatives, and D, M.

    ``curve`` must be built on the chain ``master_seg`` (its topology and stencils are
    used; the coordinates come from ``master_x``); ``pairs = (slave_segments,
    master_segments)`` are candidates (e.g. from :func:`.search.candidate_pairs`).
    Returns ``(gap, area, D, M)``: per-pair contributions for slave nodes a and b (local
    coordinates [x_a, y_a, x_b, y_b, stencil of the master segment], m = 2(2 + L)), and D
    (slave × slave), M (slave × master node) as COO triplets. Contribution order: node a
    of every contributing pair, then node b of every contributing pair.

    ``basis``: the weight of the weighted gaps, ``"standard"`` (N_j) or ``"dual"`` (Φ_j,
    :class:`_Dual`); the nodal areas are always A_j = ∫ N_j dΓ (positive: the scale of
    g̃_j/A_j).

    ``slave_curve`` (two-sided smoothing, docs/smoothing.md): a curve of the same kind as
    the master's built on the slave chain (a local one: its stencil the segment's nodes and
    their neighbours); the gap is then measured from the points of that curve instead of
    the slave chords, and the traction is tested with the linear functions of both sides
    (the Petrov–Galerkin test vectors, "Master-side test functions" above).

    The jet work runs over blocks of ``block`` pairs: the arrays then stay a few MB, which
    avoids the page-fault cost of fresh huge temporaries and stays in cache.
    """
    if n_gauss < 2:
        raise ValueError("mortar integration needs n_gauss >= 2")
    chain_m = master_seg                     # the caller's array: identifies the chain
    master_seg = np.asarray(master_seg, dtype=np.int64).reshape(-1, 2)
    L = curve.stencil_size
    m = 2 * (2 + L)
    ps = np.asarray(pairs[0], dtype=np.int64)
    pm = np.asarray(pairs[1], dtype=np.int64)

    # cheap float pass first: only contributing pairs get the (…, m, m) jet work
    xs = np.asarray(slave_x, dtype=float)
    if ps.shape[0] == 0:
        e = NodalContributions.empty(2, L)
        return e, NodalContributions.empty(2, L)
    lay = layout(ps, pm, slave_seg, chain_m, master_seg.shape[0])
    xa0, xb0 = columns(xs, lay.na), columns(xs, lay.nb)
    lo, hi, keep, mix = prepass(xa0, xb0, curve, master_x, lay)
    keep = np.flatnonzero(keep)
    ps, pm = ps.take(keep), pm.take(keep)
    ends = Ends(lo, hi, mix).subset(keep)
    K = ps.shape[0]
    if K == 0:
        e = NodalContributions.empty(2, L)
        return e, NodalContributions.empty(2, L)

    na, nb = lay.na.take(keep), lay.nb.take(keep)
    stencil = curve.stencil(pm)
    tail = None
    if slave_curve is not None:
        tail = slave_curve.stencil(ps)[:, [0, 3]]        # prev(a), next(b) on the slave
        m += 4
    X = np.empty((K, m))
    for col, v in enumerate(xa0 + xb0):        # columns x_a, y_a, x_b, y_b
        X[:, col] = v.take(keep)
    X[:, 4:4 + 2 * L] = curve.points(master_x)[stencil].reshape(K, 2 * L)
    if tail is not None:
        X[:, 4 + 2 * L:] = xs[tail].reshape(K, 4)

    # outputs per (node a / b, pair): reshaped to rows [0, K) for node a, [K, 2K) for node b
    val = np.empty((2, 2, K))                   # (gap / area, node, pair)
    grad = np.empty((2, 2, K, m))
    test = curve.hat_test or slave_curve is not None
    if test:
        tgrad = np.empty((2, K, 8))
    blocks = []
    closed = type(curve) is Polyline and slave_curve is None
    if closed:
        # straight master segments: closed-form integrals, derivatives over five
        # intermediates (PolylineGeometry)
        has_p, has_q = curve.prev_seg[pm] >= 0, curve.next_seg[pm] >= 0
        for b0 in range(0, K, block):
            b1 = min(b0 + block, K)
            e = ends if b1 - b0 == K else ends.subset(slice(b0, b1))
            v, gr = PolylineGeometry(X[b0:b1], has_p[b0:b1], has_q[b0:b1], e.lo, e.hi,
                                      e.mix, False).outputs()
            val[:, :, b0:b1] = v.reshape(2, 2, -1)
            grad[:, :, b0:b1] = gr.reshape(2, 2, b1 - b0, m)
        # (second derivatives in blocks of 128 pairs: (K, 144) temporaries of more pairs
        # cost page faults; measured 5 µs a pair at 128, 8–11 at 256–332)
        hess = PolylineDeferred(X, has_p, has_q, ends, 128)
        area_hessian = PolylineDeferred(X, has_p, has_q, ends, 128, kind=1)
    for b0 in range(0, 0 if closed else K, block):
        b1 = min(b0 + block, K)
        blk = _Block(X[b0:b1], pm[b0:b1], curve, n_gauss,
                     ends if b1 - b0 == K else ends.subset(slice(b0, b1)), test,
                     None if slave_curve is None else (slave_curve, ps[b0:b1]))
        # values and gradients of every pair now; Hessians for the pairs the tangent asks
        # for, when it asks (_Deferred): most candidate pairs are not in contact
        with ad.gradients_only():
            gaps, tests = blk.integrands()
            q = _nodal(gaps)
            val[0, :, b0:b1] = q.val
            grad[0, :, b0:b1] = q.grad[..., :m]
            if test:
                tgrad[:, b0:b1] = _nodal(tests).grad[..., m:]
        val[1, :, b0:b1], grad[1, :, b0:b1] = _areas(X[b0:b1], gaps.bounds)
        blocks.append((b0, b1, blk))

    if not closed:
        def area_hessian() -> np.ndarray:
            # the contact terms need only ∇A: the area Hessian is built on demand
            H = np.empty((2 * K, m, m))
            for b0, b1, blk in blocks:
                area_a, area_b = _area_jets(X[b0:b1], *blk.integrands()[0].bounds.jets(m))
                H[b0:b1] = area_a.hess
                H[K + b0:K + b1] = area_b.hess
            return H

        hess = _Deferred(K, blocks, 0, slice(0, m), slice(0, m), (m, m))
    node = np.concatenate([na, nb])
    slave_nodes = np.tile(np.stack([na, nb], axis=1), (2, 1))
    master_nodes = np.tile(stencil, (2, 1))
    jac = _Deferred(K, blocks, 1, slice(m, m + 8), slice(0, m), (8, m)) if test else None
    if basis == "dual":
        val[0], grad[0] = _dual(val[0]), _dual(grad[0])
        hess = _Dual(hess)
        if test:
            tgrad, jac = _dual(tgrad), _Dual(jac)
    elif basis != "standard":
        raise ValueError(f"unknown multiplier basis {basis!r}; expected 'standard' or 'dual'")
    tail_nodes = None if tail is None else np.tile(tail, (2, 1))
    gap = NodalContributions(node, slave_nodes, master_nodes, val[0].reshape(2 * K),
                             grad[0].reshape(2 * K, m), hess, tail_nodes)
    mc, md = master_seg[pm, 0], master_seg[pm, 1]
    if test:
        gap.test = MasterTest(np.tile(np.stack([na, nb, mc, md], axis=1), (2, 1)),
                              tgrad.reshape(2 * K, 8), jac)
    area = NodalContributions(node.copy(), slave_nodes.copy(), master_nodes.copy(),
                              val[1].reshape(2 * K), grad[1].reshape(2 * K, m), area_hessian,
                              None if tail_nodes is None else tail_nodes.copy())
    if basis == "dual":   # ∫Φ_j ≠ ∫N_j where the master covers part of a segment only
        area.psi = _dual(val[1]).reshape(2 * K)

    return gap, area


def mortar_matrices(slave_x: np.ndarray, slave_seg: np.ndarray, master_x: np.ndarray,
                    curve: MasterCurve, pairs: Tuple[np.ndarray, np.ndarray], n_gauss: int = 2
                    ) -> Tuple[Triplets, Triplets]:
    """The mortar matrices D_jk = ∫ N_j N_k dΓ (slave × slave) and M_jl = ∫ N_j N̂_l(ξ) dΓ
    (slave × master node; N̂ the master segment's linear shape functions at the
    projection ξ) as COO triplets, values only, over the same segmentation and Gauss points
    as :func:`weighted_gaps` (step 4 of the module docstring)."""
    ps = np.asarray(pairs[0], dtype=np.int64)
    pm = np.asarray(pairs[1], dtype=np.int64)
    xs = np.asarray(slave_x, dtype=float)
    empty = Triplets(np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0))
    if ps.shape[0] == 0:
        return empty, empty
    lo, hi, keep = segmentation(xs, slave_seg, curve, (ps, pm), master_x)
    keep = np.flatnonzero(keep)
    if keep.shape[0] == 0:
        return empty, empty
    lo, hi, pm = lo[keep], hi[keep], pm[keep]
    seg_s = np.asarray(slave_seg, dtype=np.int64).reshape(-1, 2)
    na, nb = seg_s[ps[keep], 0], seg_s[ps[keep], 1]
    xa, xb = (xs[na, 0], xs[na, 1]), (xs[nb, 0], xs[nb, 1])
    s, w = gauss_legendre_01(n_gauss)
    z = lo + (hi - lo) * s[:, None]                          # (n_gauss, K)
    x_s = (xa[0] + (xb[0] - xa[0]) * z, xa[1] + (xb[1] - xa[1]) * z)
    P = curve.split_points(curve.local_points(pm, master_x))
    xi = np.broadcast_to(ad.value(curve.gap(pm[None, :], x_s, P)[1]), z.shape)
    Jw = np.hypot(xb[0] - xa[0], xb[1] - xa[1]) * (hi - lo) * w[:, None]
    mc, md = curve.seg[pm, 0], curve.seg[pm, 1]
    Na, Nb = (1.0 - z) * Jw, z * Jw
    D = Triplets(np.concatenate([na, na, nb, nb]), np.concatenate([na, nb, na, nb]),
                 np.concatenate([(Na * (1.0 - z)).sum(0), (Na * z).sum(0),
                                 (Nb * (1.0 - z)).sum(0), (Nb * z).sum(0)]))
    M = Triplets(np.concatenate([na, na, nb, nb]), np.concatenate([mc, md, mc, md]),
                 np.concatenate([(Na * (1.0 - xi)).sum(0), (Na * xi).sum(0),
                                 (Nb * (1.0 - xi)).sum(0), (Nb * xi).sum(0)]))
    return D, M
