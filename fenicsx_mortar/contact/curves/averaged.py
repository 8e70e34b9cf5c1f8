"""The polyline with nodal averaged normals (eqs. 3.2–3.4), three averages."""
from __future__ import annotations

from typing import Tuple

import numpy as np

from .. import ad
from ..ad import Vec2
from ..registry import SMOOTHINGS
from .base import _NeighbourStencil, _stack_coefficients
from .polyline import Polyline


def _normal_simple(p, c, d):
    """eq. 3.2: n̄ = (n_{i−1} + n_i)/|n_{i−1} + n_i| (unit segment normals)."""
    return ad.unit(ad.add(ad.unit(ad.perp(ad.sub(c, p))), ad.unit(ad.perp(ad.sub(d, c)))))


def _normal_weighted(p, c, d):
    """eq. 3.3: n̄ ∝ l_{i−1} n_{i−1} + l_i n_i = e3 × ((x_c − x_p) + (x_d − x_c))."""
    return ad.unit(ad.add(ad.perp(ad.sub(c, p)), ad.perp(ad.sub(d, c))))


def _normal_tangent(p, c, d):
    """eq. 3.4: ā = (t_{i−1} + t_i)/|t_{i−1} + t_i|, n̄ = e3 × ā."""
    return ad.perp(ad.unit(ad.add(ad.unit(ad.sub(c, p)), ad.unit(ad.sub(d, c)))))


class AveragedNormals(_NeighbourStencil):
    """Polyline geometry with averaged nodal normals (docs/design.md §6.1–3, eqs. 3.2–3.4).

    Nodal normal n̄ by ``variant``: "simple" (eq. 3.2, mean of the unit normals),
    "weighted" (eq. 3.3, weighted by segment length) or "tangent" (eq. 3.4, normal of the
    mean unit tangent, the paper's choice). In 2D "simple" and "tangent" coincide (the
    unit normals are the unit tangents turned by 90°); on a polygon inscribed in a circle
    with arcs Δ_{i−1}, Δ_i at node i their normal deviates from the circle's by
    (Δ_i − Δ_{i−1})/4, the weighted one by (Δ_i − Δ_{i−1})/2 (both exact on a regular
    polygon).

    Inside the segment the normal is interpolated and renormalized (a C0 normal field):
        n̂(ξ) = m(ξ)/|m(ξ)|,   m(ξ) = (1−ξ) n̄_c + ξ n̄_d;
    the gap is measured along it (docs/design.md §3): x_s − x(ξ̄) ∥ n̂(ξ̄), i.e.
        F(ξ) = (x_s − x(ξ)) × m(ξ) = 0   (quadratic in ξ),   g = (x_s − x(ξ̄))·n̂(ξ̄).
    A point on the line through x_c along n̄_c projects onto ξ = 0 of both adjacent
    segments: the gap is continuous across nodes (no blind wedge).
    """

    VARIANTS = {"simple": _normal_simple, "weighted": _normal_weighted,
                "tangent": _normal_tangent}
    variant = "tangent"

    def __init__(self, x, seg, variant: str | None = None):
        variant = variant or self.variant
        if variant not in self.VARIANTS:
            raise ValueError(f"unknown averaged-normal variant {variant!r}; expected one of "
                             f"{sorted(self.VARIANTS)}")
        super().__init__(x, seg)
        self.variant = variant
        self._node_normal = self.VARIANTS[variant]

    def with_nodes(self, x):
        return type(self)(x, self.seg, self.variant)

    def node_normals(self, seg_index, P) -> Tuple[Vec2, Vec2]:
        """Unit averaged normals n̄_c, n̄_d of the variant."""
        p, c, d, q = self._ghosted(seg_index, P)
        return self._node_normal(p, c, d), self._node_normal(c, d, q)

    def node_tangents(self, seg_index, P):
        # the direction a with e3 × a = n̄: a = (n̄_y, −n̄_x)
        nc, nd = self.node_normals(seg_index, P)
        return (nc[1], -nc[0]), (nd[1], -nd[0])

    def _node_tangent(self, prev, node, nxt):
        n = self._node_normal(prev, node, nxt)
        return (n[1], -n[0])

    def derivatives(self, seg_index, xi, P, order):
        return Polyline.derivatives(self, seg_index, xi, P, order)

    def normal_at(self, seg_index, xi, P, a=None):
        nc, nd = self.node_normals(seg_index, P)
        return ad.unit(ad.add(nc, ad.scale(ad.sub(nd, nc), xi)))

    def condition_polynomial(self, seg_index, xs, P):
        # F = (r₀ + r₁ξ) × (m₀ + m₁ξ), r₀ = x_s − x_c, r₁ = −(x_d − x_c), m₀ = n̄_c, m₁ = n̄_d − n̄_c
        c, d = P[1], P[2]
        m0, nd = self.node_normals(seg_index, P)
        r0, r1, m1 = ad.sub(xs, c), ad.sub(c, d), ad.sub(nd, m0)
        F = [ad.cross(r0, m0), ad.cross(r0, m1) + ad.cross(r1, m0), ad.cross(r1, m1)]
        return np.empty((0,)), _stack_coefficients(F)[None]

    def condition(self, seg_index, xi, xs, P, derivative=False):
        c, d = P[1], P[2]
        nc, nd = self.node_normals(seg_index, P)
        a, dn = ad.sub(d, c), ad.sub(nd, nc)
        r = ad.sub(xs, ad.add(c, ad.scale(a, xi)))
        m = ad.add(nc, ad.scale(dn, xi))
        F = ad.cross(r, m)
        if not derivative:
            return F
        return F, ad.cross(r, dn) - ad.cross(a, m)


@SMOOTHINGS.register("averaged-simple")
class AveragedSimple(AveragedNormals):
    """Averaged normals, eq. 3.2."""
    variant = "simple"


@SMOOTHINGS.register("averaged-weighted")
class AveragedWeighted(AveragedNormals):
    """Averaged normals weighted by segment length, eq. 3.3."""
    variant = "weighted"


@SMOOTHINGS.register("averaged-tangent")
class AveragedTangent(AveragedNormals):
    """Normal of the averaged tangent, eq. 3.4."""
    variant = "tangent"


