"""Slave nodes at the edge of the master: boundary modification of the mortar test functions.

Where the slave surface extends beyond the master's end, a slave node j just outside the
master keeps a support that overlaps the master by a sliver (the part of its segment next
to its neighbour k inside). Its weighted gap g̃_j = ∫ N_j g dΓ and nodal area A_j = ∫ N_j dΓ
over that sliver both vanish like the square of the overlap, and the constraint g̃_j ≥ 0
is a test of the gap with a test function that is almost zero where it lives: the discrete
inf-sup constant of that multiplier degenerates. Whatever force the master's end corner has
to carry (a finite, physical corner force F, the slave wrapping around the corner) then
goes through p_j A_j ≈ F, so p_j ≈ F/A_j → ∞ as the node slides off (measured on the B3
half-rings: p_j A_j ≈ 20–75 while A_j falls to 1e-4 and p_j rises to 4e4), until the
sliver disappears and the force jumps to the next node, which starts the same way. Newton
and the ALM updates then crawl (A_j-scaled penalties, 1e4-fold pressure jumps) and the
step control gives up.

The cure is the boundary modification of the multiplier space used for slave boundaries
and crosspoints in the mortar literature (Wohlmuth; for contact, Cichosz & Bischoff 2011,
Popp et al.): a node that is not *supported* by the master (its supported fraction
f_j = A_j / A_j^full below ``threshold``; A_j^full = ∫ N_j dΓ over its whole slave support,
f = 1 wherever the master covers the node's support, f ≈ 1/2 when the node itself sits on
the master's end perpendicular) carries no multiplier of its own: its test function N_j is
added, on the segment it shares with a supported neighbour k, to N_k. In terms of the
kernel outputs, the contributions (g̃, A and their derivatives) of node j on segment (j, k)
are moved to node k. Then Σ_j ψ_j = 1 on every supported part still holds (a constant
pressure is transmitted exactly: the patch test is untouched, it has f = 1 everywhere), the
sliver's gap is tested by node k's well-supported multiplier, and p_k ≈ F/(A_k + A_j)
stays bounded. Nodes with f = 1 (everything away from the master's ends) are unchanged.
Two weak nodes can sit side by side (the node on the master's end just below f = 1/2, its
outer neighbour with a sliver). The rows of both on the segment between them then go,
together, to the supported neighbour beyond the better supported of the two (the larger
A_j; beyond the other if that one is not supported), and the rest of their rows to their
supported neighbours as above: ψ_k = N_k + N_j + N_i = 1 on the weak tail, Σ ψ = 1 still.
Handing only to a direct neighbour left the sliver node its own multiplier there — B3 with
a master finer than the slave met it at t = 1.6: a node with f = 1e-4 kept its terms and
its tangential multiplier row vanished (a singular Jacobian). Rows go at most one node
beyond their segment, so under MPI the rank owning the receiver has integrated the
segment when every rank integrates one segment more at each partition boundary
(:func:`segments_to_integrate`). Rows with no supported receiver so near (three weak nodes
in a row, a master shorter than about one slave segment) stay where they are.

The choice is made per Newton iterate from the current configuration, like the active set
(it is a discrete choice: no derivative of f enters the tangent).
"""
from __future__ import annotations

from typing import Sequence

import numpy as np

from .kernel import NodalContributions

#: a slave node with less than this fraction of its support on the master hands its
#: terms to its supported neighbour (1/2: the node's own point is past the master's end)
SUPPORT_THRESHOLD = 0.5


def full_areas(xs: np.ndarray, seg: np.ndarray, n: int) -> np.ndarray:
    """A_j^full = ∫ N_j dΓ over the whole slave support (current configuration)."""
    seg = np.asarray(seg, dtype=np.int64).reshape(-1, 2)
    half = 0.5 * np.linalg.norm(xs[seg[:, 1]] - xs[seg[:, 0]], axis=1)
    return (np.bincount(seg[:, 0], weights=half, minlength=n)
            + np.bincount(seg[:, 1], weights=half, minlength=n))


def classify(A: np.ndarray, A_full: np.ndarray, threshold: float = SUPPORT_THRESHOLD
             ) -> tuple[np.ndarray, np.ndarray]:
    """(weak, supported): the nodes that see the master (A > 0) on less than ``threshold``
    of their support, and those that see it on at least that."""
    supported = A >= threshold * A_full
    return (A > 0.0) & ~supported, supported


def chain_neighbours(seg: np.ndarray, n: int) -> np.ndarray:
    """(n, 2): the slave chain neighbours of every node (−1 where a chain ends)."""
    seg = np.asarray(seg, dtype=np.int64).reshape(-1, 2)
    nb = np.full((n, 2), -1, dtype=np.int64)
    for a, b in seg:
        for node, other in ((a, b), (b, a)):
            if nb[node, 0] < 0:
                nb[node, 0] = other
            elif nb[node, 1] < 0:
                nb[node, 1] = other
            else:
                raise ValueError(f"slave node {node} is in more than two segments: not a chain")
    return nb


def segments_to_integrate(owned: np.ndarray, seg: np.ndarray, nb: np.ndarray) -> np.ndarray:
    """The slave segments a rank integrates: those touching the nodes it owns or their
    chain neighbours (:func:`hand_over` moves rows one node beyond their segment)."""
    near = owned.copy()
    for k in (0, 1):
        has = nb[:, k] >= 0
        near[nb[has, k]] |= owned[has]
    return near[seg[:, 0]] | near[seg[:, 1]]


def _beyond(nb: np.ndarray, node: np.ndarray, away: np.ndarray) -> np.ndarray:
    """The chain neighbour of ``node`` that is not ``away`` (−1 at a chain end)."""
    return np.where(nb[node, 0] == away, nb[node, 1], nb[node, 0])


def hand_over(contributions: Sequence[NodalContributions], A: np.ndarray,
              weak: np.ndarray, supported: np.ndarray, nb: np.ndarray
              ) -> tuple[NodalContributions, ...]:
    """The mortar contributions (weighted gaps and nodal areas: the same rows) with the
    rows of ``weak`` nodes (:func:`classify`) moved to a ``supported`` node (module
    docstring): the other node of the row's segment if it is supported; if it is weak too,
    the supported neighbour beyond the segment's end with the larger nodal area ``A`` (else
    beyond the other end), the same for both rows of that segment; else the row stays.
    ``nb``: :func:`chain_neighbours`. Values, gradients and Hessians are over the pair's
    local coordinates, which do not change."""
    contributions = tuple(contributions)
    c = contributions[0]
    if c.size == 0 or not weak.any():
        return contributions
    a, b = c.slave_nodes[:, 0], c.slave_nodes[:, 1]
    other = np.where(c.node == a, b, a)
    to = np.full(c.node.shape, -1, dtype=np.int64)
    mine = weak[c.node]
    simple = mine & supported[other]
    to[simple] = other[simple]
    both = np.flatnonzero(mine & weak[other])
    if both.size:
        sa, sb = a[both], b[both]
        first_a = (A[sa] > A[sb]) | ((A[sa] == A[sb]) & (sa < sb))
        p, q = np.where(first_a, sa, sb), np.where(first_a, sb, sa)
        for end, far in ((p, q), (q, p)):
            k = _beyond(nb, end, far)
            ok = (to[both] < 0) & (k >= 0)
            ok[ok] = supported[k[ok]]
            to[both[ok]] = k[ok]
    move = to >= 0
    if not move.any():
        return contributions
    node = np.where(move, to, c.node)
    return tuple(_moved(x, node) for x in contributions)


def _moved(c: NodalContributions, node: np.ndarray) -> NodalContributions:
    out = NodalContributions(node, c.slave_nodes, c.master_nodes, c.value, c.grad, c._hess,
                             c.tail_nodes)
    # Petrov–Galerkin test vectors (smoothed masters) are per contribution, summed by node
    # like the values: they move along with their rows
    out.test = c.test
    out.psi = c.psi
    return out
