"""Master curve geometry (docs/design.md §3, §6): the C0 polyline and the smoothed master
surfaces of the paper's Section 3.

A :class:`MasterCurve` maps (master segment i, ξ ∈ [0, 1]) to a point x(ξ) and its
ξ-derivatives. On segment i the curve depends on the coordinates of a fixed number L of
*curve points*, its *stencil*; all geometric methods take these local coordinates ``P`` as
a sequence of L points, each a 2-tuple of :class:`~.ad.Jet2` or of float arrays, so one
code path gives plain values (search, segmentation pre-pass, Newton iterations) and exact
derivatives (kernels).

Curve points and master nodes (``point_map``):
* local curves (polyline, averaged normals, Hermite): the points ARE the master nodes,
  ``point_map is None``;
* the global B-spline: the points are its control points, P = ``point_map`` @ X for both
  coordinate columns, X (n_nodes, 2) the master node coordinates; ``point_map`` is a
  scipy.sparse (n_points, n_nodes) matrix, constant for a frozen parametrization (see
  :class:`BSpline`).
``stencil``/``local_points`` index points, so the kernels' ``master_nodes`` index points;
the derivatives with respect to the nodes follow by the chain rule with ``point_map``
(∂q/∂X = point_mapᵀ ∂q/∂P, per coordinate).

Batch convention: ``seg_index`` is an integer array that broadcasts (numpy rules) against
the batch shape of ``P``/``xi``/``xs``: shape (k,) for a batch (k,) of segments, (1, k)
for the mortar Gauss batch (n_gauss, k) where ``P`` has batch (k,).

Implementations (:func:`make_curve` picks one by the scene's ``smoothing`` name):
* :class:`Polyline` — C0, today's behaviour ("none");
* :class:`AveragedNormals` — polyline with nodal averaged normals, eqs. 3.2–3.4;
* :class:`Hermite` — C1 cubic Hermite segments with averaged nodal tangents, eqs. 3.6–3.13;
* :class:`BSpline` — one global C2 cubic B-spline interpolating the nodes, eqs. 3.16–3.33.
Projection onto all of them: :mod:`.projection`.
"""
from __future__ import annotations

import abc
from typing import Sequence, Tuple

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from . import ad, projection
from .ad import Scalar, Vec2
from .kernel import chain_links
from .registry import SMOOTHINGS


class MasterCurve(abc.ABC):
    """Geometry of the master surface: a map (segment i, ξ∈[0,1]) -> point, built from the
    chain nodes."""

    #: number of curve points the curve on one segment depends on
    stencil_size: int
    #: the point gap is C1 across master nodes (closest point on a C1 curve: no blind
    #: wedge, no kink; NTS measures along the node normal only beyond an open chain's
    #: end). Not so for the polyline (normal jumps) nor the averaged normals: their normal
    #: is continuous but the chords are not perpendicular to it at a node, so the gap's
    #: tangential derivative jumps there — NTS then measures along n̄ near a node.
    c1_gap: bool = False
    #: sparse (n_points, n_nodes) map from node to curve-point coordinates; None: identity
    point_map = None
    #: the mortar kernel tests the contact traction on the master with the master's own
    #: linear shape functions N̂ (c, d) instead of the variation of the curve (see
    #: :mod:`.mortar`, "Master-side test functions"): set where the curve between two
    #: nodes depends on more than those two nodes
    hat_test: bool = False
    #: default Gauss points per mortar segment. The polyline's integrand N_j g is quadratic
    #: (2 points: exact). On the smoothed curves it is not; then the derivative of the Gauss
    #: sum with respect to a mortar segment's end is not the integrand there, and g̃_j gets a
    #: slope jump where a slave node passes a master node's segmentation line: measured
    #: 7e-6 (2 points), 1e-8 (3), below 1e-10 (4) on a curved test arc — at 2 points Newton
    #: stalls at a residual ~5e-5 (stability case 3); :mod:`.mortar` step 2
    gauss_points: int = 4

    def __init__(self, x: np.ndarray, seg: np.ndarray):
        self.x = np.asarray(x, dtype=float)
        self.seg = np.asarray(seg, dtype=np.int64).reshape(-1, 2)
        self._before, self._after = chain_links(self.seg, self.x.shape[0])
        #: neighbouring segments along the chain (−1 at the ends of an open chain)
        self.prev_seg = self._before[self.seg[:, 0]]
        self.next_seg = self._after[self.seg[:, 1]]

    def with_nodes(self, x: np.ndarray) -> "MasterCurve":
        """The same kind of curve on the same chain with new node coordinates (a frozen
        parametrization, where the curve has one, is kept)."""
        return type(self)(x, self.seg)

    def node_segments(self) -> Tuple[np.ndarray, np.ndarray]:
        """Per node, the segment ending at it and the one starting at it (−1: none)."""
        return self._before, self._after

    # ------------------------------------------------------------------ topology
    @abc.abstractmethod
    def stencil(self, seg_index: np.ndarray) -> np.ndarray:
        """(k, L) curve-point indices the curve on these segments depends on."""

    def points(self, x: np.ndarray | None = None) -> np.ndarray:
        """(n_points, 2) curve-point coordinates from node coordinates ``x`` (default: the
        curve's own nodes)."""
        x = self.x if x is None else np.asarray(x, dtype=float)
        return x if self.point_map is None else self.point_map @ x

    def local_points(self, seg_index: np.ndarray, x: np.ndarray | None = None) -> np.ndarray:
        """(k, L, 2) coordinates of the stencil points (from node coordinates ``x`` or the
        curve's own nodes)."""
        return self.points(x)[self.stencil(np.asarray(seg_index))]

    @staticmethod
    def split_points(P: np.ndarray) -> list:
        """(k, L, 2) float array -> list of L points (x, y) of (k,) arrays."""
        return [(P[:, i, 0], P[:, i, 1]) for i in range(P.shape[1])]

    # ------------------------------------------------------------------ geometry
    @abc.abstractmethod
    def derivatives(self, seg_index, xi: Scalar, P: Sequence[Vec2], order: int) -> list:
        """[x(ξ), x′(ξ), …, x^(order)(ξ)] on the segments, derivatives with respect to ξ
        (order ≤ 2); beyond [0, 1] the segment's curve piece is extended."""

    def evaluate(self, seg_index, xi: Scalar, P: Sequence[Vec2]) -> Tuple[Vec2, Vec2]:
        """Point x(ξ) and tangent a(ξ) = dx/dξ on the segments."""
        x, a = self.derivatives(seg_index, xi, P, 1)
        return x, a

    @abc.abstractmethod
    def node_points(self, seg_index, P: Sequence[Vec2]) -> Tuple[Vec2, Vec2]:
        """The segment's start and end nodes x(0), x(1)."""

    @abc.abstractmethod
    def node_tangents(self, seg_index, P: Sequence[Vec2]) -> Tuple[Vec2, Vec2]:
        """Tangent *directions* (any positive length) at the segment's start and end node,
        used by the mortar segmentation: the master segment's shadow on the slave ends on
        the lines through the end nodes perpendicular to these. For the smoothed curves
        these are the directions whose normal is the curve's normal at the node, so that
        a point on such a line projects onto the node."""

    def end_frame(self, seg_index, P: Sequence[Vec2], at_d) -> Tuple[Vec2, Vec2]:
        """The node point and tangent direction of :meth:`node_points` and
        :meth:`node_tangents` at one end per entry: the start node where ``at_d`` (boolean
        array over the batch) is False, the end node where True (the same values; curves
        override this to evaluate just that end)."""
        xc, xd = self.node_points(seg_index, P)
        tc, td = self.node_tangents(seg_index, P)
        return _pick(at_d, xc, xd), _pick(at_d, tc, td)

    def normal(self, a: Vec2) -> Vec2:
        """Outward unit normal n = e3 × a/|a| (docs/design.md §3)."""
        return ad.unit(ad.perp(a))

    def normal_at(self, seg_index, xi: Scalar, P: Sequence[Vec2], a: Vec2 | None = None) -> Vec2:
        """Unit normal of the gap field at ξ: the curve normal (closest-point curves);
        ``a`` = x′(ξ) if already known."""
        return self.normal(self.derivatives(seg_index, xi, P, 1)[1] if a is None else a)

    def condition(self, seg_index, xi, xs: Vec2, P: Sequence[Vec2], derivative: bool = False):
        """Projection condition F(ξ), decreasing through the root (and F′ with
        ``derivative``): closest point, F = (x_s − x)·x′, F′ = −|x′|² + (x_s − x)·x″."""
        if not derivative:
            x, a = self.derivatives(seg_index, xi, P, 1)
            return ad.dot(ad.sub(xs, x), a)
        x, a, b = self.derivatives(seg_index, xi, P, 2)
        r = ad.sub(xs, x)
        return ad.dot(r, a), ad.dot(r, b) - ad.dot(a, a)

    def pieces(self, seg_index, P: Sequence[Vec2]) -> Tuple[np.ndarray, list]:
        """Power form of x(ξ) on the segments from values ``P``: ``(breaks, [C, …])`` with one
        coefficient list C = [C_0, C_1, …] (x = Σ_r C_r ξ^r, each C_r a Vec2) per piece of
        the segment's curve; piece q holds for breaks[q−1] ≤ ξ < breaks[q] (``breaks``
        (n_pieces − 1, *B), +inf padded; the first and last pieces extend beyond)."""
        return np.empty((0,)), [self._coefficients(seg_index, P)]

    def _coefficients(self, seg_index, P: Sequence[Vec2]) -> list:
        """[C_0, …, C_deg] of a one-piece curve (jets or values)."""
        raise NotImplementedError(f"{type(self).__name__} has no power form")

    def condition_polynomial(self, seg_index, xs: Vec2, P: Sequence[Vec2]):
        """Power coefficients of :meth:`condition` F(ξ) per piece from values ``xs``,
        ``P``: ``(breaks, Fc)``, Fc (n_pieces, degree + 1, *B) — the Newton iterations of
        :func:`.projection.solve_on_segments` evaluate F and F′ from these instead of the
        curve. Closest point: F = (x_s − x)·x′ = Σ_k (x_s·D_k) ξ^k − Σ_{i,j} (C_i·D_j) ξ^{i+j},
        D_j = (j+1) C_{j+1} the coefficients of x′."""
        breaks, pieces = self.pieces(seg_index, P)
        return breaks, np.stack([_stack_coefficients(_closest_point_poly(C, xs))
                                 for C in pieces])

    def project(self, seg_index, xs: Vec2, P: Sequence[Vec2]) -> Scalar:
        """ξ̄ of the projection of xs onto the segment's curve (unclamped; −1 or 2 when the
        root lies beyond the search window): safeguarded Newton, jets exact to second
        order (:func:`.projection.project`)."""
        return projection.project(self, seg_index, xs, P)

    def gap(self, seg_index, xs: Vec2, P: Sequence[Vec2]) -> Tuple[Scalar, Scalar]:
        """Normal gap g = (xs − x(ξ̄))·n(ξ̄) at the projection ξ̄ = :meth:`project`, and ξ̄.

        Subclasses may shortcut this (the polyline does); the returned ξ̄ may then be
        values only — it is used for the mortar matrix M, not differentiated.
        """
        g, xi, _ = self.gap_frame(seg_index, xs, P)
        return g, xi

    def gap_frame(self, seg_index, xs: Vec2, P: Sequence[Vec2]) -> Tuple[Scalar, Scalar, Vec2]:
        """(g, ξ̄, n(ξ̄)): the gap of :meth:`gap` with its projection and the unit normal,
        all differentiable."""
        xi = self.project(seg_index, xs, P)
        x_m, a_m = self.derivatives(seg_index, xi, P, 1)
        n = self.normal_at(seg_index, xi, P, a_m)
        return ad.dot(ad.sub(xs, x_m), n), xi, n


def _pick(at_d, u: Vec2, v: Vec2) -> Vec2:
    """u where ``at_d`` is False, v where True (per batch entry)."""
    return ad.where(at_d, v[0], u[0]), ad.where(at_d, v[1], u[1])


def _closest_point_poly(C: Sequence[Vec2], xs: Vec2) -> list:
    """Power coefficients of F = (x_s − x)·x′ for x = Σ_r C_r ξ^r (values)."""
    n = len(C)
    D = [((r + 1) * C[r + 1][0], (r + 1) * C[r + 1][1]) for r in range(n - 1)]
    F = [xs[0] * D[k][0] + xs[1] * D[k][1] for k in range(n - 1)] + [0.0] * (n - 1)
    for i in range(n):
        for j in range(n - 1):
            F[i + j] = F[i + j] - (C[i][0] * D[j][0] + C[i][1] * D[j][1])
    return F


def _stack_coefficients(F: list) -> np.ndarray:
    """(degree + 1, *B) array of scalar coefficients that broadcast to a common batch."""
    return np.stack(np.broadcast_arrays(*[np.asarray(f, dtype=float) for f in F]))


def _horner_derivatives(C: Sequence[Vec2], xi, order: int) -> list:
    """[x, x′, …, x^(order)] of the cubic x(ξ) = Σ_r C_r ξ^r (vector coefficients C_r)."""
    out = []
    for k in range(order + 1):
        # d^k/dξ^k: Σ_{r≥k} r!/(r−k)! C_r ξ^{r−k}, evaluated by Horner from the top
        fall = [1.0, 1.0, 2.0, 6.0]
        v = ad.scale(C[3], fall[3] / fall[3 - k])
        for r in range(2, k - 1, -1):
            v = ad.add(ad.scale(v, xi), ad.scale(C[r], fall[r] / fall[r - k]))
        out.append(v)
    return out


# ---------------------------------------------------------------------- local curves
class _NeighbourStencil(MasterCurve):
    """Curves whose segment (c, d) depends on (prev(c), c, d, next(d)) — the averaged
    nodal quantities at c and d need the neighbouring segments.

    At the ends of an open chain prev(c) = c (or next(d) = d) is stored in the stencil and
    the missing neighbour is replaced by the ghost node 2x_c − x_d (reflection), whose
    segment tangent equals t_{c,d} *as a function of the coordinates*, so every averaged
    quantity reduces to the segment's own, the derivatives are right and the repeated slot
    gets zero derivative.
    """

    stencil_size = 4
    #: ghost nodes at an open chain's ends: the reflection (the end segment's own tangent
    #: at the end node), or the circle through the end node and its next two (the end
    #: tangent of that circle: the curve keeps its order up to the end, :func:`_circle_ghost`)
    circle_ends = False

    def stencil(self, seg_index: np.ndarray) -> np.ndarray:
        seg_index = np.asarray(seg_index, dtype=np.int64)
        c, d = self.seg[seg_index, 0], self.seg[seg_index, 1]
        ps, ns = self.prev_seg[seg_index], self.next_seg[seg_index]
        p = np.where(ps >= 0, self.seg[ps, 0], c)
        q = np.where(ns >= 0, self.seg[ns, 1], d)
        return np.stack([p, c, d, q], axis=1)

    def _ghosted(self, seg_index, P):
        """(p, c, d, q) with reflected ghosts for missing neighbours."""
        p, c, d, q = P
        seg_index = np.asarray(seg_index)
        has_p = self.prev_seg[seg_index] >= 0
        has_q = self.next_seg[seg_index] >= 0
        if not has_p.all():      # (ghosts only where needed: most batches have none)
            ghost = (2.0 * c[0] - d[0], 2.0 * c[1] - d[1])
            if self.circle_ends and has_q.any():
                g = _circle_ghost(c, d, q)
                ghost = (ad.where(has_q, g[0], ghost[0]), ad.where(has_q, g[1], ghost[1]))
            p = (ad.where(has_p, p[0], ghost[0]), ad.where(has_p, p[1], ghost[1]))
        if not has_q.all():
            ghost = (2.0 * d[0] - c[0], 2.0 * d[1] - c[1])
            if self.circle_ends and has_p.any():
                g = _circle_ghost(d, c, p)
                ghost = (ad.where(has_p, g[0], ghost[0]), ad.where(has_p, g[1], ghost[1]))
            q = (ad.where(has_q, q[0], ghost[0]), ad.where(has_q, q[1], ghost[1]))
        return p, c, d, q

    def averaged_tangents(self, seg_index, P) -> Tuple[Vec2, Vec2]:
        """Unnormalized averaged nodal tangents t̄ = t_{i−1} + t_i at c and d (unit segment
        tangents t, eq. 3.4 before normalization)."""
        p, c, d, q = self._ghosted(seg_index, P)
        t_cd = ad.unit(ad.sub(d, c))
        return ad.add(ad.unit(ad.sub(c, p)), t_cd), ad.add(t_cd, ad.unit(ad.sub(q, d)))

    def _node_tangent(self, prev: Vec2, node: Vec2, nxt: Vec2) -> Vec2:
        """:meth:`node_tangents` at a node from the node and its neighbours (the averaged
        tangent here)."""
        return ad.add(ad.unit(ad.sub(node, prev)), ad.unit(ad.sub(nxt, node)))

    def end_frame(self, seg_index, P, at_d):
        # the end's node and its two neighbours: (p, c, d) at the start, (c, d, q) at the end
        p, c, d, q = self._ghosted(seg_index, P)
        node = _pick(at_d, c, d)
        return node, self._node_tangent(_pick(at_d, p, c), node, _pick(at_d, d, q))

    def node_points(self, seg_index, P):
        return P[1], P[2]


def _circle_ghost(a: Vec2, b: Vec2, c: Vec2) -> Vec2:
    """A ghost node g before the chain end a (a, b, c: the end node and the next two) such
    that the averaged tangent at a, unit(a − g) + unit(b − a), is the tangent at a of the
    circle through a, b, c (pointing towards b):

        τ ∝ |v|² u − |u|² v  (u = b − a, v = c − a; τ ⊥ the radius at a, as
        (O − a)·u = |u|²/2 and (O − a)·v = |v|²/2 for the centre O),
        unit(a − g) = r = 2 (τ̂·ê) τ̂ − ê  (ê = u/|u|, the reflection of ê about τ̂),
        g = a − |u| r.

    On a straight chain r = ê and g = 2a − b, the reflection. Exact on a circle, second
    order on any smooth curve: the end segment then keeps the curve's order."""
    # (computed for the whole batch: where c repeats b — a one-segment chain — the result
    # is 0/0 and the caller keeps the reflection there)
    with np.errstate(divide="ignore", invalid="ignore"):
        u, v = ad.sub(b, a), ad.sub(c, a)
        tau = ad.unit(ad.sub(ad.scale(u, ad.dot(v, v)), ad.scale(v, ad.dot(u, u))))
        lu = ad.norm(u)
        e = ad.scale(u, ad.reciprocal(lu))
        r = ad.sub(ad.scale(tau, 2.0 * ad.dot(tau, e)), e)
        return ad.sub(a, ad.scale(r, lu))


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


# ---------------------------------------------------------------------- factory
def make_curve(smoothing: str, x: np.ndarray, seg: np.ndarray) -> MasterCurve:
    """The master curve of a contact pair's ``smoothing`` (a registered name, docs/design.md §6)."""
    try:
        cls = SMOOTHINGS[smoothing]
    except KeyError as e:
        raise ValueError(str(e.args[0])) from None
    return cls(x, seg)
