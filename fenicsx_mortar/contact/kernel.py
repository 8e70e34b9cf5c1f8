"""Result types shared by the contact kernels (mortar and node-to-segment).

A kernel returns, for a nodal quantity q_j of the slave nodes (weighted gap g̃_j or nodal
area A_j, docs/design.md §4–5), a list of *contributions*: contribution k adds ``value[k]`` to
q at slave node ``node[k]``, and depends on the local coordinates

    [x_{s_0}, y_{s_0}, …, x_{s_{S-1}}, y_{s_{S-1}}, x_{m_0}, y_{m_0}, …, x_{m_{L-1}}, y_{m_{L-1}}]

with s = ``slave_nodes[k]`` (indices into the slave chain) and m = ``master_nodes[k]``
(indices of the master curve's *points*: the master nodes for the local curves, whose
``point_map`` is None; the control points P = point_map @ X of the global B-spline, see
:mod:`.curves`); ``grad[k]`` and ``hess[k]`` are the exact first and second derivatives
with respect to these m = 2(S + L) coordinates. With a point map the derivatives with
respect to the master nodes follow by the chain rule, ∂q/∂X = point_mapᵀ ∂q/∂P per
coordinate (and point_mapᵀ H point_map for Hessian blocks); this mapping is the
assembly's job. A node index may appear twice
in one row (chain ends, repeated stencil entries); the derivative belonging to each slot is
then to be *added* into the global vector/matrix, which is what scatter-add assembly does.
"""
from __future__ import annotations

from typing import NamedTuple, Tuple

import numpy as np


class NodalContributions:
    """Per-contribution value/grad/hess of a nodal quantity (weighted gap or area) of slave
    node `node`, depending on local nodes `slave_nodes`/`master_nodes`.

    ``hess`` may be given as a zero-argument callable: it is then computed on first access
    (the mortar kernel does so for the nodal areas, whose Hessian the contact terms never
    need, and for the weighted gaps, see :meth:`pair_hessian`). ``cache`` holds derived data
    of the assembly (e.g. the gradient matrix), valid as long as the arrays are not
    modified in place.
    """

    node: np.ndarray          # (K,) slave node index (into the slave chain)
    slave_nodes: np.ndarray   # (K, S) slave node indices of the local variables (first 2S coords)
    master_nodes: np.ndarray  # (K, L) master curve-point indices (next 2L local coords)
    value: np.ndarray         # (K,)
    grad: np.ndarray          # (K, m)   m = 2*(S+L), order [xs0, ys0, xs1, ys1, .., xm0, ym0, ..]
    # hess: np.ndarray        # (K, m, m)  (property, possibly lazy)

    def __init__(self, node, slave_nodes, master_nodes, value, grad, hess, tail_nodes=None):
        self.node = node
        self.slave_nodes = slave_nodes
        self.master_nodes = master_nodes
        #: (K, T) more slave nodes whose coordinates come after the master's (the slave
        #: curve's stencil beyond the segment's two nodes, two-sided smoothing); None: none
        self.tail_nodes = tail_nodes
        self.value = value
        self.grad = grad
        self._hess = hess
        self.cache: dict = {}
        #: Petrov–Galerkin test vectors replacing ∇value as the direction of the force
        #: (:class:`MasterTest`); None: the force is −p ∇value (variational)
        self.test: MasterTest | None = None
        #: (nodal areas only) ∫ ψ_j dΓ of each contribution, ψ_j the weight of node j's
        #: pressure: the normal force node j's pressure carries is p_j Σ psi (on a straight
        #: segment); None: ψ = N (then it is the area)
        self.psi: np.ndarray | None = None

    @property
    def hess(self) -> np.ndarray:
        if callable(self._hess):
            self._hess = self._hess()
        return self._hess

    @hess.setter
    def hess(self, h) -> None:
        self._hess = h

    def pair_hessian(self, wa: np.ndarray, wb: np.ndarray, pairs) -> np.ndarray:
        """wa ∇²q_k + wb ∇²q_{k+h} (h = size/2) for the contributions k in ``pairs`` (index
        array or slice into the first half), where contributions k and k + h share their
        local coordinates (the mortar kernel's node-a and node-b rows of a pair).

        The tangent needs the Hessians only weighted by the pressures, and only for pairs
        with a node in contact: a kernel that defers them (``hess`` an object with a
        ``weighted(wa, wb, pairs)`` method, as the mortar kernel's) forms just these sums,
        one per pair, as the Hessian of wa q_k + wb q_{k+h}."""
        return _pair_weighted(self._hess, lambda: self.hess, wa, wb, pairs)

    def __repr__(self) -> str:
        return f"NodalContributions(size={self.size}, m={self.m})"

    @property
    def size(self) -> int:
        return int(self.node.shape[0])

    @property
    def m(self) -> int:
        tail = 0 if self.tail_nodes is None else self.tail_nodes.shape[1]
        return 2 * (self.slave_nodes.shape[1] + self.master_nodes.shape[1] + tail)

    @classmethod
    def empty(cls, S: int, L: int) -> "NodalContributions":
        m = 2 * (S + L)
        return cls(np.zeros(0, dtype=np.int64), np.zeros((0, S), dtype=np.int64),
                   np.zeros((0, L), dtype=np.int64), np.zeros(0), np.zeros((0, m)),
                   np.zeros((0, m, m)))

    def global_indices(self, n_slave: int) -> np.ndarray:
        """(K, m) positions of the local coordinates in the stacked coordinate vector
        ``[slave_x.ravel(), master_x.ravel()]`` (slave node i -> 2i, 2i+1; master node l ->
        2 n_slave + 2l, 2 n_slave + 2l + 1)."""
        parts = [self.slave_nodes, self.master_nodes + n_slave]
        if self.tail_nodes is not None:
            parts.append(self.tail_nodes)
        nodes = np.concatenate(parts, axis=1)
        return np.stack([2 * nodes, 2 * nodes + 1], axis=2).reshape(nodes.shape[0], -1)


class MasterTest:
    """Petrov–Galerkin test vectors of a weighted gap (see :mod:`.mortar`, "Master-side test
    functions"), one row per contribution of the gap they belong to (same order):

        T_k = ∂Ψ_k/∂v,  Ψ_k = ∫ N_j (v_a N_a + v_b N_b − v_c N̂_c(ξ) − v_d N̂_d(ξ))·n dΓ,

    over the virtual displacements v of the slave segment's nodes (a, b) and of the master
    segment's nodes (c, d) — master NODES, not curve points — and ``jac`` = ∂T_k/∂(local
    coordinates of the gap contribution) for the tangent. ``jac`` may be given as an object
    computing it on first access; with a ``weighted`` method it also serves
    :meth:`pair_jacobian` directly (see :meth:`NodalContributions.pair_hessian`)."""

    def __init__(self, nodes: np.ndarray, grad: np.ndarray, jac):
        #: (K, 4) slave a, slave b (slave chain), master c, master d (master nodes)
        self.nodes = nodes
        self.grad = grad     # (K, 8) T_k over [v_a, v_b, v_c, v_d] (x, y each)
        self._jac = jac      # (K, 8, m), or deferred

    @property
    def jac(self) -> np.ndarray:
        if callable(self._jac):
            self._jac = self._jac()
        return self._jac

    def pair_jacobian(self, wa: np.ndarray, wb: np.ndarray, pairs) -> np.ndarray:
        """wa ∂T_k/∂x + wb ∂T_{k+h}/∂x for the contributions k in ``pairs`` of the first half
        (h = K/2; rows k and k + h share nodes and local coordinates)."""
        return _pair_weighted(self._jac, lambda: self.jac, wa, wb, pairs)

    def global_indices(self, n_slave: int) -> np.ndarray:
        """(K, 8) positions in the stacked NODE coordinates [slave nodes, master nodes]."""
        nodes = self.nodes + np.array([0, 0, n_slave, n_slave])
        return np.stack([2 * nodes, 2 * nodes + 1], axis=2).reshape(nodes.shape[0], -1)


class Triplets(NamedTuple):
    """A sparse matrix as COO triplets (duplicates are meant to be summed)."""

    rows: np.ndarray
    cols: np.ndarray
    vals: np.ndarray


def nodal_sum(contrib: NodalContributions, n_slave: int) -> np.ndarray:
    """Σ of the contributions per slave node: q_j for j = 0 … n_slave−1."""
    return np.bincount(contrib.node, weights=contrib.value, minlength=n_slave)


def chain_links(seg: np.ndarray, n_nodes: int) -> Tuple[np.ndarray, np.ndarray]:
    """For each node, the segment that ends at it and the one that starts at it (−1: none).

    Chains are ordered (segment i = (c, d) runs from c to d), so every node has at most one
    of each; a closed chain has both everywhere.
    """
    seg = np.asarray(seg, dtype=np.int64).reshape(-1, 2)
    before = np.full(n_nodes, -1, dtype=np.int64)
    after = np.full(n_nodes, -1, dtype=np.int64)
    idx = np.arange(seg.shape[0], dtype=np.int64)
    before[seg[:, 1]] = idx
    after[seg[:, 0]] = idx
    return before, after


def _pair_weighted(stored, full, wa: np.ndarray, wb: np.ndarray, pairs) -> np.ndarray:
    """wa D_k + wb D_{k+h} over the pairs: by the deferred object's own ``weighted`` when
    ``stored`` has one, else from the full (K, …) array ``full()`` (h = K/2)."""
    weighted = getattr(stored, "weighted", None)
    if weighted is not None:
        return weighted(wa, wb, pairs)
    D = full()
    h = D.shape[0] // 2
    out = D[:h][pairs] * wa[:, None, None]
    out += D[h:][pairs] * wb[:, None, None]
    return out

