"""Condensed dual-mortar multipliers: the Newton system over [u, λ] solved through a
displacement-only matrix (docs/condensation.md has the derivation).

The SNES still iterates on [u, λ] with the residual [R_u; C] of
:class:`~.system.MultiplierSystem` — same function, same norms, same line search — so the
iterates are those of the saddle-point solve to round-off. Only the linear solve differs:
the SNES's KSP is a Python KSP (:class:`_CondensedKSP`) that, per Newton iteration,

1. eliminates the multipliers whose own rows are invertible (inactive nodes, the tangential
   multiplier of sliding or frictionless nodes): their columns in the u-rows are zero;
2. eliminates the others, ``H`` (active normal multipliers, sticking tangential ones: rows
   with ∂C/∂λ = 0), through one displacement row of each node, ``P`` (the node's own rows,
   where the dual basis makes the multipliers' forces nearly diagonal): with
   M = P B_H and W = M⁻¹ the condensed matrix is

       J_c = (I − B_H W P) K    on the rows outside P,   J_c = G_H on the rows P,

   G_H = ∂C_H/∂u; M is block-tridiagonal along the slave chain and W its inverse by a
   Neumann series truncated where the terms fall below round-off of the kept ones;
3. solves J_c Δu = f_c with the inner KSP (MUMPS, or a Krylov method with AMG) and
   recovers Δλ_H = W (b_P − P K Δu) and the eliminated ones from their rows.

Every rank holds the multiplier data of all slave nodes (the surfaces are 1D and gathered
anyway); each rank inserts the condensation's entries of the rows it owns.
"""
from __future__ import annotations

import weakref
from typing import Sequence

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from mpi4py import MPI
from petsc4py import PETSc

from . import _dolfinx as dx
from .system import MultiplierSystem, near_nullspace
from .timings import Timings

#: entries of the truncated inverse W below this fraction of their row's diagonal block
#: are dropped: eps/16, below round-off of the entries they would be added to
TRUNCATION = np.finfo(float).eps / 16
#: the Neumann series is used while ‖D⁻¹E‖∞ is below this; above, W is the dense inverse
NEUMANN_LIMIT = 0.5
#: band of slave nodes (along the chain) whose couplings are preallocated around a node
PREDICTED_BAND = 4


class CondensationError(RuntimeError):
    """The multiplier blocks do not have the structure the condensation relies on."""


def condensable(pairs: Sequence) -> bool:
    """Whether every pair with multipliers weighs its gaps with the dual basis (the
    condensed path's premise: nearly diagonal slave blocks of the multiplier forces).

    Args:
        pairs: The contact pairs.

    Returns:
        True if at least one pair has multipliers and all of those use the dual basis.
    """
    with_lam = [p for p in pairs if p.unknowns]
    return bool(with_lam) and all(
        getattr(p.discretization, "basis", "standard") == "dual" for p in with_lam)


# ------------------------------------------------------------------------- the algebra


class Elimination:
    """One Newton iteration's elimination of the multipliers, from the multiplier blocks
    of the whole system (every rank holds all of them; global numbering: displacement dofs
    [0, n_u), multipliers [0, n_lam)).

    Args:
        n_u: Global number of displacement dofs.
        B: ∂R_u/∂λ, (n_u, n_lam) COO (Dirichlet rows left out).
        Cu: ∂C/∂u, (n_lam, n_u) COO (Dirichlet columns left out).
        Cl: ∂C/∂λ, (n_lam, n_lam) COO.
        node_dofs: (n_lam, 2) the global displacement dofs of each multiplier's slave node.
        free: (n_lam, 2) whether each of those dofs is free (not Dirichlet).

    Raises:
        CondensationError: a structure the elimination cannot take (named).
    """

    def __init__(self, n_u: int, B: sp.coo_matrix, Cu: sp.coo_matrix, Cl: sp.coo_matrix,
                 node_dofs: np.ndarray, free: np.ndarray):
        self.n_u = n_u
        n_lam = Cl.shape[0]
        Cl = sp.csr_matrix(Cl)
        Cl.eliminate_zeros()
        # B over the u-rows it acts on only (n_u is the whole mesh)
        B = sp.coo_matrix(B)
        keep = B.data != 0.0
        rows, inv = np.unique(B.row[keep], return_inverse=True)
        Bc = sp.csc_matrix((B.data[keep], (inv, B.col[keep])), shape=(len(rows), n_lam))
        hard = np.diff(Cl.indptr) == 0
        H, E = np.flatnonzero(hard), np.flatnonzero(~hard)
        if np.any(np.diff(Bc.indptr)[E] > 0):
            raise CondensationError(
                "a multiplier with an invertible row of its own acts on the displacement "
                "rows: the condensation has no rule for that enforcement")
        Bh = sp.csr_matrix(Bc[:, H])
        Cu = sp.csr_matrix(Cu)
        order, self.p_rows, first, size = self._rows(Bh, rows, H, node_dofs, free,
                                                     sp.csr_matrix(Cu[H]))
        H = H[order]
        Bh = sp.csr_matrix(Bh[:, order])
        self.H, self.E = H, E
        at = np.searchsorted(rows, self.p_rows)
        M = sp.csr_matrix(Bh[at])                              # M = P B_H, rows as H
        self.W = _inverse(M, first, size) if len(H) else sp.csr_matrix((0, 0))
        used = np.flatnonzero(np.diff(Bh.indptr))              # u-rows B_H acts on
        self.B_rows = rows[used]
        self.BHW = sp.csr_matrix(Bh[used] @ self.W)
        self.G = G = sp.csr_matrix(Cu[H])                      # rows of H, cols global u
        # second stage: the constraint rows G eliminate the displacements P, with
        # G_PP = G[:, P] as nearly diagonal as M (the same dual-basis argument)
        in_p = np.isin(G.indices, self.p_rows)
        G_PP = sp.csr_matrix(G[:, self.p_rows])
        self.Y = _inverse(G_PP, first, size) if len(H) else sp.csr_matrix((0, 0))
        G_R = G.copy()
        G_R.data[in_p] = 0.0
        G_R.eliminate_zeros()
        self.YG = sp.csr_matrix(self.Y @ G_R)                  # Δu_P = Y b_H − YG Δu
        self._Kc_RP = None
        self.Cu_E = sp.csr_matrix(Cu[E])
        self.Cl_EH = sp.csr_matrix(Cl[E][:, H])
        Cl_EE = sp.csc_matrix(Cl[E][:, E])
        self._lu = spla.splu(Cl_EE) if len(E) else None
        self.n_lam = n_lam

    @staticmethod
    def _rows(Bh: sp.csr_matrix, rows: np.ndarray, H, node_dofs, free, G: sp.csr_matrix):
        """The displacement row P of every hard multiplier (columns of Bh, in H's order),
        and the blocks of M = P B_H: the rows of the multiplier's own slave node, where the
        dual basis makes its force dominant — both rows for a node with two hard
        multipliers whose forces are not nearly parallel (a 2×2 block), else the node's
        free row with the larger force if that is at least a tenth of the multiplier's
        largest (a 1×1 block). A multiplier left without (a sticking node with a Dirichlet
        dof) takes the row of its largest force that no other has (a master node's). Of
        the choices left, the one that puts the larger entries of the constraint rows G
        on Kc's diagonal (an iterative solver's smoother divides by it).

        Returns:
            (order of H's multipliers, their P rows, first index and size of each block).
        """
        n = len(H)
        key = node_dofs[H, 0] // 2
        node = np.unique(key, return_inverse=True)[1] if n else np.zeros(0, np.int64)
        count = np.bincount(node) if n else np.zeros(0, np.int64)
        if np.any(count > 2):
            raise CondensationError("more than two active multipliers on one slave node "
                                    "(two pairs sharing a slave surface, both sticking)")
        val, gval = np.zeros((n, 2)), np.zeros((n, 2))
        for c in (0, 1):
            val[:, c] = _entries(Bh, rows, node_dofs[H, c], np.arange(n))
            gval[:, c] = _entries(G, np.arange(n), np.arange(n), node_dofs[H, c])
        val[~free[H]] = 0.0
        colmax = np.asarray(abs(Bh).max(axis=0).todense()).ravel() if n else np.zeros(0)
        p = np.full(n, -1, dtype=np.int64)
        blocks: list[np.ndarray] = []
        # nodes with two: a 2x2 block when both rows are free and the forces not parallel
        pairs = np.flatnonzero(count == 2)
        if len(pairs):
            members = np.argsort(node, kind="stable").reshape(-1)
            members = members[np.isin(node[members], pairs)].reshape(-1, 2)
            a, b = members[:, 0], members[:, 1]
            det = np.abs(val[a, 0] * val[b, 1] - val[a, 1] * val[b, 0])
            good = det >= 0.1 * np.hypot(*val[a].T) * np.hypot(*val[b].T)
            good &= (det > 0)
            # a's constraint on the x or the y row: the larger diagonal of Kc
            swap = (np.abs(gval[a, 1] * gval[b, 0]) > np.abs(gval[a, 0] * gval[b, 1]))
            ca = swap.astype(np.int64)
            p[a[good]] = node_dofs[H[a[good]], ca[good]]
            p[b[good]] = node_dofs[H[b[good]], 1 - ca[good]]
            blocks += [m for m in members[good]]
        single = np.flatnonzero(p < 0)
        if len(single):
            usable = np.abs(val[single]) >= 0.1 * colmax[single, None]
            usable &= np.abs(val[single]) > 0
            pick = np.argmax(np.where(usable, np.abs(gval[single]) + 1e-300, -1.0), axis=1)
            big = usable[np.arange(len(single)), pick]
            taken = np.isin(node_dofs[H[single], pick], p)
            ok = big & ~taken
            # two singles of one node on the same row: the second is exceptional
            rows_ok = node_dofs[H[single[ok]], pick[ok]]
            _, firsts = np.unique(rows_ok, return_index=True)
            keep = np.zeros(ok.sum(), dtype=bool)
            keep[firsts] = True
            ok[np.flatnonzero(ok)[~keep]] = False
            p[single[ok]] = node_dofs[H[single[ok]], pick[ok]]
            blocks += [np.array([k]) for k in single[ok]]
        for k in np.flatnonzero(p < 0):   # rare: no usable row of its own node
            col = sp.csc_matrix(Bh[:, k])
            cand = rows[col.indices[np.argsort(-np.abs(col.data))]]
            cand = cand[~np.isin(cand, p)]
            if not len(cand):
                raise CondensationError("an active multiplier has no displacement row to "
                                        "be eliminated through")
            p[k] = cand[0]
            blocks.append(np.array([k]))
        order = np.concatenate(blocks) if blocks else np.zeros(0, np.int64)
        size = np.array([len(b) for b in blocks], dtype=np.int64)
        first = np.concatenate([[0], np.cumsum(size)[:-1]]).astype(np.int64)
        return order, p[order], first, size

    # -- the condensed matrix ---------------------------------------------------------
    def coupled_rows(self, PK: sp.csr_matrix) -> np.ndarray:
        """The rows outside P that can hold entries in the columns P once the multipliers
        are eliminated: those of K's pattern there (K's pattern is structurally symmetric:
        the columns of K's rows P) and those B_H acts on."""
        rows = np.union1d(np.unique(PK.indices).astype(np.int64), self.B_rows)
        return rows[~np.isin(rows, self.p_rows)]

    def delta(self, PK: sp.csr_matrix, rows: np.ndarray, K_RP: sp.csr_matrix,
              owned: tuple[int, int]) -> tuple[np.ndarray, sp.csr_matrix]:
        """What to add to the assembled K for the condensed matrix Kc on this rank's rows:
        with Π K = K − B_H W P K (the multipliers eliminated through the rows P), then the
        displacements P eliminated through the constraints G (Kc_P· = G):

            rows R:  Kc_RR = (Π K)_RR − (Π K)_RP Y G_PR,   Kc_RP = 0
            rows P:  the identity (Δu_P is recovered from the constraints)

        Args:
            PK: The rows P of the assembled K, (n_H, n_u), in the order of H.
            rows: :meth:`coupled_rows`, global.
            K_RP: K[rows, P], (len(rows), n_H).
            owned: This rank's row range [r0, r1).

        Returns:
            (global rows, CSR over them with global columns).
        """
        r0, r1 = owned
        # (Π K)_RP on the coupled rows: −B_H W K_PP added where B_H acts
        at = np.searchsorted(self.B_rows, rows)
        hit = at < len(self.B_rows)
        hit[hit] = self.B_rows[at[hit]] == rows[hit]
        BHW_rows = sp.csr_matrix((np.ones(int(hit.sum())), (np.flatnonzero(hit), at[hit])),
                                 shape=(len(rows), len(self.B_rows))) @ self.BHW
        PK_P = sp.csr_matrix(PK[:, self.p_rows]) if len(self.p_rows) else \
            sp.csr_matrix((0, 0))
        Kc_RP = sp.csr_matrix(K_RP - BHW_rows @ PK_P)
        self._Kc_RP = (rows, Kc_RP)
        mine = (rows >= r0) & (rows < r1)
        n_u = PK.shape[1]
        # zero the columns P, add −(Π K)_RP Y G_PR, and −B_H W P K where B_H acts
        to_p = sp.csr_matrix((np.ones(len(self.p_rows)), (np.arange(len(self.p_rows)),
                                                          self.p_rows)),
                             shape=(len(self.p_rows), n_u))
        D_R = -(BHW_rows[mine] @ PK) - Kc_RP[mine] @ (self.YG + to_p)
        mp = (self.p_rows >= r0) & (self.p_rows < r1)
        D_P = sp.csr_matrix(to_p[mp] - PK[mp])
        out_rows = np.concatenate([rows[mine], self.p_rows[mp]])
        return out_rows, sp.csr_matrix(sp.vstack([sp.csr_matrix(D_R), D_P], format="csr"))

    # -- right-hand side and recovery ---------------------------------------------------
    def rhs_update(self, b_P: np.ndarray, b_H: np.ndarray, owned: tuple[int, int]):
        """The condensed right-hand side's changes to b_u on this rank's rows: on R,
        −B_H W b_P where B_H acts and −(Π K)_RP Y b_H on the coupled rows; the rows P
        become 0 (Δu_P is recovered by :meth:`displacements_P`).

        Returns:
            (rows added to, values; rows set, values), global rows.
        """
        r0, r1 = owned
        rows, Kc_RP = self._Kc_RP          # (the coupled rows hold every B_H row but P)
        add = Kc_RP @ (self.Y @ b_H)
        at = np.searchsorted(self.B_rows, rows)
        hit = at < len(self.B_rows)
        hit[hit] = self.B_rows[at[hit]] == rows[hit]
        add[hit] += self.BHW[at[hit]] @ b_P
        mine = (rows >= r0) & (rows < r1)
        mp = (self.p_rows >= r0) & (self.p_rows < r1)
        return rows[mine], -add[mine], self.p_rows[mp], np.zeros(int(mp.sum()))

    def displacements_P(self, b_H: np.ndarray, YG_du: np.ndarray) -> np.ndarray:
        """Δu at the rows P from the constraints: Y (b_H − G_PR Δu_R)."""
        return self.Y @ b_H - YG_du

    def recover(self, b_lam: np.ndarray, b_P: np.ndarray, PK_du: np.ndarray,
                CuE_du: np.ndarray) -> np.ndarray:
        """Δλ of every multiplier from the displacement step: Δλ_H = W (b_P − P K Δu),
        then the others from their own rows.

        Args:
            b_lam: The multiplier rows' right-hand side (n_lam).
            b_P: The right-hand side at the rows P (in the order of H).
            PK_du: (P K) Δu.
            CuE_du: (∂C_E/∂u) Δu.

        Returns:
            Δλ (n_lam).
        """
        out = np.zeros(self.n_lam)
        lam_H = self.W @ (b_P - PK_du)
        out[self.H] = lam_H
        if self._lu is not None:
            out[self.E] = self._lu.solve(b_lam[self.E] - CuE_du - self.Cl_EH @ lam_H)
        return out


def _entries(A: sp.csr_matrix, rows: np.ndarray, r: np.ndarray, c: np.ndarray
             ) -> np.ndarray:
    """A[k, c[k]] at the row k of A whose global row number ``rows[k]`` is r[k], for each k
    (0 where not stored)."""
    out = np.zeros(len(r))
    at = np.searchsorted(rows, r)
    ok = at < len(rows)
    ok[ok] = rows[at[ok]] == r[ok]
    if not ok.any():
        return out
    coo = sp.coo_matrix(A)
    n = np.int64(A.shape[1])
    keys = coo.row.astype(np.int64) * n + coo.col
    order = np.argsort(keys)
    keys, data = keys[order], coo.data[order]
    q = at[ok].astype(np.int64) * n + c[ok]
    i = np.minimum(np.searchsorted(keys, q), len(keys) - 1)
    out[ok] = np.where(keys[i] == q, data[i], 0.0)
    return out


def _inverse(M: sp.csr_matrix, first: np.ndarray, size: np.ndarray) -> sp.csr_matrix:
    """M⁻¹ for M = D + E with D block-diagonal (contiguous 1×1 and 2×2 blocks, one per
    slave node) and E the couplings of neighbouring nodes, its entries below TRUNCATION of
    their row's diagonal-block scale dropped. Where ‖D⁻¹E‖∞ is small (the dual basis: the
    forces of a node's neighbours on its rows are ~1e-3 of its own), the Neumann series
    Σ (−D⁻¹E)^k D⁻¹, each term reaching one node further along the chain; else the exact
    inverse by sparse LU, column block by column block, pruned alike."""
    n = M.shape[0]
    group = np.repeat(np.arange(len(first)), size)
    coo = M.tocoo()
    same = group[coo.row] == group[coo.col]
    D = sp.csr_matrix((coo.data[same], (coo.row[same], coo.col[same])), shape=(n, n))
    E = sp.csr_matrix((coo.data[~same], (coo.row[~same], coo.col[~same])), shape=(n, n))
    Dinv = _block_inverse(D, first, size)
    scale = np.asarray(abs(Dinv).max(axis=1).todense()).ravel()
    F = sp.csr_matrix(Dinv @ E)
    rho = float(abs(F).sum(axis=1).max()) if F.nnz else 0.0
    if rho < NEUMANN_LIMIT:
        W, term = Dinv.copy(), Dinv
        for _ in range(400):
            term = _prune(sp.csr_matrix(-(F @ term)), scale)
            if term.nnz == 0:
                return sp.csr_matrix(W)
            W = W + term
    try:
        lu = spla.splu(sp.csc_matrix(M))
    except RuntimeError:
        raise CondensationError("the active multipliers' forces on their rows are "
                                "singular (M = P B_H)") from None
    parts = []
    for c0 in range(0, n, 256):
        rhs = np.zeros((n, min(256, n - c0)))
        rhs[c0 + np.arange(rhs.shape[1]), np.arange(rhs.shape[1])] = 1.0
        parts.append(_prune(sp.csr_matrix(lu.solve(rhs)), scale))
    return sp.csr_matrix(sp.hstack(parts))


def _block_inverse(D: sp.csr_matrix, first: np.ndarray, size: np.ndarray) -> sp.csr_matrix:
    """Inverse of a block-diagonal matrix of contiguous 1×1 and 2×2 blocks."""
    n = D.shape[0]
    rows, cols, vals = [], [], []
    one = first[size == 1]
    if len(one):
        d = np.asarray(D[one, one]).ravel()
        if np.any(d == 0.0):
            raise CondensationError("an active multiplier's force on its row is zero")
        rows.append(one), cols.append(one), vals.append(1.0 / d)
    two = first[size == 2]
    if len(two):
        a = np.asarray(D[two, two]).ravel()
        b = np.asarray(D[two, two + 1]).ravel()
        c = np.asarray(D[two + 1, two]).ravel()
        d = np.asarray(D[two + 1, two + 1]).ravel()
        det = a * d - b * c
        if np.any(np.abs(det) <= 1e-14 * np.maximum(np.abs(a * d), np.abs(b * c))):
            raise CondensationError("a sticking node's 2x2 multiplier block is singular")
        for r, cc, v in ((two, two, d), (two, two + 1, -b), (two + 1, two, -c),
                         (two + 1, two + 1, a)):
            rows.append(r), cols.append(cc), vals.append(v / det)
    return sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows),
                                                 np.concatenate(cols))), shape=(n, n))


def _prune(A: sp.csr_matrix, scale: np.ndarray) -> sp.csr_matrix:
    """A without the entries below TRUNCATION times their row's scale."""
    rows = np.repeat(np.arange(A.shape[0]), np.diff(A.indptr))
    A.data[np.abs(A.data) <= TRUNCATION * scale[rows]] = 0.0
    A.eliminate_zeros()
    return A


# ---------------------------------------------------------------------- PETSc plumbing


class CondensedSystem(MultiplierSystem):
    """[u, λ] for the SNES as :class:`~.system.MultiplierSystem` lays them out, solved
    through the condensed displacement matrix ``Kc`` (module docstring).

    ``A`` is a Python matrix: the Jacobian over [u, λ] as an operator (its product, for
    line searches and tests, from Kc, the condensation's entries and the multiplier
    blocks); the SNES's KSP is :class:`_CondensedKSP`, and ``inner`` the KSP on Kc that
    the options under the SNES's prefix configure.

    Args:
        residual, jacobian, u, bcs, pairs: As for :class:`~.system.MultiplierSystem`.
        matrix: A DOLFINx matrix with the bulk and the predicted contact couplings (its
            pattern seeds Kc's; destroyed here).
        timings: Seconds by phase: the condensation counts as ``contact``.
    """

    condensed = True

    def __init__(self, residual, jacobian, u, bcs, pairs, matrix, timings=None):
        dof_map, n_blocks, comm = self._layout(residual, jacobian, u, bcs, pairs)
        self.timings = timings if timings is not None else Timings()
        self.comm = comm
        V = u.function_space
        self.n_global_u = dx.dof_count(V)
        l2g = dx.local_to_global_dofs(V)
        local = np.asarray(self.bc_dofs)
        g = l2g[local] if len(local) else np.zeros(0, dtype=np.int64)
        #: the Dirichlet dofs, global (DOLFINx's numbering)
        self.skip_u = np.unique(np.concatenate(comm.allgather(g))).astype(np.int64)
        # the multipliers: per pair with unknowns 2 per slave node, node-major
        self._lam_pairs = [p for p in pairs if p.unknowns]
        sizes = [2 * p.slave.n for p in self._lam_pairs]
        self._lam_offset = np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)
        self.n_lam = int(self._lam_offset[-1])
        self._node_dofs = np.concatenate(
            [np.repeat(p.slave.dofs.astype(np.int64), 2, axis=0) for p in self._lam_pairs])
        self._free = ~np.isin(self._node_dofs, self.skip_u)
        own = [o for p, o in zip(pairs, self._owned) if p.unknowns]
        self._lam_owned = np.concatenate(
            [off + (2 * o[:, None] + np.arange(2)).ravel()
             for off, o in zip(self._lam_offset[:-1], own)]).astype(np.int64)
        self._bc_local = [np.isin(p.dofs, self.skip_u) for p in pairs]
        self._lgmap_u = PETSc.LGMap().create(
            dx.local_to_global_blocks(V).astype(PETSc.IntType), bsize=2, comm=comm)
        self._nullspace = near_nullspace(V)
        self._all_cols = PETSc.IS().createStride(self.n_global_u, 0, 1, comm=PETSc.COMM_SELF)
        indptr, indices, _ = matrix.getValuesCSR()
        r0 = matrix.getOwnershipRange()[0]
        self._watch = np.unique(np.concatenate([p.dofs for p in pairs])).astype(np.int64)
        rows, cols = self._predicted(indptr, indices.astype(np.int64), r0)
        matrix.destroy()
        self.Kc = self._build(indptr, indices, r0, rows, cols)
        self._elim: Elimination | None = None
        self._delta = None
        n_local = 2 * self._owned_blocks
        n_total = 2 * n_blocks
        self.x = PETSc.Vec().createMPI((n_local, n_total), bsize=2, comm=comm)
        self.b = self.x.duplicate()
        self.A = PETSc.Mat().createPython(((n_local, n_total), (n_local, n_total)),
                                          _SaddleOperator(self), comm=comm)
        self.A.setUp()
        self.pull(self.x)
        self.inner = PETSc.KSP().create(comm)
        self.inner.setOperators(self.Kc)
        self._f, self._y = self.Kc.createVecs()
        #: Eisenstat–Walker forcing for a Krylov inner solve (set by configure)
        self.forcing: Forcing | None = None
        self.last_solve = {"iterations": 0, "reason": 0, "residual": 0.0, "rtol": 0.0}

    # -- the condensed matrix's pattern ------------------------------------------------
    def _predicted(self, indptr, indices, r0):
        """Owned (row, column) slots the condensation will likely fill, and the rows it can
        touch at all (``self._watch``, whose pattern is kept for the checks). For every
        slave node j: its reach — the dofs its force and constraint depend on (couplings)
        and its rows' stencil in K. Eliminating the multipliers adds the rows of K of the
        nodes within PREDICTED_BAND along the chain to the rows j's force reaches;
        eliminating the displacements P adds the constraints' columns to the rows of the
        stencil: both within reach(j) × ∪ reach(k), k within the band."""
        comm = self.comm
        n_own = len(indptr) - 1
        out_r, out_c, watch = [], [], [self._watch]
        for p in self._lam_pairs:
            s = p.slave
            dofs = s.dofs.astype(np.int64)
            # K's row pattern of every slave node (owner's rows, gathered)
            local = dofs - r0
            mine = np.flatnonzero(((local >= 0) & (local < n_own)).all(axis=1))
            pats = {int(j): np.unique(np.concatenate(
                [indices[indptr[d]:indptr[d + 1]] for d in local[j]])) for j in mine}
            merged: dict[int, np.ndarray] = {}
            for part in comm.allgather(pats):
                merged.update(part)
            couplings = [np.asarray(c, dtype=np.int64) for c in p.couplings_by_node()]
            reach = [np.union1d(couplings[j], merged.get(j, np.zeros(0, np.int64)))
                     for j in range(s.n)]
            watch += reach
            nb = s.neighbours
            for j in range(s.n):
                if len(couplings[j]) <= 4:      # no master candidates: never active
                    continue
                band, front = {j}, {j}
                for _ in range(PREDICTED_BAND):
                    front = {int(k) for f in front for k in nb[f] if k >= 0} - band
                    band |= front
                cols = np.unique(np.concatenate([reach[k] for k in band]))
                rows = reach[j][(reach[j] >= r0) & (reach[j] < r0 + n_own)]
                out_r.append(np.repeat(rows, len(cols)))
                out_c.append(np.tile(cols, len(rows)))
        self._watch = np.unique(np.concatenate(watch)).astype(np.int64)
        if not out_r:
            return np.zeros(0, np.int64), np.zeros(0, np.int64)
        return np.concatenate(out_r), np.concatenate(out_c)

    def _build(self, indptr, indices, r0: int, rows, cols) -> PETSc.Mat:
        """Kc: the CSR pattern (owned rows, global columns) with the slots (rows, cols)
        added, preallocated exactly; the watched rows' pattern kept for the checks."""
        n_own = len(indptr) - 1
        N = self.n_global_u
        P = sp.csr_matrix((np.ones(len(indices), dtype=np.int8), indices, indptr),
                          shape=(n_own, N))
        if len(rows):
            keep = ~np.isin(rows, self.skip_u) & ~np.isin(cols, self.skip_u)
            X = sp.csr_matrix((np.ones(int(keep.sum()), dtype=np.int8),
                               (rows[keep] - r0, cols[keep])), shape=(n_own, N))
            P = P + X
        P.sort_indices()
        w = self._watch[(self._watch >= r0) & (self._watch < r0 + n_own)] - r0
        sub = P[w].tocoo()
        self._pattern = np.sort((w[sub.row] + r0) * np.int64(N) + sub.col)
        J = PETSc.Mat().create(self.comm)
        J.setSizes(((n_own, N), (n_own, N)), bsize=2)
        J.setType(PETSc.Mat.Type.AIJ)
        J.setPreallocationCSR((P.indptr.astype(PETSc.IntType),
                               P.indices.astype(PETSc.IntType)))
        J.setLGMap(self._lgmap_u, self._lgmap_u)
        J.setOption(PETSc.Mat.Option.NEW_NONZERO_ALLOCATION_ERR, False)
        J.setNearNullSpace(self._nullspace)
        return J

    def _grow(self, rows: np.ndarray, cols: np.ndarray) -> None:
        """Kc again with the slots (rows, cols) added (collective: every rank calls it)."""
        indptr, indices, _ = self.Kc.getValuesCSR()
        r0 = self.Kc.getOwnershipRange()[0]
        J = self._build(indptr, indices.astype(np.int64), r0, rows, cols)
        self.Kc.destroy()
        self.Kc = J
        self.inner.setOperators(J)
        self._f, self._y = J.createVecs()

    def _missing(self, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
        """Which owned slots (rows, cols) the pattern lacks (True where missing)."""
        keys = rows.astype(np.int64) * np.int64(self.n_global_u) + cols
        pat = self._pattern
        at = np.minimum(np.searchsorted(pat, keys), max(len(pat) - 1, 0))
        return (pat[at] != keys) if len(pat) else np.ones(len(keys), dtype=bool)

    # -- the Jacobian -------------------------------------------------------------------
    def assemble_jacobian(self, A, add_contact) -> None:
        """Kc = the condensed Jacobian at the current state (``A``, the operator, needs no
        assembly: its product reads Kc and the condensation). The pairs' tangents are
        taken here (``add_contact``, the saddle-point insertion, is not used)."""
        timings = self.timings
        with timings("contact"):
            uu, B, Cu, Cl = self._pair_blocks()
            elim = Elimination(self.n_global_u, B, Cu, Cl, self._node_dofs, self._free)
        r0, r1 = self.Kc.getOwnershipRange()
        mine = (uu[0] >= r0) & (uu[0] < r1)
        uu = tuple(a[mine] for a in uu)
        if self._any(self._missing(uu[0], uu[1]).any()):
            self._grow(uu[0], uu[1])
        for attempt in range(2):
            dx.assemble_jacobian(self.Kc, self.jacobian_form, self.bcs,
                                 extra=lambda K: self._insert(K, *uu))
            diag = self.Kc.getDiagonal()
            with timings("contact"), timings("contact_condensation"):
                PK = self._rows_of_K(elim.p_rows)
                coupled = elim.coupled_rows(PK)
                K_RP = self._block_of_K(coupled, elim.p_rows)
                rows, D = elim.delta(PK, coupled, K_RP, (r0, r1))
                D = _below_round_off(D, rows, diag, r0)
                coo = D.tocoo()
                grow = rows[coo.row], coo.col
                missing = self._missing(*grow)
            if attempt == 0 and self._any(missing.any()):
                self._grow(grow[0][missing], grow[1][missing])
                continue
            break
        with timings("contact"), timings("contact_condensation"):
            self._insert(self.Kc, rows[coo.row], coo.col, coo.data)
            self.Kc.assemble()
        self._elim, self._delta = elim, (rows, D)
        self._B, self._Cu, self._Cl = sp.csc_matrix(B), sp.csr_matrix(Cu), sp.csr_matrix(Cl)
        # the columns of P K, ∂C_E/∂u and Y G, compressed, for the recovery of Δu_P, Δλ
        cols = np.unique(np.concatenate([PK.indices, elim.Cu_E.indices]).astype(np.int64))
        ycols = np.unique(elim.YG.indices).astype(np.int64)
        self._recovery = (cols, _compress(PK, cols), _compress(elim.Cu_E, cols), ycols,
                          _compress(elim.YG, ycols))

    def _any(self, flag: bool) -> bool:
        return bool(self.comm.allreduce(bool(flag), op=MPI.LOR))

    def _insert(self, K: PETSc.Mat, rows, cols, vals) -> None:
        """K[rows, cols] += vals (owned rows, global numbers; repeated entries summed)."""
        if not len(rows):
            return
        u, inv = np.unique(rows, return_inverse=True)
        M = sp.csr_matrix((vals, (inv, cols)), shape=(len(u), self.n_global_u))
        M.sum_duplicates()
        K.setValuesIJV(M.indptr.astype(PETSc.IntType), M.indices.astype(PETSc.IntType),
                       M.data, addv=PETSc.InsertMode.ADD, rowmap=u.astype(PETSc.IntType))

    def _pair_blocks(self):
        """The pairs' tangents split into the displacement block (owned rows) and the
        multiplier blocks B = ∂R_u/∂λ, Cu = ∂C/∂u, Cl = ∂C/∂λ of the whole system (gathered
        from every rank); Dirichlet rows and columns left out."""
        uu, bl, cu, cl = ([], [], []), ([], [], []), ([], [], []), ([], [], [])
        k = 0
        for p, bc in zip(self.pairs, self._bc_local):
            K = p.tangent().tocoo()
            r, c, v = K.row, K.col, K.data
            n_test = len(p.dofs)
            ru, cu_ = r < n_test, c < n_test
            dofs = p.dofs.astype(np.int64)
            sel = ru & cu_ & (v != 0.0)
            sel[sel] = ~bc[r[sel]] & ~bc[c[sel]]
            for a, x in zip(uu, (dofs[r[sel]], dofs[c[sel]], v[sel])):
                a.append(x)
            if not p.unknowns:
                continue
            off = self._lam_offset[k]
            k += 1
            sel = ru & ~cu_ & (v != 0.0)
            sel[sel] = ~bc[r[sel]]
            for a, x in zip(bl, (dofs[r[sel]], off + c[sel] - n_test, v[sel])):
                a.append(x)
            sel = ~ru & cu_ & (v != 0.0)
            sel[sel] = ~bc[c[sel]]
            for a, x in zip(cu, (off + r[sel] - n_test, dofs[c[sel]], v[sel])):
                a.append(x)
            sel = ~ru & ~cu_ & (v != 0.0)
            for a, x in zip(cl, (off + r[sel] - n_test, off + c[sel] - n_test, v[sel])):
                a.append(x)
        parts = [tuple(np.concatenate(a) if a else np.zeros(0) for a in t)
                 for t in (uu, bl, cu, cl)]
        if self.comm.size > 1:
            gathered = self.comm.allgather(parts)
            parts = [tuple(np.concatenate([g[i][j] for g in gathered]) for j in range(3))
                     for i in range(4)]
        (ur, uc, uv), blk, cuk, clk = parts
        n_u, n_lam = self.n_global_u, self.n_lam
        B = sp.coo_matrix((blk[2], (blk[0].astype(np.int64), blk[1].astype(np.int64))),
                          shape=(n_u, n_lam))
        Cu = sp.coo_matrix((cuk[2], (cuk[0].astype(np.int64), cuk[1].astype(np.int64))),
                           shape=(n_lam, n_u))
        Cl = sp.coo_matrix((clk[2], (clk[0].astype(np.int64), clk[1].astype(np.int64))),
                           shape=(n_lam, n_lam))
        return (ur.astype(np.int64), uc.astype(np.int64), uv), B, Cu, Cl

    def _block_of_K(self, rows: np.ndarray, cols: np.ndarray) -> sp.csr_matrix:
        """Kc[rows, cols] (global, any rank's; ``rows`` sorted), on every rank."""
        u, inv = np.unique(cols, return_inverse=True)
        isr = PETSc.IS().createGeneral(rows.astype(PETSc.IntType), comm=PETSc.COMM_SELF)
        isc = PETSc.IS().createGeneral(u.astype(PETSc.IntType), comm=PETSc.COMM_SELF)
        (sub,) = self.Kc.createSubMatrices(isr, isc)
        indptr, indices, vals = sub.getValuesCSR()
        for obj in (sub, isr, isc):
            obj.destroy()
        M = sp.csr_matrix((vals, indices, indptr), shape=(len(rows), len(u)))
        return sp.csr_matrix(M[:, inv])

    def _rows_of_K(self, rows: np.ndarray) -> sp.csr_matrix:
        """The rows ``rows`` (global, any rank's) of the assembled Kc, on every rank."""
        u, inv = np.unique(rows, return_inverse=True)
        isr = PETSc.IS().createGeneral(u.astype(PETSc.IntType), comm=PETSc.COMM_SELF)
        (sub,) = self.Kc.createSubMatrices(isr, self._all_cols)
        indptr, indices, vals = sub.getValuesCSR()
        sub.destroy()
        isr.destroy()
        M = sp.csr_matrix((vals, indices, indptr), shape=(len(u), self.n_global_u))
        return sp.csr_matrix(M[inv])

    # -- the linear solve ---------------------------------------------------------------
    def _gather(self, local: np.ndarray, first: int, rows: np.ndarray) -> np.ndarray:
        """Values of a distributed vector (this rank's part ``local``, starting at global
        ``first``) at the global ``rows``, on every rank."""
        at = rows - first
        mine = (at >= 0) & (at < len(local))
        out = np.zeros(len(rows))
        out[mine] = local[at[mine]]
        if self.comm.size > 1:
            out = self.comm.allreduce(out, op=MPI.SUM)
        return out

    def _lam_values(self, arr: np.ndarray) -> np.ndarray:
        """The multiplier entries of an extended local array, gathered: (n_lam,)."""
        out = np.zeros(self.n_lam)
        out[self._lam_owned] = arr[self.n_u:]
        if self.comm.size > 1:
            out = self.comm.allreduce(out, op=MPI.SUM)
        return out

    def _u_at(self, y: PETSc.Vec, cols: np.ndarray) -> np.ndarray:
        r0 = y.getOwnershipRange()[0]
        return self._gather(y.array_r, r0, cols)

    def solve(self, b: PETSc.Vec, x: PETSc.Vec, fnorm_iteration: int) -> tuple[int, int]:
        """x = J⁻¹ b through the condensed system. Returns (inner iterations, reason)."""
        elim = self._elim
        arr = b.array_r
        r0, r1 = self.Kc.getOwnershipRange()
        b_lam = self._lam_values(arr)
        b_u = arr[: self.n_u]
        b_P = self._gather(b_u, r0, elim.p_rows)
        f = self._f
        fa = f.array
        fa[:] = b_u
        add_rows, add, set_rows, values = elim.rhs_update(b_P, b_lam[elim.H], (r0, r1))
        fa[add_rows - r0] += add                # B_rows are unique
        fa[set_rows - r0] = values
        if self.forcing is not None:
            self.inner.setTolerances(rtol=self.forcing.rtol(b.norm(), fnorm_iteration))
        y = self._y
        y.set(0.0)
        self.inner.solve(f, y)
        reason = self.inner.getConvergedReason()
        its = self.inner.getIterationNumber()
        self._fill_P(y, b_lam[elim.H])
        self.last_solve = {"iterations": its, "reason": int(reason),
                           "residual": float(self.inner.getResidualNorm()),
                           "rtol": float(self.inner.getTolerances()[0])}
        dlam = self._recover(b_lam, b_P, y)
        out = x.array
        out[: self.n_u] = y.array_r
        out[self.n_u:] = dlam[self._lam_owned]
        return its, reason

    def _fill_P(self, du: PETSc.Vec, b_H: np.ndarray) -> None:
        """Δu at the rows P (this rank's) from the constraints and the rest of Δu."""
        elim = self._elim
        ycols, YGc = self._recovery[3:]
        u_P = elim.displacements_P(b_H, YGc @ self._u_at(du, ycols))
        r0 = du.getOwnershipRange()[0]
        mp = (elim.p_rows >= r0) & (elim.p_rows < r0 + du.getLocalSize())
        du.array[elim.p_rows[mp] - r0] = u_P[mp]

    def _recover(self, b_lam: np.ndarray, b_P: np.ndarray, du: PETSc.Vec) -> np.ndarray:
        """Δλ (n_lam) from the displacement step ``du`` (Kc's layout)."""
        cols, PKc, CuEc = self._recovery[:3]
        uc = self._u_at(du, cols)
        return self._elim.recover(b_lam, b_P, PKc @ uc, CuEc @ uc)

    def lift(self, du: PETSc.Vec) -> PETSc.Vec:
        """The step [δu, δλ] over [u, λ] whose eliminated rows of J [δu, δλ] vanish: δu at
        the rows P from the constraints, δλ from the recovery, both with a zero right-hand
        side. Along it J acts as Kc on the rows outside P (tests).

        Args:
            du: A displacement direction in Kc's layout.

        Returns:
            A new vector in the SNES's layout.
        """
        n_H = len(self._elim.H)
        du = du.copy()
        self._fill_P(du, np.zeros(n_H))
        dlam = self._recover(np.zeros(self.n_lam), np.zeros(n_H), du)
        d = self.x.duplicate()
        d.array[: self.n_u] = du.array_r
        d.array[self.n_u:] = dlam[self._lam_owned]
        return d

    def mult(self, x: PETSc.Vec, y: PETSc.Vec) -> None:
        """y = J x, J the Jacobian over [u, λ]: K = Kc − (the condensation's entries)."""
        rows, D = self._delta
        arr = x.array_r
        r0, r1 = self.Kc.getOwnershipRange()
        f, g = self._f, self._y
        f.array[:] = arr[: self.n_u]
        self.Kc.mult(f, g)
        lam = self._lam_values(arr)
        B, Cu, Cl = self._B, self._Cu, self._Cl
        cols = np.unique(np.concatenate([D.indices, Cu.indices]).astype(np.int64))
        full = np.zeros(self.n_global_u)
        full[cols] = self._u_at(f, cols)
        out_u = g.array_r.copy()
        out_u[rows - r0] -= D @ full              # the rows of Δ are unique
        Bx = B @ lam
        nz = np.flatnonzero(Bx)
        own = nz[(nz >= r0) & (nz < r1)]
        out_u[own - r0] += Bx[own]
        ylam = Cu @ full + Cl @ lam
        out = y.array
        out[: self.n_u] = out_u
        out[self.n_u:] = ylam[self._lam_owned]

    def owned_objects(self) -> list:
        return [self.b_u, self._lgmap, self._lgmap_u, self.Kc, self.inner, self._f, self._y,
                self._all_cols, self._nullspace]

    def configure(self, snes: PETSc.SNES, applied) -> None:
        """The SNES's KSP becomes the condensing one; the options under the prefix
        configure the inner KSP on Kc."""
        prefix = snes.getOptionsPrefix() or ""
        ksp = snes.getKSP()
        ksp.setOptionsPrefix(prefix + "condensed_")
        ksp.setType(PETSc.KSP.Type.PYTHON)
        ksp.setPythonContext(_CondensedKSP(self, snes))
        ksp.getPC().setType(PETSc.PC.Type.NONE)
        self.inner.setOptionsPrefix(prefix)
        applied.set_from_options(snes, extra=[self.inner])
        # a Krylov inner solve without a tolerance of the user's: inexact Newton
        self.forcing = (Forcing(applied.settings.atol)
                        if self.inner.getType() != PETSc.KSP.Type.PREONLY
                        and "ksp_rtol" not in applied.options else None)


def _below_round_off(D: sp.csr_matrix, rows: np.ndarray, diag: PETSc.Vec,
                     r0: int) -> sp.csr_matrix:
    """D without the entries below TRUNCATION of their row's scale (the larger of K's
    diagonal entry there and D's largest entry in the row): added to that row they change
    nothing beyond its round-off, and they would only widen the pattern (the truncated
    inverses' tails, ~1e-16 of the row, reach several nodes further along the chain)."""
    D = sp.csr_matrix(D)
    scale = np.abs(diag.array_r[rows - r0])
    diag.destroy()
    n = np.diff(D.indptr)
    big = np.zeros(len(rows))
    has = n > 0
    big[has] = np.maximum.reduceat(np.abs(D.data), D.indptr[:-1][has])
    scale = np.maximum(scale, big)
    D.data[np.abs(D.data) <= TRUNCATION * np.repeat(scale, n)] = 0.0
    D.eliminate_zeros()
    return D


def _compress(A: sp.csr_matrix, cols: np.ndarray) -> sp.csr_matrix:
    """A with its columns renumbered as their positions in the sorted ``cols``."""
    return sp.csr_matrix((A.data, np.searchsorted(cols, A.indices), A.indptr),
                         shape=(A.shape[0], len(cols)))


class Forcing:
    """Eisenstat–Walker forcing terms (their choice 2, γ = 0.9, α = 2, with the usual
    safeguard): the inner solve's relative tolerance from the ratio of the last two
    residual norms, so that early Newton steps are solved loosely and the last ones
    tightly (quadratic convergence kept), at most ETA_MAX; never tighter than needed to
    reach a tenth of the Newton solve's ``atol`` from the current residual.

    Args:
        atol: The Newton solve's absolute tolerance (SolverSettings.atol).
    """

    gamma, alpha, eta0, eta_max, eta_min = 0.9, 2.0, 1e-2, 1e-2, 1e-12

    def __init__(self, atol: float = 0.0):
        self.atol = atol
        self._last: tuple[float, float] | None = None

    def rtol(self, fnorm: float, iteration: int) -> float:
        """The relative tolerance of Newton iteration ``iteration``'s linear solve, whose
        right-hand side (the residual) has the norm ``fnorm``."""
        if iteration == 0 or self._last is None:
            eta = self.eta0
        else:
            f_prev, eta_prev = self._last
            eta = self.gamma * (fnorm / f_prev) ** self.alpha
            safe = self.gamma * eta_prev ** self.alpha
            if safe > 0.1:
                eta = max(eta, safe)
        floor = 0.1 * self.atol / fnorm if fnorm > 0 else self.eta_max
        eta = min(max(eta, self.eta_min, floor), self.eta_max)
        self._last = (fnorm, eta)
        return eta


class _CondensedKSP:
    """The SNES's KSP (type python): one condensed solve (CondensedSystem.solve)."""

    def __init__(self, system: CondensedSystem, snes: PETSc.SNES):
        self._system = weakref.ref(system)
        self._snes = weakref.ref(snes)

    @property
    def inner(self):
        s = self._system()
        return None if s is None else s.inner

    def setUp(self, ksp) -> None:
        pass

    def reset(self, ksp) -> None:
        s = self._system()
        if s is None:
            return
        if s.inner.getPC().getType() in (PETSc.PC.Type.LU, PETSc.PC.Type.CHOLESKY):
            # a failed factorization is forgotten (newton._reset_linear_solver); KSPReset
            # drops the operators too. Not a multigrid's: reset, its levels keep the old
            # coarse sizes and its next set-up fails ("Cannot change local size of Amat")
            s.inner.reset()
            s.inner.setOperators(s.Kc)

    def solve(self, ksp, b, x) -> None:
        s, snes = self._system(), self._snes()
        it = snes.getIterationNumber() if snes is not None else 0
        its, reason = s.solve(b, x, it)
        ksp.setIterationNumber(its)
        ksp.setConvergedReason(reason if reason < 0
                               else PETSc.KSP.ConvergedReason.CONVERGED_RTOL)


class _SaddleOperator:
    """The Jacobian over [u, λ] as a Python matrix (CondensedSystem.mult)."""

    def __init__(self, system: CondensedSystem):
        self._system = weakref.ref(system)

    def mult(self, mat, x, y) -> None:
        self._system().mult(x, y)
