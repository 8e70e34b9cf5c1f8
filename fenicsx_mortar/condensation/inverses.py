"""The truncated inverses of the condensation: W = M⁻¹ and Y = G_PP⁻¹ of matrices that are
block-diagonal per slave node up to small couplings of neighbouring nodes (the dual basis),
by a Neumann series pruned at round-off (docs/condensation.md §2); and the same pruning of
the condensed entries before they are added to Kc.
"""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from mpi4py import MPI  # noqa: F401  (before petsc4py: the PyPI wheel needs it)
from petsc4py import PETSc

#: entries of the truncated inverse W below this fraction of their row's diagonal block
#: are dropped: eps/16, below round-off of the entries they would be added to
TRUNCATION = np.finfo(float).eps / 16
#: the Neumann series is used while ‖D⁻¹E‖∞ is below this; above, W is the dense inverse
NEUMANN_LIMIT = 0.5


class CondensationError(RuntimeError):
    """The multiplier blocks do not have the structure the condensation relies on."""


def inverse(M: sp.csr_matrix, first: np.ndarray, size: np.ndarray) -> sp.csr_matrix:
    """M⁻¹ for M = D + E with D block-diagonal (contiguous 1×1 and 2×2 blocks, one per
    slave node) and E the couplings of neighbouring nodes, its entries below TRUNCATION of
    their row's diagonal-block scale dropped. Where ‖D⁻¹E‖∞ is small (the dual basis: the
    forces of a node's neighbours on its rows are ~1e-3 of its own), the Neumann series
    Σ (−D⁻¹E)^k D⁻¹, each term reaching one node further along the chain; else the exact
    inverse by sparse LU, column block by column block, pruned alike.

    Args:
        M: The matrix, (n, n).
        first: The first row of each node's diagonal block.
        size: Each block's size (1 or 2).

    Returns:
        The pruned inverse, CSR.

    Raises:
        CondensationError: a singular diagonal block, or M singular.
    """
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


def below_round_off(D: sp.csr_matrix, rows: np.ndarray, diag: PETSc.Vec,
                    r0: int) -> sp.csr_matrix:
    """D without the entries below TRUNCATION of their row's scale (the larger of K's
    diagonal entry there and D's largest entry in the row): added to that row they change
    nothing beyond its round-off, and they would only widen the pattern (the truncated
    inverses' tails, ~1e-16 of the row, reach several nodes further along the chain).

    Args:
        D: The condensation's entries, one row per entry of ``rows``.
        rows: Their global rows (this rank's).
        diag: K's diagonal (destroyed here).
        r0: This rank's first row.

    Returns:
        D pruned, CSR.
    """
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
