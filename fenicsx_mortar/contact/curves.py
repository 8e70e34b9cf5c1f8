"""Master curve geometry (DESIGN.md §3, §6).

A :class:`MasterCurve` maps (master segment i, ξ ∈ [0, 1]) to a point x(ξ) and tangent
a = dx/dξ. On segment i the curve depends on the coordinates of a fixed number L of master
nodes, its *stencil*; all geometric methods take these local coordinates ``P`` as a sequence
of L points, each a 2-tuple of :class:`~.ad.Jet2` or of float arrays, so one code path
gives plain values (search, segmentation pre-pass) and exact derivatives (kernels).

Batch convention: ``seg_index`` is an integer array that broadcasts (numpy rules) against
the batch shape of ``P``/``xi``/``xs``: shape (k,) for a batch (k,) of segments, (1, k)
for the mortar Gauss batch (n_gauss, k) where ``P`` has batch (k,).

Only the C0 polyline exists now; smoothed curves (averaged normals, Hermite, B-spline)
subclass this with their own stencils and override :meth:`MasterCurve.project` (safeguarded
Newton).
"""
from __future__ import annotations

import abc
from typing import Sequence, Tuple

import numpy as np

from . import ad
from .ad import Scalar, Vec2
from .kernel import chain_links


class MasterCurve(abc.ABC):
    """Geometry of the master surface: a map (segment i, ξ∈[0,1]) -> point, built from the
    chain nodes."""

    #: number of master nodes the curve on one segment depends on
    stencil_size: int

    def __init__(self, x: np.ndarray, seg: np.ndarray):
        self.x = np.asarray(x, dtype=float)
        self.seg = np.asarray(seg, dtype=np.int64).reshape(-1, 2)
        before, after = chain_links(self.seg, self.x.shape[0])
        #: neighbouring segments along the chain (−1 at the ends of an open chain)
        self.prev_seg = before[self.seg[:, 0]]
        self.next_seg = after[self.seg[:, 1]]

    # ------------------------------------------------------------------ topology
    @abc.abstractmethod
    def stencil(self, seg_index: np.ndarray) -> np.ndarray:
        """(k, L) master node indices the curve on these segments depends on."""

    def local_points(self, seg_index: np.ndarray, x: np.ndarray | None = None) -> np.ndarray:
        """(k, L, 2) coordinates of the stencil nodes (from ``x`` or the curve's own nodes)."""
        x = self.x if x is None else np.asarray(x, dtype=float)
        return x[self.stencil(np.asarray(seg_index))]

    @staticmethod
    def split_points(P: np.ndarray) -> list:
        """(k, L, 2) float array -> list of L points (x, y) of (k,) arrays."""
        return [(P[:, i, 0], P[:, i, 1]) for i in range(P.shape[1])]

    # ------------------------------------------------------------------ geometry
    @abc.abstractmethod
    def evaluate(self, seg_index, xi: Scalar, P: Sequence[Vec2]) -> Tuple[Vec2, Vec2]:
        """Point x(ξ) and tangent a(ξ) = dx/dξ on the segments."""

    @abc.abstractmethod
    def node_points(self, seg_index, P: Sequence[Vec2]) -> Tuple[Vec2, Vec2]:
        """The segment's start and end nodes x(0), x(1)."""

    @abc.abstractmethod
    def node_tangents(self, seg_index, P: Sequence[Vec2]) -> Tuple[Vec2, Vec2]:
        """Tangent *directions* (any positive length) at the segment's start and end node,
        used by the mortar segmentation: the master segment's shadow on the slave ends on
        the lines through the end nodes perpendicular to these."""

    def normal(self, a: Vec2) -> Vec2:
        """Outward unit normal n = e3 × a/|a| (DESIGN.md §3)."""
        return ad.unit(ad.perp(a))

    def project(self, seg_index, xs: Vec2, P: Sequence[Vec2]) -> Scalar:
        """ξ̄ of the closest-point projection of xs onto the segment's curve (unclamped).

        General curves need a safeguarded Newton iteration (DESIGN.md §3); subclasses
        provide it (planned: contact/projection.py).
        """
        raise NotImplementedError(f"{type(self).__name__} has no projection yet")

    def gap(self, seg_index, xs: Vec2, P: Sequence[Vec2]) -> Tuple[Scalar, Scalar]:
        """Normal gap g = (xs − x(ξ̄))·n(ξ̄) at the projection ξ̄ = :meth:`project`, and ξ̄.

        Subclasses may shortcut this (the polyline does); the returned ξ̄ may then be
        values only — it is used for the mortar matrix M, not differentiated.
        """
        xi = self.project(seg_index, xs, P)
        x_m, a_m = self.evaluate(seg_index, xi, P)
        return ad.dot(ad.sub(xs, x_m), self.normal(a_m)), xi


class Polyline(MasterCurve):
    """The C0 polyline: x(ξ) = (1−ξ) x_c + ξ x_d, a = x_d − x_c on segment (c, d).

    Stencil (prev(c), c, d, next(d)): the curve itself only needs c, d, but the
    segmentation uses the averaged nodal tangent (DESIGN.md eq. 3.4)
        t̄_c = t_{prev(c),c} + t_{c,d}   (unit segment tangents; only the direction matters)
    At the ends of an open chain prev(c) = c (or next(d) = d) is stored in the stencil and
    t̄ reduces to the segment's own tangent: the missing neighbour is replaced by the ghost
    node 2x_c − x_d (reflection), whose tangent equals t_{c,d} *as a function of the
    coordinates*, so the derivatives are right and the repeated slot gets zero derivative.
    """

    stencil_size = 4

    def stencil(self, seg_index: np.ndarray) -> np.ndarray:
        seg_index = np.asarray(seg_index, dtype=np.int64)
        c, d = self.seg[seg_index, 0], self.seg[seg_index, 1]
        ps, ns = self.prev_seg[seg_index], self.next_seg[seg_index]
        p = np.where(ps >= 0, self.seg[ps, 0], c)
        q = np.where(ns >= 0, self.seg[ns, 1], d)
        return np.stack([p, c, d, q], axis=1)

    def evaluate(self, seg_index, xi, P):
        c, d = P[1], P[2]
        a = ad.sub(d, c)
        return ad.add(c, ad.scale(a, xi)), a

    def node_points(self, seg_index, P):
        return P[1], P[2]

    def node_tangents(self, seg_index, P):
        p, c, d, q = P
        seg_index = np.asarray(seg_index)
        has_p = self.prev_seg[seg_index] >= 0
        has_q = self.next_seg[seg_index] >= 0
        p = (ad.where(has_p, p[0], 2.0 * c[0] - d[0]), ad.where(has_p, p[1], 2.0 * c[1] - d[1]))
        q = (ad.where(has_q, q[0], 2.0 * d[0] - c[0]), ad.where(has_q, q[1], 2.0 * d[1] - c[1]))
        t_cd = ad.unit(ad.sub(d, c))
        return ad.add(ad.unit(ad.sub(c, p)), t_cd), ad.add(t_cd, ad.unit(ad.sub(q, d)))

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
