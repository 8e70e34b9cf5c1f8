"""One Newton iteration's elimination of the dual multipliers, as sparse algebra on the
multiplier blocks of the whole system (docs/condensation.md §1-4): which multipliers are
eliminated through their own rows and which through displacement rows P, the condensed
matrix's entries on a rank's rows, the condensed right-hand side and the recovery of
Δu_P and Δλ. No PETSc: the system (system.py) extracts and inserts.
"""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from .inverses import CondensationError, inverse


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
        self.W = inverse(M, first, size) if len(H) else sp.csr_matrix((0, 0))
        used = np.flatnonzero(np.diff(Bh.indptr))              # u-rows B_H acts on
        self.B_rows = rows[used]
        self.BHW = sp.csr_matrix(Bh[used] @ self.W)
        self.G = G = sp.csr_matrix(Cu[H])                      # rows of H, cols global u
        # second stage: the constraint rows G eliminate the displacements P, with
        # G_PP = G[:, P] as nearly diagonal as M (the same dual-basis argument)
        in_p = np.isin(G.indices, self.p_rows)
        G_PP = sp.csr_matrix(G[:, self.p_rows])
        self.Y = inverse(G_PP, first, size) if len(H) else sp.csr_matrix((0, 0))
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
