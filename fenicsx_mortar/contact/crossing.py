"""Slave nodes that passed through the master within one load step, unseen by the search.

The contact search (:mod:`.search`) looks for master segments within the search radius of
the *current* slave segments. An increment large enough to carry a slave node from in
front of the master to more than that radius behind it within one Newton solve leaves the
node with no candidate: the bodies interpenetrate and the step converges without contact
(measured: a block driven 0.3 down onto a slab 0.05 below it in one step ended 0.25 inside
it, contact force 0). This module tells such nodes from the last converged configuration
and the new one, by the signed distance of each slave node to the master polyline,

    d(x) = (x − x_c)·n_c   at the closest point x_c of the master chain,

with n_c the outward normal there (at a vertex, that of the two segments' mean). A node is
reported when its closest point lies inside the master (not at an open chain's end: past
the end there is no body to be inside of), d ≤ −r after the step, and d > −r before it
(r: the node's search radius). Nodes already behind by more than r at the start of the
step (a slave that also passes behind the master far away, e.g. around a thin body) are
not reported. The polyline is used for every smoothing: the test is about distances of
the order of the search radius, far above the smoothing's gap corrections.
"""
from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree


def signed_distance(x: np.ndarray, xm: np.ndarray, seg: np.ndarray
                    ) -> tuple[np.ndarray, np.ndarray]:
    """(d, inside) per point of ``x`` against the master polyline (nodes ``xm``, segments
    ``seg`` oriented so that e₃ × t points out of the body): the signed distance d (module
    docstring) and whether the closest point lies inside the chain (not at an open end)."""
    d, inside, _ = closest(x, xm, seg)
    return d, inside


def closest(x: np.ndarray, xm: np.ndarray, seg: np.ndarray
            ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(d, inside, n): :func:`signed_distance` and the master's outward normal n_c.

    Exact closest point: the nearest master node's distance D bounds the polyline's, and a
    segment with a point within D has its midpoint within D + L_max/2; the nearest
    midpoints are taken until the next one lies beyond that bound."""
    seg = np.asarray(seg, dtype=np.int64).reshape(-1, 2)
    n_p, n_m, n_s = x.shape[0], xm.shape[0], seg.shape[0]
    if n_p == 0 or n_s == 0:
        return np.full(n_p, np.inf), np.zeros(n_p, dtype=bool), np.zeros((n_p, 2))
    # segments at each master node (at most two on a chain; −1 pads)
    node_of = seg.T.ravel()
    seg_of = np.tile(np.arange(n_s), 2)
    order = np.argsort(node_of, kind="stable")
    count = np.bincount(node_of, minlength=n_m)
    rank = np.arange(order.size) - np.repeat(np.cumsum(count) - count, count)
    at = np.full((n_m, 2), -1, dtype=np.int64)
    at[node_of[order], np.minimum(rank, 1)] = seg_of[order]
    a, t = xm[seg[:, 0]], xm[seg[:, 1]] - xm[seg[:, 0]]
    length2 = np.einsum("ij,ij->i", t, t)
    normal = np.stack([-t[:, 1], t[:, 0]], axis=1) / np.sqrt(length2)[:, None]
    D, _ = cKDTree(xm).query(x)
    bound = D + 0.5 * np.sqrt(length2.max()) * (1.0 + 1e-12)
    mids = cKDTree(a + 0.5 * t)
    s_best = np.zeros(n_p, dtype=np.int64)
    xi_best = np.zeros(n_p)
    todo, k = np.arange(n_p), 4
    while todo.size:
        k = min(k, n_s)
        dm, cand = mids.query(x[todo], k=k)
        dm, cand = dm.reshape(todo.size, k), cand.reshape(todo.size, k)
        p = x[todo][:, None, :]
        xi = np.clip(np.einsum("pqi,pqi->pq", p - a[cand], t[cand]) / length2[cand], 0.0, 1.0)
        dist = np.linalg.norm(p - (a[cand] + xi[..., None] * t[cand]), axis=2)
        best = np.argmin(dist, axis=1)
        rows = np.arange(todo.size)
        s_best[todo], xi_best[todo] = cand[rows, best], xi[rows, best]
        # done where every segment not looked at has its midpoint beyond the bound
        done = (k == n_s) | (dm[:, -1] > bound[todo])
        todo, k = todo[~done], 2 * k
    foot = a[s_best] + xi_best[:, None] * t[s_best]
    # at a vertex: the normal of the mean of its segments (the side of the corner)
    node = np.where(xi_best <= 0.0, seg[s_best, 0], np.where(xi_best >= 1.0, seg[s_best, 1], -1))
    n = normal[s_best].copy()
    vertex = node >= 0
    both = vertex & (count[np.maximum(node, 0)] >= 2)
    if both.any():
        pair = at[node[both]]
        m = normal[pair[:, 0]] + normal[pair[:, 1]]
        n[both] = m / np.maximum(np.linalg.norm(m, axis=1), 1e-300)[:, None]
    inside = ~vertex | both                                          # not an open chain end
    return np.einsum("pi,pi->p", x - foot, n), inside, n


def initial_overlap(xs: np.ndarray, seg_s: np.ndarray, xm: np.ndarray, seg_m: np.ndarray
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(nodes, depth, size): the slave nodes that lie behind the master's front, facing it
    (the slave's outward node normal against the master's within 90° of opposite), by
    more than the length of their longest slave segment, with that depth −d and length.

    An initial interference that deep is often beyond the first Newton step from u = 0
    (the overlap is there in full at any increment): two blocks overlapping by 1 element
    converged; by 1.4 to 3.2 elements (four meshes) the runs failed, or converged with a
    folded slave (its cells inverted at their corners); by 1.5 elements on another pair
    it converged."""
    seg_s = np.asarray(seg_s, dtype=np.int64).reshape(-1, 2)
    n_s = xs.shape[0]
    t = xs[seg_s[:, 1]] - xs[seg_s[:, 0]]
    length = np.linalg.norm(t, axis=1)
    normal = np.zeros((n_s, 2))
    size = np.zeros(n_s)
    for col in (0, 1):
        np.add.at(normal, seg_s[:, col], np.column_stack([-t[:, 1], t[:, 0]]))
        np.maximum.at(size, seg_s[:, col], length)
    d, inside, nm = closest(xs, xm, seg_m)
    facing = np.einsum("pi,pi->p", normal, nm) < 0.0
    nodes = np.flatnonzero(inside & facing & (d < -(1.0 + 1e-9) * size))
    return nodes, -d[nodes], size[nodes]


def passed_through(xs0: np.ndarray, xm0: np.ndarray, xs1: np.ndarray, xm1: np.ndarray,
                   seg_m: np.ndarray, radius: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(nodes, depth): the slave nodes that went from within ``radius`` (per node) of the
    master's front to more than it behind, from configuration 0 to 1 (module docstring),
    and their depth −d behind it in configuration 1."""
    d0, _ = signed_distance(xs0, xm0, seg_m)
    d1, inside = signed_distance(xs1, xm1, seg_m)
    nodes = np.flatnonzero(inside & (d1 <= -radius) & (d0 > -radius))
    return nodes, -d1[nodes]
