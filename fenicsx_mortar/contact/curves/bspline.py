"""One global cubic B-spline interpolating the master nodes (eqs. 3.16–3.33), with a
frozen parametrization and end conditions for open chains."""
from __future__ import annotations


import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from .. import ad
from ..kernel import chain_links
from ..registry import SMOOTHINGS
from .base import MasterCurve, _horner_derivatives


def _chains(seg: np.ndarray, n_nodes: int):
    """The chains of an ordered segment list: [(nodes in order, segments in order, closed)]."""
    before, after = chain_links(seg, n_nodes)
    seen = np.zeros(seg.shape[0], dtype=bool)
    out = []
    starts = [int(s) for s in range(seg.shape[0]) if before[seg[s, 0]] < 0]
    starts += list(range(seg.shape[0]))            # closed chains: any unseen segment
    for s0 in starts:
        if seen[s0]:
            continue
        segs, s = [], s0
        while s >= 0 and not seen[s]:
            seen[s] = True
            segs.append(s)
            s = after[seg[s, 1]]
        segs = np.array(segs, dtype=np.int64)
        closed = seg[segs[-1], 1] == seg[segs[0], 0]
        nodes = seg[segs, 0] if closed else np.append(seg[segs, 0], seg[segs[-1], 1])
        out.append((nodes, segs, bool(closed)))
    return out


def span_basis(U: np.ndarray, span: np.ndarray, t0: np.ndarray, p: int) -> np.ndarray:
    """Power coefficients of the p+1 B-spline basis functions N_{span−p … span, p} that are
    nonzero on the knot span [U[span], U[span+1]), as polynomials in τ = t − t0:
    (M, p+1 functions, p+1 powers). Cox–de Boor recursion on polynomials (Piegl & Tiller,
    eq. 2.5) with 0/0 := 0; t0 may lie outside the span (the span's polynomial is used)."""
    M = span.shape[0]
    N = np.zeros((M, 1, p + 1))
    N[:, 0, 0] = 1.0

    def times_linear(poly, const, slope):    # poly · (const + slope τ)
        out = poly * const[:, None]
        out[:, 1:] += slope * poly[:, :-1]
        return out

    for q in range(1, p + 1):
        new = np.zeros((M, q + 1, p + 1))
        for kk in range(q + 1):
            k = span - q + kk
            if kk >= 1:      # (t − u_k)/(u_{k+q} − u_k) N_{k,q−1}
                den = U[k + q] - U[k]
                f = np.where(den > 0, 1.0 / np.where(den > 0, den, 1.0), 0.0)[:, None]
                new[:, kk] += f * times_linear(N[:, kk - 1], t0 - U[k], 1.0)
            if kk <= q - 1:  # (u_{k+q+1} − t)/(u_{k+q+1} − u_{k+1}) N_{k+1,q−1}
                den = U[k + q + 1] - U[k + 1]
                f = np.where(den > 0, 1.0 / np.where(den > 0, den, 1.0), 0.0)[:, None]
                new[:, kk] += f * times_linear(N[:, kk], U[k + q + 1] - t0, -1.0)
        N = new
    return N


def _sparse_inverse(A: np.ndarray, block: int = 512, drop: float = 1e-17, rhs=None):
    """Entries (rows, cols, values) of A⁻¹ (or of A⁻¹ rhs, ``rhs`` a sparse matrix) for the
    banded (or cyclic banded) interpolation matrix, by a sparse LU and blocks of right-hand
    sides; entries below ``drop`` times their column's maximum are left out (the inverse of
    a B-spline collocation matrix decays geometrically away from the diagonal)."""
    lu = spla.splu(sp.csc_matrix(A))
    n = A.shape[0]
    rhs = None if rhs is None else sp.csc_matrix(rhs)
    n_cols = n if rhs is None else rhs.shape[1]
    rows, cols, vals = [], [], []
    for j0 in range(0, n_cols, block):
        j1 = min(j0 + block, n_cols)
        if rhs is None:
            E = np.zeros((n, j1 - j0))
            E[np.arange(j0, j1), np.arange(j1 - j0)] = 1.0
        else:
            E = rhs[:, j0:j1].toarray()
        X = lu.solve(E)
        keep = np.abs(X) > drop * np.abs(X).max(axis=0, keepdims=True)
        r, c = np.nonzero(keep)
        rows.append(r)
        cols.append(c + j0)
        vals.append(X[r, c])
    return np.concatenate(rows), np.concatenate(cols), np.concatenate(vals)


class BSplineParametrization:
    """Frozen data of a global B-spline on one master chain topology: per chain the degree,
    parameters ū, knots, and the derived per-segment polynomial tables and point map.

    Built from node coordinates by :meth:`from_nodes` (docs/design.md §6.5):
    * chord-length parameters ū₀ = 0, ū_k = ū_{k−1} + |x_k − x_{k−1}|/r, ū_last = 1;
    * open chain (n+1 nodes, clamped, cubic for n ≥ 3): knots 0, 0, 0, 0, ū_1 … ū_{n−1},
      1, 1, 1, 1 and n+3 control points, the two beyond the interpolation conditions set by
      the end derivatives C′(0), C′(1) = dx/dū of the polynomial through the first (last)
      min(5, n+1) nodes in ū (O(h⁴) slopes: the end segments keep the interior's accuracy;
      not-a-knot ends had 2.7 × its gap error there); n < 3: the polynomial of degree n
      through all nodes (knots 0 … 0, 1 … 1);
    * closed chain (n nodes, periodic, p = 3): knots at the parameters, extended
      periodically (u_{k+n} = u_k + 1); n control points, P_{k+n} = P_k (for odd degree the
      parameters are the centred averages of themselves, and every node sits on a knot: the
      classical periodic cubic spline, a cyclic tridiagonal interpolation system);
    * control points from Σ_i B_{i,p}(ū_k) P_i = x_k (and the end rows): P = A⁻¹ C X;
      ``point_map`` holds A⁻¹ C (entries below 1e-17 of their column's maximum dropped:
      they decay like 0.27^distance).
    """

    def __init__(self, chains, n_nodes: int):
        self.chains = chains           # list of dicts (see from_nodes)
        self.n_nodes = n_nodes

    @classmethod
    def from_nodes(cls, x: np.ndarray, seg: np.ndarray) -> "BSplineParametrization":
        chains = []
        for nodes, segs, closed in _chains(seg, x.shape[0]):
            pts = x[nodes]
            loop = np.vstack([pts, pts[:1]]) if closed else pts
            chord = np.linalg.norm(np.diff(loop, axis=0), axis=1)
            if np.any(chord <= 0.0):
                raise ValueError("B-spline: coincident consecutive master nodes")
            ubar = np.concatenate([[0.0], np.cumsum(chord) / chord.sum()])
            ubar[-1] = 1.0
            n = len(chord)                      # segments of the chain
            if closed:
                if n < 4:
                    raise ValueError("periodic B-spline needs a closed chain of >= 4 nodes")
                p = 3
                k = np.arange(-p, n + p + 1)
                U = ubar[k % n] + np.floor_divide(k, n)
                n_ctrl = n
            elif n >= 3:
                # knots at the parameters, and the end derivatives dx/dū of the quartic (a
                # cubic on 4 nodes) through the end nodes in ū: exact to O(h⁴), so the end
                # segments keep the interior's order and constant (not-a-knot ends had
                # 2.7 × the interior's gap error and polluted the next segments)
                p = 3
                U = np.concatenate([np.zeros(4), ubar[1:n], np.ones(4)])
                n_ctrl = n + 3
                k = min(5, n + 1)
                end = (_derivative_weights(ubar[:k], 0.0), _derivative_weights(ubar[-k:], 1.0))
            else:
                p = n
                U = np.concatenate([np.zeros(p + 1), np.ones(p + 1)])
                n_ctrl = n + 1
            chains.append(dict(nodes=nodes, segs=segs, closed=closed, p=p, ubar=ubar, U=U,
                               n_ctrl=n_ctrl, end=None if closed or n < 3 else end))
        self = cls(chains, x.shape[0])
        self._tables(seg.shape[0])
        return self

    def _span(self, ch, t, right: bool) -> np.ndarray:
        """Knot span index m of parameters t (U[m] ≤ t < U[m+1]; with ``right`` False the
        span whose open interval ends at t, U[m] < t ≤ U[m+1])."""
        U, p = ch["U"], ch["p"]
        if ch["closed"]:
            first, last = p, len(U) - p - 2
        else:
            first, last = p, ch["n_ctrl"] - 1
        m = np.searchsorted(U, t, side="right" if right else "left") - 1
        return np.clip(m, first, last)

    def _ctrl(self, ch, ext):
        return ext % ch["n_ctrl"] if ch["closed"] else ext

    def _tables(self, n_seg: int) -> None:
        """Per segment the slot weights as polynomials in ξ: W (n_seg, 4, 4) with
        x(ξ) = Σ_s Σ_r W[s, r] ξ^r P_s (every segment is one knot span: the knots are at the
        parameters); the stencil (n_seg, 4) of global point indices; the point map."""
        L = 4
        self.W = np.zeros((n_seg, L, 4))
        self.stencil = np.zeros((n_seg, L), dtype=np.int64)
        rows, cols, vals = [], [], []
        offset = 0
        for ch in self.chains:
            U, p, ubar, segs = ch["U"], ch["p"], ch["ubar"], ch["segs"]
            t_lo, t_hi = ubar[:-1], ubar[1:]
            m = self._span(ch, t_lo, True)
            if np.any(self._span(ch, t_hi, False) != m):
                raise AssertionError("B-spline: a data interval spans more than one knot span")
            du = t_hi - t_lo
            C = span_basis(U, m, t_lo, p)                     # powers of τ = t − ū_i
            C = C * du[:, None, None] ** np.arange(p + 1)      # powers of ξ
            for kk in range(p + 1):
                self.W[segs, kk, :p + 1] = C[:, kk]
            for s in range(L):
                ext = np.minimum(m - p + s, m)                 # pad: repeat the last point
                self.stencil[segs, s] = offset + self._ctrl(ch, ext)
            # interpolation matrix A[k, i] = B_i(ū_k) at the data parameters
            nd = len(ch["nodes"])
            tk = ubar[:nd]
            mk = self._span(ch, tk, True)
            Bk = span_basis(U, mk, tk, p)[:, :, 0]            # values at τ = 0
            A = np.zeros((nd, ch["n_ctrl"]))
            for kk in range(p + 1):
                np.add.at(A, (np.arange(nd), self._ctrl(ch, mk - p + kk)), Bk[:, kk])
            if ch["end"] is None:
                r, c, v = _sparse_inverse(A)
            else:
                r, c, v = self._with_end_derivatives(ch, A)
            rows.append(offset + r)
            cols.append(ch["nodes"][c])
            vals.append(v)
            ch["A"] = A
            ch["offset"] = offset
            offset += ch["n_ctrl"]
        self.n_points = offset
        self.point_map = sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows),
                                        np.concatenate(cols))),
                                       shape=(self.n_points, self.n_nodes))


    @staticmethod
    def _with_end_derivatives(ch, A: np.ndarray, drop: float = 1e-17):
        """Entries (control point, node, value) of the map nodes → control points of an
        open chain with the end derivative conditions C′(0) = Σ w₀ x, C′(1) = Σ w₁ x: the
        interpolation rows ``A`` and the two derivative rows (C′(0) = 3/u₄ (P₁ − P₀),
        C′(1) = 3/(1 − u_{n−1}) (P_n − P_{n−1}), Piegl & Tiller eq. 3.7) solved for the
        right-hand sides [x; Σ w₀ x; Σ w₁ x], still linear in the nodes."""
        U, nd, nc = ch["U"], A.shape[0], ch["n_ctrl"]
        w0, w1 = ch["end"]
        k = w0.shape[0]
        d0, d1 = 3.0 / U[4], 3.0 / (1.0 - U[nc - 1])
        M = np.zeros((nd + 2, nc))
        M[:nd] = A
        M[nd, :2] = -d0, d0
        M[nd + 1, nc - 2:] = -d1, d1
        rhs = sp.vstack([sp.identity(nd),
                         sp.csr_matrix((w0, (np.zeros(k), np.arange(k))), shape=(1, nd)),
                         sp.csr_matrix((w1, (np.zeros(k), np.arange(nd - k, nd))),
                                       shape=(1, nd))])
        return _sparse_inverse(M, drop=drop, rhs=rhs)


def _derivative_weights(t: np.ndarray, t0: float) -> np.ndarray:
    """w with Σ w_i f(t_i) = q′(t0), q the polynomial through (t_i, f(t_i))."""
    V = np.vander(t - t0, t.shape[0], increasing=True)
    return np.linalg.solve(V.T, np.eye(t.shape[0])[1])


@SMOOTHINGS.register("bspline")
class BSpline(MasterCurve):
    """One global cubic B-spline per master chain, interpolating all its nodes (C2;
    docs/design.md §6.5, eqs. 3.16–3.33): clamped for an open chain, periodic for a closed one.

    The curve is parametrized per master segment by the local ξ of eq. 3.33,
        t = ū_i + ξ (ū_{i+1} − ū_i)   on segment i (the data interval [ū_i, ū_{i+1}]),
    one knot span (the knots are at the parameters), so x(ξ) is one cubic in the segment's
    L = 4 control points (fewer for a chain of 1 or 2 segments: the unused slots repeat a
    point with zero weight); x′ = dx/dξ. Closest-point projection (Newton on
    f(t) = (x_s − x)·x′, here in ξ, which has the same roots) with hand-over between segments
    (:mod:`.projection`).

    Parametrization and linearization. The parameters ū and knots (and with them the
    interpolation matrix A and ``point_map`` = A⁻¹) are a :class:`BSplineParametrization`
    that is *frozen*: a curve built with ``parametrization=`` (or by :meth:`with_nodes`)
    reuses it, the control points P = A⁻¹ X are then linear in the node coordinates X and
    the kernels' derivatives (taken with respect to P, mapped to X by ``point_map``) are
    exact. Rebuilding the parametrization from moved nodes changes ū (chord lengths) and
    therefore the curve between the nodes by O(|ΔX|); the tangent does not contain that
    term. Intended use (contact/pair.py): build once from the reference configuration and
    call :meth:`with_nodes` at every iterate — the interpolation condition x(ū_k) = x_k
    holds for any X, only the parametrization stops being exactly chord-length.
    """

    stencil_size = 4
    c1_gap = True
    hat_test = True

    def __init__(self, x, seg, parametrization: BSplineParametrization | None = None):
        super().__init__(x, seg)
        if parametrization is None:
            parametrization = BSplineParametrization.from_nodes(self.x, self.seg)
        self.parametrization = parametrization
        self.point_map = parametrization.point_map
        # (16, n_seg): row 4s + r = weight of slot s, power r; column = segment
        W = parametrization.W
        self._WT = np.ascontiguousarray(W.reshape(W.shape[0], 16).T)
        self._W = W
        self._stencil = parametrization.stencil

    def with_nodes(self, x):
        return BSpline(x, self.seg, self.parametrization)

    def stencil(self, seg_index):
        return self._stencil[np.asarray(seg_index, dtype=np.int64)]

    def derivatives(self, seg_index, xi, P, order):
        return _horner_derivatives(self._coefficients(seg_index, P), xi, order)

    def _coefficients(self, seg_index, P) -> list:
        """Power coefficients C_r = Σ_s W_sr P_s of the segment's cubic (linear in P: cheap
        jets)."""
        W = self._WT[:, np.asarray(seg_index, dtype=np.int64)]   # (16, *B), contiguous rows
        C = []
        for r in range(4):
            v = None
            for sl in range(self.stencil_size):
                t = ad.scale(P[sl], W[4 * sl + r])
                v = t if v is None else ad.add(v, t)
            C.append(v)
        return C

    def node_points(self, seg_index, P):
        z = np.zeros(np.shape(seg_index))
        return (self.derivatives(seg_index, z, P, 0)[0],
                self.derivatives(seg_index, z + 1.0, P, 0)[0])

    def node_tangents(self, seg_index, P):
        z = np.zeros(np.shape(seg_index))
        return (self.derivatives(seg_index, z, P, 1)[1],
                self.derivatives(seg_index, z + 1.0, P, 1)[1])

    def end_frame(self, seg_index, P, at_d):
        x, a = self.derivatives(seg_index, np.where(at_d, 1.0, 0.0), P, 1)
        return x, a


