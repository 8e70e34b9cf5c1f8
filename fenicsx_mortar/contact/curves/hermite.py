"""C1 cubic Hermite segments with averaged nodal tangents (eqs. 3.6–3.13)."""
from __future__ import annotations



from .. import ad
from ..registry import SMOOTHINGS
from .base import _NeighbourStencil, _horner_derivatives


@SMOOTHINGS.register("hermite")
class Hermite(_NeighbourStencil):
    """C1 cubic Hermite segments with averaged nodal tangents (docs/design.md §6.4, eqs.
    3.6–3.13): on segment (c, d) of length l,
        x̂(ξ) = H₁ x_c + H₂ x_d + H₃ l ā_c + H₄ l ā_d,
        H₁ = 1 − 3ξ² + 2ξ³, H₂ = 3ξ² − 2ξ³, H₃ = ξ − 2ξ² + ξ³, H₄ = −ξ² + ξ³,
    ā the unit averaged tangents of eq. 3.4. At an open chain's end, ā is the tangent of
    the circle through the end node and its next two (:func:`_circle_ghost`): with the
    segment's own tangent there, the end segment's gap error was O(h²) against O(h⁴) inside
    (a quarter-circle arc of 8 … 64 segments: 250 … 15 700 × the interior error).
    x̂′(0) = l ā_c, x̂′(1) = l ā_d: the unit tangent is continuous at the nodes and, in the
    chord-length parameter s = l ξ, so is dx̂/ds = ā (C1). Projection: closest point
    (quintic in ξ), safeguarded Newton (:mod:`.projection`).
    """

    c1_gap = True
    hat_test = True
    circle_ends = True

    def derivatives(self, seg_index, xi, P, order):
        return _horner_derivatives(self._coefficients(seg_index, P), xi, order)

    _memo = None

    def _coefficients(self, seg_index, P):
        # the kernels evaluate one batch's curve several times (the projection's chord
        # steps, the point, the normal): the last coefficients are kept; the memo holds
        # its arguments, so their ids are not reused while it exists
        key = (id(seg_index), ad.second_order()) + tuple(id(v) for p in P for v in p)
        if self._memo is not None and self._memo[0] == key:
            return self._memo[2]
        C = self._hermite_coefficients(seg_index, P)
        self._memo = (key, (seg_index, P), C)
        return C

    def _hermite_coefficients(self, seg_index, P):
        # power form x̂ = x_c + ξ T_c + ξ² (3e − 2T_c − T_d) + ξ³ (−2e + T_c + T_d)
        c, d = P[1], P[2]
        ta, tb = self.averaged_tangents(seg_index, P)
        e = ad.sub(d, c)
        l = ad.norm(e)
        Tc, Td = ad.scale(ad.unit(ta), l), ad.scale(ad.unit(tb), l)
        C2 = ad.sub(ad.sub(ad.scale(e, 3.0), ad.scale(Tc, 2.0)), Td)
        C3 = ad.add(ad.add(ad.scale(e, -2.0), Tc), Td)
        return [c, Tc, C2, C3]

    def node_tangents(self, seg_index, P):
        return self.averaged_tangents(seg_index, P)


# ---------------------------------------------------------------------- B-spline
