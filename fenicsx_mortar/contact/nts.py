"""Node-to-segment (NTS) contact, the classical baseline (docs/design.md §1, §3, §5).

For each slave node j:

* projection onto the master curve: among the candidate master segments, those with the
  closest-point parameter ξ̄ ∈ [0, 1] qualify and the one with the smallest |g| wins;
  a node that projects onto no segment (beyond the master's ends, or into the blind
  wedge outside a convex master corner) gets no contribution; no facing test is made
  (the smallest |g| already prefers the near side of a closed master);
* point gap g_j = (x_j − x_m(ξ̄))·n_m(ξ̄) (:meth:`MasterCurve.gap`: with averaged
  normals ξ̄ is the projection along the smoothed normal and n_m the smoothed normal; for
  the Hermite and B-spline curves the closest point, with exact derivatives of ξ̄);
  on the faceted curves, within ``BLEND`` of a segment's length from a master node the gap
  turns C1 into (x_j − x_node)·n̄_node, the same function on both sides of the node (the
  surface g = 0 then departs from the facets by at most BLEND·L·sin(θ/2) at a kink θ);
* nodal area A_j = ½(|x_j − x_{j−1}| + |x_{j+1} − x_j|) (adjacent slave segments, current
  configuration); at a chain end the missing neighbour contributes 0;
* weighted gap g̃_j = A_j g_j, so that g̃_j / A_j = g_j and the same enforcement code
  (docs/design.md §5) serves mortar and NTS.

Local coordinates of contribution j (S = 3 slave nodes, then the L master stencil points —
master nodes, or the B-spline's control points, see :mod:`.curves` ``point_map``):
    [x_{j−1}, y_{j−1}, x_j, y_j, x_{j+1}, y_{j+1}, x_{m0}, y_{m0}, …]
At a chain end the missing neighbour's slot holds j itself; its area term is switched off
by ``where`` on a finite ghost, so that slot has exactly zero derivative and the
scatter-added derivatives stay right.
"""
from __future__ import annotations

from typing import Tuple

import numpy as np

from . import ad
from .ad import Jet2
from .curves import MasterCurve
from .kernel import NodalContributions, chain_links
from .projection import closest_segments


BLEND = 0.1  # fraction of a segment next to each of its nodes where the gap blends (below)


def _node_weight(xi):
    """1 at and behind a segment's start node (ξ ≤ 0), 0 from ξ = BLEND on, the C1
    smoothstep 3t² − 2t³ (t = 1 − ξ/BLEND) in between."""
    v = ad.value(xi)
    t = (BLEND - xi) * (1.0 / BLEND)
    return ad.where(v <= 0.0, 1.0, ad.where(v >= BLEND, 0.0, t * t * (3.0 - 2.0 * t)))


def node_gaps(slave_x: np.ndarray, slave_seg: np.ndarray, master_x: np.ndarray,
              master_seg: np.ndarray, curve: MasterCurve,
              pairs: Tuple[np.ndarray, np.ndarray], previous: np.ndarray | None = None
              ) -> Tuple[NodalContributions, NodalContributions]:
    """NTS weighted gaps g̃_j = A_j g_j and nodal areas A_j with exact derivatives.

    ``pairs = (slave_segments, master_segments)`` are segment candidates (e.g. from
    :func:`.search.candidate_pairs`); the nodes of a slave segment inherit its master
    candidates. ``curve`` must be built on the chain ``master_seg``; coordinates come from
    ``master_x``. Returns ``(gap, area)``
    with one contribution per slave node in contact range, S = 3 (see module docstring).
    ``previous`` (in/out, optional): the master segment of each slave node from the last
    call (−1: none); kept while still valid, and updated in place.
    """
    slave_x = np.asarray(slave_x, dtype=float)
    slave_seg = np.asarray(slave_seg, dtype=np.int64).reshape(-1, 2)
    L = curve.stencil_size
    ps = np.asarray(pairs[0], dtype=np.int64)
    pm = np.asarray(pairs[1], dtype=np.int64)
    n_ms = max(int(np.asarray(master_seg).reshape(-1, 2).shape[0]), 1)

    nodes = np.concatenate([slave_seg[ps, 0], slave_seg[ps, 1]])
    segs = np.concatenate([pm, pm])
    key = np.unique(nodes * n_ms + segs)
    nodes, segs = key // n_ms, key % n_ms
    nodes, segs = closest_segments(slave_x, master_x, nodes, segs, curve, previous)
    if previous is not None:
        previous[:] = -1
        previous[nodes] = segs
    K = nodes.shape[0]
    if K == 0:
        return NodalContributions.empty(3, L), NodalContributions.empty(3, L)

    before, after = chain_links(slave_seg, slave_x.shape[0])
    has_p = before[nodes] >= 0
    has_q = after[nodes] >= 0
    prev = np.where(has_p, slave_seg[before[nodes], 0], nodes)
    nxt = np.where(has_q, slave_seg[after[nodes], 1], nodes)
    slave_nodes = np.stack([prev, nodes, nxt], axis=1)
    stencil = curve.stencil(segs)

    X = np.concatenate([slave_x[slave_nodes].reshape(K, 6),
                        curve.local_points(segs, master_x).reshape(K, 2 * L)], axis=1)
    v = Jet2.variables(X)
    xp, xj, xq = (v[0], v[1]), (v[2], v[3]), (v[4], v[5])
    P = [(v[6 + 2 * i], v[7 + 2 * i]) for i in range(L)]

    # a missing neighbour sits on node j: measure to a finite ghost instead of |0|
    # (whose derivative is undefined) and switch the term off
    ghost_p = (ad.where(has_p, xp[0], xj[0] + 1.0), xp[1])
    ghost_q = (ad.where(has_q, xq[0], xj[0] + 1.0), xq[1])
    l_p = ad.where(has_p, ad.norm(ad.sub(xj, ghost_p)), 0.0)
    l_q = ad.where(has_q, ad.norm(ad.sub(ghost_q, xj)), 0.0)
    A = (l_p + l_q) * 0.5

    g, xi = curve.gap(segs, xj, P)
    # Next to a master node the gap turns, C1, into the gap along the node's averaged
    # normal: the segment normals jump at the node, and a slave node sitting on it (matching
    # meshes under compression: every node of a Hertz contact) then has no equilibrium
    # with either segment alone, and a sharp switch makes the force direction jump (Newton
    # cycles). On both sides of the node the gap is then the same function, so the choice
    # of segment there no longer matters. Curves whose gap is C1 across nodes (Hermite,
    # B-spline) need the node's gap only beyond an open chain's end; averaged normals give
    # a continuous but kinked gap at a node and take the blend like the polyline.
    xc, xd = curve.node_points(segs, P)
    if curve.c1_gap:
        xiv = ad.value(xi)
        w_c = np.where((xiv < 0.0) & (curve.prev_seg[segs] < 0), 1.0, 0.0)
        w_d = np.where((xiv > 1.0) & (curve.next_seg[segs] < 0), 1.0, 0.0)
    else:
        # the weights follow the position along the chord (differentiable; the polyline's
        # ξ̄ comes as values only)
        a = ad.sub(xd, xc)
        s = ad.dot(ad.sub(xj, xc), a) / ad.dot(a, a)
        w_c, w_d = _node_weight(s), _node_weight(1.0 - s)
    if (ad.value(w_c) > 0.0).any() or (ad.value(w_d) > 0.0).any():
        tc, td = curve.node_tangents(segs, P)
        g_c = ad.dot(ad.sub(xj, xc), curve.normal(tc))
        g_d = ad.dot(ad.sub(xj, xd), curve.normal(td))
        g = g + (g_c - g) * w_c + (g_d - g) * w_d
    gt = A * g

    gap = NodalContributions(nodes, slave_nodes, stencil, gt.val, gt.grad, gt.hess)
    area = NodalContributions(nodes.copy(), slave_nodes.copy(), stencil.copy(),
                              A.val, np.array(A.grad), A.hess)
    return gap, area
