"""Mortar segment-to-segment integrals: weighted gaps, nodal areas, D and M (DESIGN.md §4).

For a candidate pair (slave segment s = [x_a, x_b], master segment m = [x_c, x_d]):

1. Segmentation on the slave segment, x_s(ζ) = (1−ζ) x_a + ζ x_b. The shadow of the
   master segment ends where the slave point lies on the line through a master end node
   perpendicular to the curve's nodal tangent t̄ there (:meth:`MasterCurve.node_tangents`,
   for the polyline the averaged tangent of DESIGN.md eq. 3.4):
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
"""
from __future__ import annotations

import functools
from typing import Sequence, Tuple

import numpy as np

from . import ad
from .ad import Jet2, Vec2
from .curves import MasterCurve
from .kernel import MasterTest, NodalContributions, Triplets


@functools.lru_cache(maxsize=None)
def gauss_legendre_01(n: int) -> Tuple[np.ndarray, np.ndarray]:
    """Gauss–Legendre points and weights on [0, 1] (weights sum to 1; cached, read-only)."""
    s, w = np.polynomial.legendre.leggauss(int(n))
    s, w = 0.5 * (s + 1.0), 0.5 * w
    s.setflags(write=False)
    w.setflags(write=False)
    return s, w


def _interval(xa: Vec2, xb: Vec2, P: Sequence[Vec2], curve: MasterCurve, pm: np.ndarray,
              nodes=None):
    """ζ_lo, ζ_hi (jets or arrays) and the boolean 'slave faces master' per pair.
    ``nodes``: (x_c, x_d, t̄_c, t̄_d) per pair if already known (values; P is then unused)."""
    if nodes is None:
        xc, xd = curve.node_points(pm, P)
        tc, td = curve.node_tangents(pm, P)
    else:
        xc, xd, tc, td = nodes
    e = ad.sub(xb, xa)
    den_c = ad.dot(e, tc)
    den_d = ad.dot(e, td)
    facing = (ad.value(den_c) < 0.0) & (ad.value(den_d) < 0.0)
    if not np.all(facing):
        # keep the discarded entries finite; they are dropped by the caller
        den_c = ad.where(facing, den_c, -1.0)
        den_d = ad.where(facing, den_d, -1.0)
    zc = ad.dot(ad.sub(xc, xa), tc) * ad.reciprocal(den_c)
    zd = ad.dot(ad.sub(xd, xa), td) * ad.reciprocal(den_d)
    zc_v, zd_v = ad.value(zc), ad.value(zd)
    zmin = ad.where(zc_v <= zd_v, zc, zd)
    zmax = ad.where(zc_v <= zd_v, zd, zc)
    lo = ad.where(ad.value(zmin) > 0.0, zmin, 0.0)
    hi = ad.where(ad.value(zmax) < 1.0, zmax, 1.0)
    return lo, hi, facing


def _node_values(curve: MasterCurve, master_x, pm: np.ndarray):
    """(x_c, x_d, t̄_c, t̄_d) values per pair, evaluated once per master segment in use
    (the candidate pairs repeat each master segment many times) and gathered."""
    n_seg = curve.seg.shape[0]
    used = np.zeros(n_seg, dtype=bool)
    used[pm] = True
    seg_used = np.flatnonzero(used)
    inv = (np.cumsum(used) - 1)[pm]
    P = curve.split_points(curve.local_points(seg_used, master_x))
    xc, xd = curve.node_points(seg_used, P)
    tc, td = curve.node_tangents(seg_used, P)
    return tuple((np.asarray(v[0], dtype=float)[inv], np.asarray(v[1], dtype=float)[inv])
                 for v in (xc, xd, tc, td))


def _prepass(xa, xb, curve: MasterCurve, master_x, pm: np.ndarray):
    """Values (ζ_lo, ζ_hi, keep) of the candidate pairs (slave end points xa, xb (k, 2))."""
    nodes = _node_values(curve, master_x, pm)
    lo, hi, facing = _interval((xa[:, 0], xa[:, 1]), (xb[:, 0], xb[:, 1]), None, curve, pm,
                               nodes)
    lo, hi = np.asarray(lo, dtype=float), np.asarray(hi, dtype=float)
    return lo, hi, facing & (hi > lo)


def segmentation(slave_x: np.ndarray, slave_seg: np.ndarray, curve: MasterCurve,
                 pairs: Tuple[np.ndarray, np.ndarray], master_x: np.ndarray | None = None
                 ) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Integration intervals of the candidate pairs (values only).

    Returns ``(zeta_lo, zeta_hi, keep)``, each (n_pairs,): the interval [ζ_lo, ζ_hi] ⊂ [0, 1]
    of the slave segment served by the master segment and whether the pair contributes
    (faces the master and ζ_hi > ζ_lo). Master coordinates from ``master_x`` (default: the
    curve's own).
    """
    ps = np.asarray(pairs[0], dtype=np.int64)
    pm = np.asarray(pairs[1], dtype=np.int64)
    seg = np.asarray(slave_seg, dtype=np.int64).reshape(-1, 2)[ps]
    xs = np.asarray(slave_x, dtype=float)
    return _prepass(xs[seg[:, 0]], xs[seg[:, 1]], curve, master_x, pm)


def _pair_block(X: np.ndarray, pm: np.ndarray, curve: MasterCurve, n_gauss: int,
                test: bool = False):
    """Jet kernel for a block of contributing pairs with local coordinates X (K, m).

    Returns the jets (over X) of g̃_a, g̃_b, the interval jets (ζ_lo, ζ_hi) (over X), and
    the values ζ_g, ξ_g (n_gauss, K) and the Gauss weights times the length element
    (n_gauss, K) for D and M. The nodal areas follow from (ζ_lo, ζ_hi) in closed form
    (:func:`_areas`). With ``test``, the jets run over [X, v] with 8 virtual displacements
    v = (v_a, v_b, v_c, v_d) appended (value 0) and two more jets Ψ_a, Ψ_b are returned
    (the Petrov–Galerkin test functionals of the module docstring).
    """
    L = curve.stencil_size
    m = X.shape[1]
    if test:
        X = np.concatenate([X, np.zeros((X.shape[0], 8))], axis=1)
    v = Jet2.variables(X)
    xa, xb = (v[0], v[1]), (v[2], v[3])
    P = [(v[4 + 2 * i], v[5 + 2 * i]) for i in range(L)]
    lo, hi, _ = _interval(xa, xb, P, curve, pm)

    # Gauss-point stage over the variables z = [ζ_lo, ζ_hi, local coordinates]: there the
    # integrand only touches the few coordinates the curve evaluation needs (sparse jets),
    # and the dependence through ζ_lo, ζ_hi (on all of them) is applied once per pair by
    # the chain rule (ad.substitute), not per Gauss point.
    Z = np.concatenate([lo.val[:, None], hi.val[:, None], X], axis=1)
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
    x_s = ad.add(xa, ad.scale(ad.sub(xb, xa), zeta))
    if test:
        g, xi, n = curve.gap_frame(pm[None, :], x_s, P)
    else:
        g, xi = curve.gap(pm[None, :], x_s, P)

    def nodal(f):                                # (∫ N_a f dΓ, ∫ N_b f dΓ) as jets
        wf = f * w
        fb = J * (wf * zeta).sum(0)
        return [ad.substitute(q, (lo, hi)) for q in (J * wf.sum(0) - fb, fb)]

    jets = nodal(g)
    if test:
        va, vb, vc, vd = [(vz[2 + m + 2 * i], vz[3 + m + 2 * i]) for i in range(4)]
        # δx_s(ζ) − Σ N̂_l(ξ) δx_l with δx → v: linear in v
        dv = ad.sub(ad.add(va, ad.scale(ad.sub(vb, va), zeta)),
                    ad.add(vc, ad.scale(ad.sub(vd, vc), xi)))
        jets += nodal(ad.dot(dv, n))
        lo, hi = (Jet2(q.val, q.grad[:, :m], q.hess[:, :m, :m]) for q in (lo, hi))
    return jets, (lo, hi), zeta.val, np.broadcast_to(ad.value(xi), zeta.shape), J.val * w


def _area_jets(X: np.ndarray, lo: Jet2, hi: Jet2):
    """Jets of the nodal areas A_a, A_b of the pairs (exact: ∫ N_j dΓ over [ζ_lo, ζ_hi])."""
    v = Jet2.variables(X)
    J = ad.norm(ad.sub((v[2], v[3]), (v[0], v[1]))) * (hi - lo)
    area_b = J * (lo + hi) * 0.5                 # ∫ ζ dζ over [lo, hi], exact
    return J - area_b, area_b


def _areas(X: np.ndarray, lo: Jet2, hi: Jet2):
    """Values (2, K) and gradients (2, K, m) of the nodal areas A_a, A_b of the pairs,

        J = |x_b − x_a| (ζ_hi − ζ_lo),   A_b = J (ζ_lo + ζ_hi)/2,   A_a = J − A_b,

    by the product rule from the interval jets (the same as :func:`_area_jets`, without
    the Hessian work)."""
    K, m = X.shape
    d = X[:, 2:4] - X[:, 0:2]
    e = np.sqrt(d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1])
    de = np.zeros((K, m))
    de[:, 2:4] = d / e[:, None]
    de[:, 0:2] = -de[:, 2:4]
    lv, hv = lo.val, hi.val
    lg, hg = lo.grad, hi.grad
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
                  block: int = 2048
                  ) -> Tuple[NodalContributions, NodalContributions, Triplets, Triplets]:
    """Mortar weighted gaps g̃_j and nodal areas A_j with exact derivatives, and D, M.

    ``curve`` must be built on the chain ``master_seg`` (its topology and stencils are
    used; the coordinates come from ``master_x``); ``pairs = (slave_segments,
    master_segments)`` are candidates (e.g. from :func:`.search.candidate_pairs`).
    Returns ``(gap, area, D, M)``: per-pair contributions for slave nodes a and b (local
    coordinates [x_a, y_a, x_b, y_b, stencil of the master segment], m = 2(2 + L)), and D
    (slave × slave), M (slave × master node) as COO triplets. Contribution order: node a
    of every contributing pair, then node b of every contributing pair.

    The jet work runs over blocks of ``block`` pairs: the arrays then stay a few MB, which
    avoids the page-fault cost of fresh huge temporaries and stays in cache.
    """
    if n_gauss < 2:
        raise ValueError("mortar integration needs n_gauss >= 2")
    master_seg = np.asarray(master_seg, dtype=np.int64).reshape(-1, 2)
    L = curve.stencil_size
    m = 2 * (2 + L)
    ps = np.asarray(pairs[0], dtype=np.int64)
    pm = np.asarray(pairs[1], dtype=np.int64)

    # cheap float pass first: only contributing pairs get the (…, m, m) jet work
    seg_s = np.asarray(slave_seg, dtype=np.int64).reshape(-1, 2)
    xs = np.asarray(slave_x, dtype=float)
    na, nb = seg_s[ps, 0], seg_s[ps, 1]
    xa0, xb0 = xs[na], xs[nb]
    keep = _prepass(xa0, xb0, curve, master_x, pm)[2] if ps.shape[0] else ps.astype(bool)
    ps, pm = ps[keep], pm[keep]
    K = ps.shape[0]
    empty_coo = Triplets(np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0))
    if K == 0:
        e = NodalContributions.empty(2, L)
        return e, NodalContributions.empty(2, L), empty_coo, empty_coo

    na, nb = na[keep], nb[keep]
    stencil = curve.stencil(pm)
    X = np.concatenate([xa0[keep], xb0[keep], curve.points(master_x)[stencil].reshape(K, 2 * L)],
                       axis=1)

    # outputs: rows [0, K) for node a, [K, 2K) for node b
    val = np.empty((2, 2 * K))
    grad = np.empty((2, 2 * K, m))
    ghess = np.empty((2 * K, m, m))
    z = np.empty((n_gauss, K))
    xv = np.empty((n_gauss, K))
    Jw = np.empty((n_gauss, K))
    test = curve.hat_test
    if test:
        tgrad = np.empty((2 * K, 8))
        tjac = np.empty((2 * K, 8, m))
    intervals = []
    for b0 in range(0, K, block):
        b1 = min(b0 + block, K)
        jets, (lo, hi), z[:, b0:b1], xv[:, b0:b1], Jw[:, b0:b1] = _pair_block(
            X[b0:b1], pm[b0:b1], curve, n_gauss, test)
        for off, jet in ((0, jets[0]), (K, jets[1])):
            val[0, off + b0:off + b1] = jet.val
            grad[0, off + b0:off + b1] = jet.grad[:, :m]
            ghess[off + b0:off + b1] = jet.hess[:, :m, :m]
        if test:
            for off, jet in ((0, jets[2]), (K, jets[3])):
                tgrad[off + b0:off + b1] = jet.grad[:, m:]
                tjac[off + b0:off + b1] = jet.hess[:, m:, :m]
        av, ag = _areas(X[b0:b1], lo, hi)
        val[1, b0:b1], val[1, K + b0:K + b1] = av
        grad[1, b0:b1], grad[1, K + b0:K + b1] = ag
        intervals.append((b0, b1, lo, hi))

    def area_hessian() -> np.ndarray:
        # the contact terms need only ∇A: the area Hessian is built on demand
        H = np.empty((2 * K, m, m))
        for b0, b1, lo, hi in intervals:
            area_a, area_b = _area_jets(X[b0:b1], lo, hi)
            H[b0:b1] = area_a.hess
            H[K + b0:K + b1] = area_b.hess
        return H

    node = np.concatenate([na, nb])
    slave_nodes = np.tile(np.stack([na, nb], axis=1), (2, 1))
    master_nodes = np.tile(stencil, (2, 1))
    gap = NodalContributions(node, slave_nodes, master_nodes, val[0], grad[0], ghess)
    mc, md = master_seg[pm, 0], master_seg[pm, 1]
    if test:
        gap.test = MasterTest(np.tile(np.stack([na, nb, mc, md], axis=1), (2, 1)), tgrad, tjac)
    area = NodalContributions(node.copy(), slave_nodes.copy(), master_nodes.copy(),
                              val[1], grad[1], area_hessian)

    # mortar matrices (values only), 1-point-per-Gauss sums of N_j N_k and N_j N̂_l
    Na = (1.0 - z) * Jw
    Nb = z * Jw
    D = Triplets(np.concatenate([na, na, nb, nb]), np.concatenate([na, nb, na, nb]),
                 np.concatenate([(Na * (1.0 - z)).sum(0), (Na * z).sum(0),
                                 (Nb * (1.0 - z)).sum(0), (Nb * z).sum(0)]))
    M = Triplets(np.concatenate([na, na, nb, nb]), np.concatenate([mc, md, mc, md]),
                 np.concatenate([(Na * (1.0 - xv)).sum(0), (Na * xv).sum(0),
                                 (Nb * (1.0 - xv)).sum(0), (Nb * xv).sum(0)]))
    return gap, area, D, M
