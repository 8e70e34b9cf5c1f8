"""The pattern of the condensed matrix Kc: the bulk's and the predicted contact couplings,
plus the fill both elimination stages can add around every slave node with master
candidates, preallocated exactly; grown once when a slot outside it is needed (large
sliding) rather than by PETSc's reallocation per row.
"""
from __future__ import annotations

import numpy as np
from mpi4py import MPI  # noqa: F401  (before petsc4py: the PyPI wheel needs it)
from petsc4py import PETSc

from ..contact.assembly import pattern_with

#: band of slave nodes (along the chain) whose couplings are preallocated around a node
PREDICTED_BAND = 4


class KcPattern:
    """Kc's pattern, for :class:`~.system.CondensedSystem` (which holds the layout these
    methods read: ``comm``, ``skip_u``, ``n_global_u``, ``_lam_pairs``, ``_watch``,
    ``_lgmap_u``, ``_nullspace``, and ``Kc``, ``inner``, ``lag`` for :meth:`_grow`)."""

    lag = None

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
        keep = ~np.isin(rows, self.skip_u) & ~np.isin(cols, self.skip_u)
        P = pattern_with(indptr, indices, N, rows[keep] - r0, cols[keep])
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
        if self.lag is not None:
            self.lag.rebuild()

    def _missing(self, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
        """Which owned slots (rows, cols) the pattern lacks (True where missing)."""
        keys = rows.astype(np.int64) * np.int64(self.n_global_u) + cols
        pat = self._pattern
        at = np.minimum(np.searchsorted(pat, keys), max(len(pat) - 1, 0))
        return (pat[at] != keys) if len(pat) else np.ones(len(keys), dtype=bool)
