"""The C0 polyline through the master nodes ("none")."""
from __future__ import annotations



from .. import ad
from ..registry import SMOOTHINGS
from .base import _NeighbourStencil


@SMOOTHINGS.register("none")
class Polyline(_NeighbourStencil):
    """The C0 polyline: x(ξ) = (1−ξ) x_c + ξ x_d, a = x_d − x_c on segment (c, d).

    The segmentation uses the averaged nodal tangent (docs/design.md eq. 3.4)
        t̄_c = t_{prev(c),c} + t_{c,d}   (unit segment tangents; only the direction matters),
    hence the stencil (prev(c), c, d, next(d)).
    """

    gauss_points = 2

    def derivatives(self, seg_index, xi, P, order):
        c, d = P[1], P[2]
        a = ad.sub(d, c)
        out = [ad.add(c, ad.scale(a, xi)), a, (0.0, 0.0)]
        return out[:order + 1]

    def _coefficients(self, seg_index, P):
        return [P[1], ad.sub(P[2], P[1])]

    def node_tangents(self, seg_index, P):
        return self.averaged_tangents(seg_index, P)

    def project(self, seg_index, xs, P):
        # closest point on the segment's line, closed form; not clamped (the mortar
        # segmentation / NTS selection decide which segment is responsible)
        c, d = P[1], P[2]
        a = ad.sub(d, c)
        return ad.dot(ad.sub(xs, c), a) * ad.reciprocal(ad.dot(a, a))

    def gap(self, seg_index, xs, P):
        # on a straight segment (x_s − x_m(ξ))·n = (x_s − x_c)·n for every ξ (a ⊥ n): the
        # gap needs no projection, only M needs ξ̄ (values)
        c, d = P[1], P[2]
        a = ad.sub(d, c)
        g = ad.dot(ad.sub(xs, c), self.normal(a))
        xs_v = (ad.value(xs[0]), ad.value(xs[1]))
        cv, av = (ad.value(c[0]), ad.value(c[1])), (ad.value(a[0]), ad.value(a[1]))
        return g, ad.dot(ad.sub(xs_v, cv), av) / ad.dot(av, av)


