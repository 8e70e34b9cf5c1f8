"""Contact terms → PETSc: nodal forces and the consistent tangent, sparsity up front.

With the weighted gaps g̃_j, nodal areas A_j and pressures p_j (DESIGN.md §4–5):

    R  = −Σ_j p_j ∇g̃_j
    K  = Σ_j (ε/A_j) ∇g̃_j ⊗ ∇g̃_j − (ε g̃_j/A_j²) ∇g̃_j ⊗ ∇A_j  − p_j ∇²g̃_j   (active j)

(∂p_j/∂x = −ε ∇g̃_j/A_j + ε g̃_j ∇A_j/A_j² while p_j > 0; the A-term makes K unsymmetric.)
Everything is built as scipy sparse matrices over the stacked surface coordinates
[slave x, slave y, …, master x, master y, …] and mapped to global dofs once.
"""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from petsc4py import PETSc

from .kernel import NodalContributions, nodal_sum


def gradient_matrix(c: NodalContributions, n_slave: int, n_coords: int) -> sp.csr_matrix:
    """Rows ∇q_j (q = g̃ or A) over the stacked coordinates, summed over contributions."""
    if c.size == 0:
        return sp.csr_matrix((n_slave, n_coords))
    gidx = c.global_indices(n_slave)
    rows = np.repeat(c.node, gidx.shape[1])
    return sp.csr_matrix((c.grad.ravel(), (rows, gidx.ravel())), shape=(n_slave, n_coords))


def hessian_sum(c: NodalContributions, weight: np.ndarray, n_slave: int,
                n_coords: int) -> sp.coo_matrix:
    """Σ_k weight[node_k] ∇²q_k over the stacked coordinates."""
    w = weight[c.node]
    keep = w != 0.0
    if not keep.any():
        return sp.coo_matrix((n_coords, n_coords))
    gidx = c.global_indices(n_slave)[keep]
    m = gidx.shape[1]
    rows = np.repeat(gidx, m, axis=1).ravel()
    cols = np.tile(gidx, (1, m)).ravel()
    vals = (c.hess[keep] * w[keep, None, None]).ravel()
    return sp.coo_matrix((vals, (rows, cols)), shape=(n_coords, n_coords))


def contact_terms(gap: NodalContributions, area: NodalContributions, enforcement,
                  n_slave: int, n_coords: int, weight: np.ndarray | None = None,
                  tangent: bool = True, touching: np.ndarray | None = None):
    """(g̃, A, p, active, R, K) over the stacked coordinates; ``weight`` (0/1 per slave
    node) selects the nodes whose terms this rank inserts; ``touching`` marks extra nodes
    that get the penalty stiffness in K (see PairHook.add_jacobian)."""
    g, A = nodal_sum(gap, n_slave), nodal_sum(area, n_slave)
    p, active = enforcement.pressure(g, A)
    w = np.ones(n_slave) if weight is None else weight
    G = gradient_matrix(gap, n_slave, n_coords)
    R = -(G.T @ (p * w))
    K = None
    if tangent:
        eps = enforcement.epsilon
        act = (active if touching is None else active | touching) * w
        As = np.where(A > 0, A, 1.0)
        GA = gradient_matrix(area, n_slave, n_coords)
        K = (G.T @ sp.diags(act * eps / As) @ G
             - G.T @ sp.diags(act * eps * g / As**2) @ GA
             - hessian_sum(gap, p * w, n_slave, n_coords))
    return g, A, p, active, R, K


def friction_terms(slip: NodalContributions, t: np.ndarray, dt_dg: np.ndarray,
                   dt_dp: np.ndarray, A: np.ndarray, g: np.ndarray, active: np.ndarray,
                   G: sp.spmatrix, GA: sp.spmatrix, epsilon: np.ndarray, n_slave: int,
                   n_coords: int, weight: np.ndarray, tangent: bool = True):
    """Tangential terms (friction.py): R_T = Σ_j A_j t_j ∇g_T,j and

        K_T = Σ_j A_j ∂t/∂g_T ∇g_T⊗∇g_T + A_j t_j ∇²g_T + t_j ∇g_T⊗∇A_j
                  + A_j ∂t/∂p ∇g_T⊗∇p_j ,   ∇p_j = −ε (∇g̃_j/A_j − g̃_j ∇A_j/A_j²)."""
    GT = gradient_matrix(slip, n_slave, n_coords)
    R = GT.T @ (A * t * weight)
    if not tangent:
        return R, None
    As = np.where(A > 0, A, 1.0)
    act = active * weight
    Gp = -(sp.diags(epsilon * act / As) @ G - sp.diags(epsilon * act * g / As**2) @ GA)
    K = (GT.T @ sp.diags(A * dt_dg * weight) @ GT
         + hessian_sum(slip, A * t * weight, n_slave, n_coords)
         + GT.T @ sp.diags(t * weight) @ GA
         + GT.T @ sp.diags(A * dt_dp * weight) @ Gp)
    return R, K


def add_to_vector(b: PETSc.Vec, dofs: np.ndarray, values: np.ndarray) -> None:
    """b[dofs] += values (global dof numbers; off-process entries are communicated)."""
    nz = values != 0.0
    b.setValues(dofs[nz].astype(PETSc.IntType), values[nz], addv=PETSc.InsertMode.ADD)
    b.assemble()


def add_to_matrix(A: PETSc.Mat, K: sp.spmatrix, dofs: np.ndarray, skip: np.ndarray,
                  n_global: int) -> None:
    """A[dofs, dofs] += K, leaving out the rows and columns of Dirichlet dofs ``skip``
    (the matrix keeps identity rows/columns there)."""
    K = K.tocoo()
    r, c = dofs[K.row], dofs[K.col]
    keep = (K.data != 0.0) & ~np.isin(r, skip) & ~np.isin(c, skip)
    r, c, v = r[keep], c[keep], K.data[keep]
    r0, r1 = A.getOwnershipRange()
    own = (r >= r0) & (r < r1)
    # owned rows in one CSR call (its rows count from the ownership range start)
    M = sp.csr_matrix((v[own], (r[own] - r0, c[own])), shape=(r1 - r0, n_global))
    A.setValuesCSR(M.indptr.astype(PETSc.IntType), M.indices.astype(PETSc.IntType),
                   M.data, addv=PETSc.InsertMode.ADD)
    if not own.all():  # rows of another rank (MPI): row by row, PETSc communicates them
        M = sp.csr_matrix((v[~own], (r[~own], c[~own])), shape=(n_global, n_global))
        for row in np.flatnonzero(np.diff(M.indptr)):
            sl = slice(M.indptr[row], M.indptr[row + 1])
            A.setValues([row], M.indices[sl].astype(PETSc.IntType), M.data[sl],
                        addv=PETSc.InsertMode.ADD)


def create_matrix(a_form, blocks: list[np.ndarray], V) -> PETSc.Mat:
    """Bulk sparsity plus the contact couplings ``blocks`` (each: global node-block numbers
    that couple all-to-all), written once with zeros so PETSc keeps the slots. Couplings
    beyond the prediction (large sliding) still go in, by dynamic allocation."""
    from .. import _dolfinx as dx
    im = V.dofmap.index_map
    n_local = im.size_local + im.num_ghosts
    l2g = im.local_to_global(np.arange(n_local, dtype=np.int32))
    order = np.argsort(l2g)
    sparsity = dx.sparsity_pattern(a_form)
    known = []
    for blk in blocks:
        pos = np.searchsorted(l2g, blk, sorter=order)
        pos = np.minimum(pos, len(order) - 1)
        local = order[pos][l2g[order[pos]] == blk].astype(np.int32)
        if len(local):
            sparsity.insert(local, local)
            known.append(local)
    A = dx.matrix_from_sparsity(a_form, sparsity)
    bs = V.dofmap.index_map_bs
    for local in known:
        g = (l2g[local][:, None] * bs + np.arange(bs)).ravel().astype(PETSc.IntType)
        A.setValues(g, g, np.zeros((len(g), len(g))), addv=PETSc.InsertMode.ADD)
    A.assemble()
    A.setOption(PETSc.Mat.Option.NEW_NONZERO_ALLOCATION_ERR, False)
    return A
