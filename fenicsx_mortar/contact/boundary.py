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
outer neighbour with a sliver): the rows of a weak node then go on, through the weak
neighbour, to the first supported node along the chain (there ψ_k = N_k + N_j + N_i = 1 on
the weak tail: Σ ψ = 1 still holds). Handing only to a direct neighbour left the sliver
node its own multiplier there — B3 with a master finer than the slave met it at t = 1.6: a
node with f = 1e-4 kept its terms and its tangential multiplier row vanished (a singular
Jacobian). A weak node with no supported node reachable through weak ones (a master
shorter than about one slave segment) keeps its own terms.

The choice is made per Newton iterate from the current configuration, like the active set
(it is a discrete choice: no derivative of f enters the tangent).
"""
from __future__ import annotations

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


def unsupported(A: np.ndarray, A_full: np.ndarray,
                threshold: float = SUPPORT_THRESHOLD) -> np.ndarray:
    """Nodes that see the master (A > 0) on less than ``threshold`` of their support."""
    return (A > 0.0) & (A < threshold * A_full)


def chain_neighbours(seg: np.ndarray, n: int) -> np.ndarray:
    """(n, 2): the slave chain neighbours of every node (−1 where a chain ends)."""
    seg = np.asarray(seg, dtype=np.int64).reshape(-1, 2)
    nb = np.full((n, 2), -1, dtype=np.int64)
    for a, b in seg:
        nb[a, 0 if nb[a, 0] < 0 else 1] = b
        nb[b, 0 if nb[b, 0] < 0 else 1] = a
    return nb


def _walk(start: np.ndarray, first: np.ndarray, weak: np.ndarray, supported: np.ndarray,
          nb: np.ndarray) -> np.ndarray:
    """From each ``start`` node, step to ``first`` and on along the chain while the nodes
    are weak: the first supported node met, or −1 (a node neither weak nor supported, or
    the chain's end)."""
    prev, cur = start.copy(), first.copy()
    out = np.full(start.shape, -1, dtype=np.int64)
    walking = cur >= 0
    for _ in range(len(weak)):
        if not walking.any():
            break
        idx = np.flatnonzero(walking)
        c = cur[idx]
        hit = supported[c]
        out[idx[hit]] = c[hit]
        go = idx[~hit & weak[c]]
        walking[:] = False
        if go.size:
            n0, n1 = nb[cur[go], 0], nb[cur[go], 1]
            nxt = np.where(n0 == prev[go], n1, n0)
            prev[go], cur[go] = cur[go], nxt
            walking[go[nxt >= 0]] = True
    return out


def hand_over(c: NodalContributions, weak: np.ndarray, supported: np.ndarray,
              nb: np.ndarray) -> NodalContributions:
    """The mortar contributions ``c`` with the rows of ``weak`` nodes moved to the first
    ``supported`` node along the slave chain (``nb``: :func:`chain_neighbours`), walking
    first through the other node of the row's segment, else the other way, through weak
    nodes only (module docstring); rows with no such node stay. Values, gradients and
    Hessians are over the pair's local coordinates, which do not change."""
    if c.size == 0 or not weak.any():
        return c
    a, b = c.slave_nodes[:, 0], c.slave_nodes[:, 1]
    other = np.where(c.node == a, b, a)
    rows = np.flatnonzero(weak[c.node])
    j, o = c.node[rows], other[rows]
    to = _walk(j, o, weak, supported, nb)
    back = to < 0
    if back.any():
        away = np.where(nb[j[back], 0] == o[back], nb[j[back], 1], nb[j[back], 0])
        to[back] = _walk(j[back], away, weak, supported, nb)
    keep = to >= 0
    if not keep.any():
        return c
    node = c.node.copy()
    node[rows[keep]] = to[keep]
    out = NodalContributions(node, c.slave_nodes, c.master_nodes, c.value, c.grad, c._hess,
                             c.tail_nodes)
    # Petrov–Galerkin test vectors (smoothed masters) are per contribution, summed by node
    # like the values: they move along with their rows
    out.test = c.test
    return out
