"""The mortar integrals on a straight master segment (the polyline, the default) in closed
form, with their derivatives by dense chain rules (:mod:`.mortar`'s jets give the same to
round-off; docs/design.md §4).
"""
from __future__ import annotations

import numpy as np

from .segmentation import Ends


# On a straight master segment the gap of a chord point is linear along the chord,
# g(ζ) = (1−ζ) g_a + ζ g_b with g_s = (x_s − x_c)·n, so the integrals are polynomials in
# the bounds, and five intermediates y = (|x_b − x_a|, g_a, g_b, ζ_lo, ζ_hi) carry all the
# dependence on the 12 local coordinates [a, b, p, c, d, q]: derivatives by the chain rule
# over y in a few dense numpy operations instead of the jets' many small ones (the jets'
# per-operation overhead was most of the kernel's time on Hertz). Every second derivative
# of an intermediate is a sum of 2 × 2 blocks h times constant selections D1ᵀ h D2, so a
# weighted Hessian is one matrix product of per-pair coefficients with constant 12 × 12
# patterns (_PATTERNS) plus a low-rank part.

#: _SEL[i] (2, 12) picks local point i's coordinates (a, b, p, c, d, q = 0 … 5)
_SEL = np.zeros((6, 2, 12))
for _i in range(6):
    _SEL[_i, 0, 2 * _i] = _SEL[_i, 1, 2 * _i + 1] = 1.0
_PA, _PB, _PP, _PC, _PD, _PQ = range(6)
_DIFF = {"ab": _SEL[_PB] - _SEL[_PA], "cd": _SEL[_PD] - _SEL[_PC],
         "pc": _SEL[_PC] - _SEL[_PP], "dq": _SEL[_PQ] - _SEL[_PD]}
_EYE2 = np.eye(2)
_ROT = np.array([[0.0, -1.0], [1.0, 0.0]])  # perp(v) = e3 × v = _ROT v


def _pattern(D1: np.ndarray, D2: np.ndarray, sym: bool) -> np.ndarray:
    """(4, 144): row 2i + j is D1[i]ᵀ D2[j] (flattened; + its transpose with ``sym``), so
    that h.reshape(K, 4) @ pattern = D1ᵀ h D2 (+ its transpose) for 2 × 2 blocks h."""
    out = np.empty((4, 144))
    for i in range(2):
        for j in range(2):
            M = np.outer(D1[i], D2[j])
            out[2 * i + j] = (M + M.T if sym else M).ravel()
    return out


#: the patterns a weighted Hessian is made of, by key: ("C", u, v) = D_uᵀ h D_v,
#: ("S", u, v) = the same plus its transpose; u, v a point (an index) or a difference
_KEYS = ([("C", "ab", "ab"), ("C", "cd", "cd"), ("C", "pc", "pc"), ("C", "dq", "dq"),
          ("S", _PA, "cd"), ("S", _PB, "cd"), ("S", _PC, "cd"), ("S", _PD, "cd"),
          ("S", _PA, "pc"), ("S", _PB, "pc"), ("S", _PC, "pc"),
          ("S", _PA, "dq"), ("S", _PB, "dq"), ("S", _PD, "dq")]
         + [("S", "r" + s, "cd") for s in "ab"])
_COLUMN = {k: 4 * i for i, k in enumerate(_KEYS)}


def _operand(u):
    if isinstance(u, str) and u[0] == "r":          # r = x_s − x_c
        return _SEL[_PA if u[1] == "a" else _PB] - _SEL[_PC]
    return _DIFF[u] if isinstance(u, str) else _SEL[u]


_PATTERNS = np.concatenate([_pattern(_operand(u), _operand(v), kind == "S")
                            for kind, u, v in _KEYS])


def _unit_derivatives(vx: np.ndarray, vy: np.ndarray, second: bool):
    """unit(v) (2, K), its Jacobian (2, 2, K) and, with ``second``, Σ_i w_i ∂²u_i/∂v∂v as a
    function of w (2, K) → (2, 2, K): ∂²u_i/∂v_j∂v_k = (3 u_i u_j u_k − δ_ij u_k − δ_ik u_j
    − δ_jk u_i)/|v|² (batch last)."""
    length = np.sqrt(vx * vx + vy * vy)
    u = np.stack([vx / length, vy / length])
    uu = u[:, None] * u[None, :]
    J = (_EYE2[:, :, None] - uu) / length
    if not second:
        return u, J, None
    l2 = length * length

    def contracted(w):
        wu = w[0] * u[0] + w[1] * u[1]
        wuT = w[:, None] * u[None, :]
        return (3.0 * wu * uu - wuT - wuT.transpose(1, 0, 2) - wu * _EYE2[:, :, None]) / l2
    return u, J, contracted


#: the 12 local coordinates of each point a, b, p, c, d, q
_COLS = [slice(2 * i, 2 * i + 2) for i in range(6)]


class PolylineGeometry:
    """The intermediates y = (L, g_a, g_b, ζ_lo, ζ_hi) of a batch of K polyline pairs: values
    ``val`` (5, K) and gradients ``Y`` (5, 12, K) over the local coordinates [a, b, p, c, d,
    q], batch last (contiguous rows: the arithmetic runs on whole (K,) rows); with
    ``second`` what the Hessians of functions of y need (:meth:`_hessian`). ``has_p`` /
    ``has_q``: whether the master segment has a neighbour before / after (else the reflected
    ghost: the segment's own tangent at that end); the bounds' values ``lo``, ``hi`` and which
    shadow end they are (``mix``, :func:`clamp`) come from the float pass."""

    def __init__(self, X, has_p, has_q, lo, hi, mix, second: bool):
        K = X.shape[0]
        P = np.ascontiguousarray(X.T).reshape(6, 2, K)          # points, (x, y), pairs
        a, b, p, c, d, q = P
        e = b - a
        L = np.sqrt(e[0] * e[0] + e[1] * e[1])
        ue = e / L
        m = d - c
        l2 = m[0] * m[0] + m[1] * m[1]
        ln = np.sqrt(l2)
        n = np.stack([-m[1], m[0]]) / ln
        val = np.empty((5, K))
        Y = np.zeros((5, 12, K))
        val[0], val[3], val[4] = L, lo, hi
        Y[0, _COLS[_PA]], Y[0, _COLS[_PB]] = -ue, ue
        terms = []                      # (pattern key, (2, 2, K) block, intermediate slot)
        if second:
            terms.append((("C", "ab", "ab"), (_EYE2[:, :, None] - ue[:, None] * ue[None, :])
                          / L, 0))
        # gaps of the slave end points from the master's line: h = r·n, r = x_s − x_c
        for slot, pt, key in ((1, _PA, "ra"), (2, _PB, "rb")):
            r = P[pt] - c
            h = r[0] * n[0] + r[1] * n[1]
            Rr = np.stack([-r[1], r[0]])
            h_m = -Rr / ln - h * m / l2
            val[slot] = h
            Y[slot, _COLS[pt]] = n
            Y[slot, _COLS[_PC]] = -n - h_m
            Y[slot, _COLS[_PD]] = h_m
            if second:
                mm = m[:, None] * m[None, :]
                Rm = Rr[:, None] * m[None, :]
                terms.append((("S", key, "cd"), _ROT[:, :, None] / ln
                              - n[:, None] * m[None, :] / l2, slot))
                terms.append((("C", "cd", "cd"), (Rm + Rm.transpose(1, 0, 2)) / (l2 * ln)
                              - (h / l2) * _EYE2[:, :, None] + (3.0 * h / (l2 * l2)) * mm,
                              slot))
        # the shadow's ends ζ = ((x_n − x_a)·t)/((x_b − x_a)·t), t the averaged tangent at
        # the master node x_n (c or d): t_c = unit(x_c − x_p) + unit(x_d − x_c), t_d =
        # unit(x_d − x_c) + unit(x_q − x_d), the segment's own unit tangent for a ghost
        u0, J0, H0 = _unit_derivatives(m[0], m[1], second)
        self.ends = []
        for pt, real, v_real, key, far in ((_PC, has_p, c - p, "pc", _PP),
                                           (_PD, has_q, q - d, "dq", _PQ)):
            v1 = np.where(real, v_real, m)
            u1, J1, H1 = _unit_derivatives(v1[0], v1[1], second)
            t = u0 + u1
            # Dt (2, 12, K): u0 over (c, d); u1 over (p, c) or (d, q), or (c, d) for a ghost
            Dt = np.zeros((2, 12, K))
            J1r, J1g = J1 * real, J1 * ~real
            Dt[:, _COLS[_PC]] = -J0 - J1g
            Dt[:, _COLS[_PD]] = J0 + J1g
            lo_pt, hi_pt = (_PP, _PC) if pt == _PC else (_PD, _PQ)
            Dt[:, _COLS[lo_pt]] -= J1r
            Dt[:, _COLS[hi_pt]] += J1r
            u = P[pt] - a
            s = e[0] * t[0] + e[1] * t[1]
            z = (u[0] * t[0] + u[1] * t[1]) / s
            w = u - z * e
            # ∇ζ = ((∂u − ζ ∂e)ᵀ t + Dtᵀ w)/s, ∂u − ζ ∂e = S_n + (ζ − 1) S_a − ζ S_b
            gz = w[0] * Dt[0] + w[1] * Dt[1]
            gz[_COLS[pt]] += t
            gz[_COLS[_PA]] += (z - 1.0) * t
            gz[_COLS[_PB]] -= z * t
            gz /= s
            end = dict(grad=gz)
            if second:
                ds = e[0] * Dt[0] + e[1] * Dt[1]
                ds[_COLS[_PA]] -= t
                ds[_COLS[_PB]] += t
                end.update(s=s, z=z, w=w, J0=J0, J1=J1, H0=H0, H1=H1, real=real, key=key,
                           pt=pt, ds=ds)
            self.ends.append(end)
        (lc, ld), (hc, hd) = mix
        self.mix = ((lc * 1.0, ld * 1.0), (hc * 1.0, hd * 1.0))
        gc, gd = self.ends[0]["grad"], self.ends[1]["grad"]
        for slot, (fc, fd) in zip((3, 4), self.mix):
            Y[slot] = fc * gc + fd * gd
        self.val, self.Y, self.terms = val, Y, terms

    def outputs(self):
        """Values (4, K) and gradients (4, K, 12) of g̃_a, g̃_b, A_a, A_b (standard basis)."""
        L, ga, gb, lo, hi = self.val
        I0, I1, I2 = hi - lo, 0.5 * (hi * hi - lo * lo), (hi ** 3 - lo ** 3) / 3.0
        al, be, gm = I0 - 2.0 * I1 + I2, I1 - I2, I2
        one_l, one_h = 1.0 - lo, 1.0 - hi
        # ∂/∂(L, g_a, g_b, lo, hi) of the four outputs (None: zero)
        F = [[ga * al + gb * be, L * al, L * be, -L * (ga * one_l * one_l + gb * lo * one_l),
              L * (ga * one_h * one_h + gb * hi * one_h)],
             [ga * be + gb * gm, L * be, L * gm, -L * (ga * lo * one_l + gb * lo * lo),
              L * (ga * hi * one_h + gb * hi * hi)],
             [I0 - I1, None, None, -L * one_l, L * one_h],
             [I1, None, None, -L * lo, L * hi]]
        vals = np.stack([L * (ga * al + gb * be), L * (ga * be + gb * gm), L * (I0 - I1),
                         L * I1])
        grads = np.zeros((4, 12, L.shape[0]))
        for o, row in enumerate(F):
            for j, f in enumerate(row):
                if f is not None:
                    grads[o] += f * self.Y[j]
        return vals, grads.transpose(0, 2, 1)

    def _hessian(self, Wy, Wyy: dict) -> np.ndarray:
        """(K, 12, 12): the Hessian Σ_i W_i H(y_i) + Σ_ij W_ij ∇y_i ⊗ ∇y_j of a function W(y)
        with gradient ``Wy`` (5, K) and Hessian ``Wyy`` over the intermediates ({(i, j):
        (K,)} for i ≤ j, the nonzero entries)."""
        K = Wy.shape[1]
        coef = np.zeros((_PATTERNS.shape[0], K))

        def add(key, h, scale):
            col = _COLUMN[key]
            coef[col:col + 4] += (h * scale).reshape(4, K)

        for key, h, slot in self.terms:
            add(key, h, Wy[slot])
        # H(ζ) = [sym((∂u − ζ ∂e)ᵀ Dt) + Σ_i w_i H(t_i) − sym(∇s ⊗ ∇ζ)]/s, weighted by
        # σ = (W_lo f_lo + W_hi f_hi)/s; the last term joins the outer products
        V = list(self.Y)
        pairs = dict(Wyy)
        for k, end in enumerate(self.ends):
            sigma = (Wy[3] * self.mix[0][k] + Wy[4] * self.mix[1][k]) / end["s"]
            z, real = end["z"], end["real"]
            for pt, beta in ((end["pt"], 1.0), (_PA, z - 1.0), (_PB, -z)):
                sb = sigma * beta
                add(("S", pt, "cd"), end["J0"], sb)
                add(("S", pt, end["key"]), end["J1"], sb * real)
                add(("S", pt, "cd"), end["J1"], sb * ~real)
            add(("C", "cd", "cd"), end["H0"](end["w"]), sigma)
            W1 = end["H1"](end["w"])
            add(("C", end["key"], end["key"]), W1, sigma * real)
            add(("C", "cd", "cd"), W1, sigma * ~real)
            V += [end["ds"], end["grad"]]
            pairs[(5 + 2 * k, 6 + 2 * k)] = -sigma
        # Σ_ij W_ij V_i ⊗ V_j = Σ_i V_i ⊗ Z_i, Z_i = Σ_j W_ij V_j (W symmetric)
        Z = [None] * len(V)
        for (i, j), wij in pairs.items():
            for r, c in ((i, j), (j, i)) if i != j else ((i, j),):
                Z[r] = wij * V[c] if Z[r] is None else Z[r] + wij * V[c]
        H = (_PATTERNS.T @ coef).reshape(12, 12, K)
        for Vi, Zi in zip(V, Z):
            if Zi is not None:
                H += Vi[:, None] * Zi[None, :]
        return H.transpose(2, 0, 1)

    def weighted_hessian(self, wa: np.ndarray, wb: np.ndarray) -> np.ndarray:
        """(K, 12, 12): the Hessian of wa g̃_a + wb g̃_b (standard basis)."""
        L, ga, gb, lo, hi = self.val
        I0, I1, I2 = hi - lo, 0.5 * (hi * hi - lo * lo), (hi ** 3 - lo ** 3) / 3.0
        al, be, gm = I0 - 2.0 * I1 + I2, I1 - I2, I2
        one_l, one_h = 1.0 - lo, 1.0 - hi
        P, Q = wa * al + wb * be, wa * be + wb * gm
        P_l = -(wa * one_l * one_l + wb * lo * one_l)
        P_h = wa * one_h * one_h + wb * hi * one_h
        Q_l = -(wa * lo * one_l + wb * lo * lo)
        Q_h = wa * hi * one_h + wb * hi * hi
        P_ll = 2.0 * wa * one_l - wb * (1.0 - 2.0 * lo)
        P_hh = -2.0 * wa * one_h + wb * (1.0 - 2.0 * hi)
        Q_ll = -wa * (1.0 - 2.0 * lo) - 2.0 * wb * lo
        Q_hh = wa * (1.0 - 2.0 * hi) + 2.0 * wb * hi
        Wy = np.stack([ga * P + gb * Q, L * P, L * Q, L * (ga * P_l + gb * Q_l),
                       L * (ga * P_h + gb * Q_h)])
        Wyy = {(0, 1): P, (0, 2): Q, (0, 3): ga * P_l + gb * Q_l, (0, 4): ga * P_h + gb * Q_h,
               (1, 3): L * P_l, (1, 4): L * P_h, (2, 3): L * Q_l, (2, 4): L * Q_h,
               (3, 3): L * (ga * P_ll + gb * Q_ll), (4, 4): L * (ga * P_hh + gb * Q_hh)}
        return self._hessian(Wy, Wyy)

    def area_hessian(self, wa: np.ndarray, wb: np.ndarray) -> np.ndarray:
        """(K, 12, 12): the Hessian of wa A_a + wb A_b, A_a = L (I0 − I1), A_b = L I1."""
        L, _, _, lo, hi = self.val
        I0, I1 = hi - lo, 0.5 * (hi * hi - lo * lo)
        p_l, p_h = -wa * (1.0 - lo) - wb * lo, wa * (1.0 - hi) + wb * hi
        z = np.zeros_like(L)
        Wy = np.stack([wa * (I0 - I1) + wb * I1, z, z, L * p_l, L * p_h])
        Wyy = {(0, 3): p_l, (0, 4): p_h, (3, 3): L * (wa - wb), (4, 4): L * (wb - wa)}
        return self._hessian(Wy, Wyy)


class PolylineDeferred:
    """Hessians of the polyline pairs' weighted gaps (standard basis; ``kind`` 0) or nodal
    areas (1) on demand, as :class:`.mortar._Deferred` gives them: the intermediates formed again
    with second derivatives for just the pairs asked for, in blocks of ``block``."""

    def __init__(self, X, has_p, has_q, ends: Ends, block: int, kind: int = 0):
        self.X, self.has_p, self.has_q, self.ends = X, has_p, has_q, ends
        self.K, self.block, self.kind = X.shape[0], block, kind

    def _geometry(self, idx):
        e = self.ends.subset(idx)
        return PolylineGeometry(self.X[idx], self.has_p[idx], self.has_q[idx], e.lo, e.hi,
                                 e.mix, True)

    def __call__(self) -> np.ndarray:
        one, zero = np.ones(self.K), np.zeros(self.K)
        return np.concatenate([self.weighted(one, zero, slice(None)),
                               self.weighted(zero, one, slice(None))])

    def weighted(self, wa: np.ndarray, wb: np.ndarray, pairs) -> np.ndarray:
        """wa H_a + wb H_b of the pairs (index array or slice into [0, K))."""
        idx = np.arange(self.K)[pairs]
        out = np.empty((idx.shape[0], 12, 12))
        for b0 in range(0, idx.shape[0], self.block):
            sel = slice(b0, min(b0 + self.block, idx.shape[0]))
            geo = self._geometry(idx[sel])
            out[sel] = (geo.weighted_hessian(wa[sel], wb[sel]) if self.kind == 0
                        else geo.area_hessian(wa[sel], wb[sel]))
        return out
