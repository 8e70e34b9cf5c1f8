"""The master curve's interface, and what the local curves share (the neighbour stencil,
the circle at an open end); the factory by smoothing name."""
from __future__ import annotations

import abc
from typing import Sequence, Tuple

import numpy as np

from .. import ad, projection
from ..ad import Scalar, Vec2
from ..kernel import chain_links
from ..registry import SMOOTHINGS


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


# ---------------------------------------------------------------------- factory
def make_curve(smoothing: str, x: np.ndarray, seg: np.ndarray) -> MasterCurve:
    """The master curve of a contact pair's ``smoothing`` (a registered name, docs/design.md §6)."""
    try:
        cls = SMOOTHINGS[smoothing]
    except KeyError as e:
        raise ValueError(str(e.args[0])) from None
    return cls(x, seg)
