"""Contact terms → PETSc: nodal forces and the consistent tangent.

With the weighted gaps g̃_j, nodal areas A_j and pressures p_j (docs/design.md §4–5):

    R  = −Σ_j p_j ∇g̃_j
    K  = Σ_j (ε/A_j) ∇g̃_j ⊗ ∇g̃_j − (ε g̃_j/A_j²) ∇g̃_j ⊗ ∇A_j  − p_j ∇²g̃_j   (active j)

(∂p_j/∂x = −ε ∇g̃_j/A_j + ε g̃_j ∇A_j/A_j² while p_j > 0; the A-term makes K unsymmetric.)
Everything is built as scipy sparse matrices over the stacked surface coordinates
[slave x, slave y, …, master x, master y, …] and mapped to global dofs once, on insertion
into the matrix whose sparsity the pair predicted (:meth:`.pair.ContactPair.couplings`).

Cost (issue 7): K is returned as COO triplets with repeated entries (the node-a and node-b
Hessians of a mortar pair come as one weighted sum over their common local coordinates,
formed by the kernel on demand for the pairs with a node in contact; Gᵀ C as the products
of each row's entries); they are summed once, on insertion. The layouts (which triplet
lands in which CSR slot) of the gradient matrices and of the insertion into PETSc are kept
while the structure repeats between Newton iterations, so a repeated structure costs
bincounts instead of sorts; the gradient matrix is cached on its contributions (residual
and tangent of one iterate share it).
"""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from mpi4py import MPI  # before petsc4py: the PyPI wheel needs it
from petsc4py import PETSc

from .kernel import NodalContributions


class Layouts:
    """Index layouts kept while the structure repeats between Newton iterations (which
    triplet lands in which CSR slot, the dense Hessian blocks' indices, the Lᵀ C products,
    the insertion into PETSc). One per contact pair, so that two pairs do not evict each
    other's layouts at every iteration."""

    def __init__(self):
        self.csr: dict = {}
        self.blocks: list = []
        self.outer: list = []
        self.insertion = None
        self.skipped = None


#: for callers outside a pair (tests, benchmarks)
_shared = Layouts()


def _gidx(c: NodalContributions, n_slave: int) -> np.ndarray:
    """c.global_indices(n_slave), cached on the contributions."""
    key = ("gidx", n_slave)
    gidx = c.cache.get(key)
    if gidx is None:
        gidx = c.cache[key] = c.global_indices(n_slave)
    return gidx


def _rows(c: NodalContributions, m: int) -> np.ndarray:
    """The node of each contribution repeated over its m local coordinates (cached)."""
    key = ("rows", m)
    rows = c.cache.get(key)
    if rows is None:
        rows = c.cache[key] = np.repeat(c.node, m)
    return rows


def _csr(vals, rows, cols, shape, lay: Layouts) -> sp.csr_matrix:
    """CSR from COO triplets (duplicates summed). The layout (which triplet goes to which
    slot) is kept for the last few structures: when the same (rows, cols) come again (the
    next Newton iteration; the gap and area gradients share it) the values are summed into
    it with one bincount instead of a sort."""
    key = (shape, rows.shape[0])
    layouts = lay.csr
    lay = layouts.get(key)
    if lay is None or not (np.array_equal(lay[0], rows) and np.array_equal(lay[1], cols)):
        n_cols = np.int64(shape[1])
        uniq, slot = np.unique(rows.astype(np.int64) * n_cols + cols, return_inverse=True)
        itype = np.int32 if max(shape) < 2**31 - 1 else np.int64
        indptr = np.zeros(shape[0] + 1, dtype=itype)
        np.cumsum(np.bincount(uniq // n_cols, minlength=shape[0]), out=indptr[1:])
        lay = (rows.copy(), cols.copy(), slot, (uniq % n_cols).astype(itype), indptr)
        if len(layouts) >= 8:
            layouts.clear()
        layouts[key] = lay
    data = np.bincount(lay[2], weights=vals, minlength=lay[3].shape[0])
    M = sp.csr_matrix((data, lay[3].copy(), lay[4].copy()), shape=shape)
    M.has_sorted_indices = True
    return M


def gradient_matrix(c: NodalContributions, n_slave: int, n_coords: int,
                    lay: Layouts = _shared) -> sp.csr_matrix:
    """Rows ∇q_j (q = g̃ or A) over the stacked coordinates, summed over contributions.

    Cached on ``c`` (the residual and the tangent of one iterate share it); treat the
    result as read-only."""
    if c.size == 0:
        return sp.csr_matrix((n_slave, n_coords))
    key = ("G", n_slave, n_coords)
    hit = c.cache.get(key)
    if hit is not None and hit[0] is c.grad:
        return hit[1]
    gidx = _gidx(c, n_slave)
    G = _csr(c.grad.ravel(), _rows(c, gidx.shape[1]), gidx.ravel(), (n_slave, n_coords), lay)
    c.cache[key] = (c.grad, G)
    return G


def _halves(c: NodalContributions, n_slave: int) -> bool:
    """Whether contributions k and k + K/2 have the same local coordinates (the mortar
    kernel's node-a and node-b rows of a pair): their Hessians can then be summed before
    they are scattered (cached)."""
    hit = c.cache.get("halves")
    if hit is None:
        K = c.size
        gidx = _gidx(c, n_slave)
        hit = c.cache["halves"] = bool(K % 2 == 0 and K > 0
                                       and np.array_equal(gidx[:K // 2], gidx[K // 2:]))
    return hit


def _pair_weights(c: NodalContributions, w: np.ndarray):
    """For contributions in halves (:func:`_halves`): the weights of the node-a and node-b
    rows of the pairs with a nonzero one, and those pairs (a slice when all)."""
    h = c.size // 2
    wa, wb = w[:h], w[h:]
    on = (wa != 0.0) | (wb != 0.0)
    keep = slice(0, h) if on.all() else np.flatnonzero(on)
    return wa[keep], wb[keep], keep


def _hessian_triplets(c: NodalContributions, weight: np.ndarray, n_slave: int,
                      lay: Layouts = _shared):
    """(rows, cols, vals) of Σ_k weight[node_k] ∇²q_k (contributions with weight ≠ 0;
    repeated (row, col) entries are to be summed)."""
    w = weight[c.node]
    gidx = _gidx(c, n_slave)
    if _halves(c, n_slave):
        # node-a and node-b rows of a pair share their coordinates: one weighted Hessian
        # per pair (the mortar kernel forms just these, NodalContributions.pair_hessian)
        wa, wb, keep = _pair_weights(c, w)
        vals = c.pair_hessian(wa, wb, keep).ravel()
    else:
        keep = np.flatnonzero(w != 0.0)
        vals = (c.hess[keep] * w[keep, None, None]).ravel()
    rows, cols = _block_indices(gidx[keep], lay)
    return rows, cols, vals


def _block_indices(gidx: np.ndarray, lay: Layouts):
    """Row and column indices of the dense m × m blocks over the rows of gidx (k, m),
    flattened row-major; in the sparse index type; the last result is reused while the
    structure repeats (between Newton iterations)."""
    blocks = lay.blocks
    if blocks and np.array_equal(blocks[0], gidx):
        return blocks[1], blocks[2]
    m = gidx.shape[1]
    g = gidx.astype(np.int32) if gidx.size and gidx.max() < 2**31 - 1 else gidx
    rows = np.repeat(g, m, axis=1).ravel()
    cols = np.tile(g, (1, m)).ravel()
    rows.setflags(write=False)
    cols.setflags(write=False)
    blocks[:] = [gidx.copy(), rows, cols]
    return rows, cols


def hessian_sum(c: NodalContributions, weight: np.ndarray, n_slave: int,
                n_coords: int, lay: Layouts = _shared) -> sp.coo_matrix:
    """Σ_k weight[node_k] ∇²q_k over the stacked coordinates (COO, repeated entries to be
    summed)."""
    if c.size == 0 or not np.any(weight[c.node] != 0.0):
        return sp.coo_matrix((n_coords, n_coords))
    rows, cols, vals = _hessian_triplets(c, weight, n_slave, lay)
    return sp.coo_matrix((vals, (rows, cols)), shape=(n_coords, n_coords))


def test_matrix(gap: NodalContributions, n_slave: int, n_test: int,
                lay: Layouts = _shared) -> sp.csr_matrix:
    """Rows T_j (the Petrov–Galerkin test vectors ``gap.test``, mortar.py) over the stacked
    node coordinates (n_test = 2 (n_slave + n_master)); cached on ``gap``."""
    key = ("T", n_slave, n_test)
    hit = gap.cache.get(key)
    if hit is None:
        t = gap.test
        hit = gap.cache[key] = _csr(t.grad.ravel(), np.repeat(gap.node, 8),
                                    t.global_indices(n_slave).ravel(), (n_slave, n_test), lay)
    return hit


def _test_jacobian_triplets(gap: NodalContributions, weight: np.ndarray, n_slave: int,
                            lay: Layouts = _shared):
    """(rows, cols, vals) of Σ_k weight[node_k] ∂T_k/∂x: rows in the node coordinates of
    the test vectors, columns in the gap's local (curve-point) coordinates."""
    t = gap.test
    w = weight[gap.node]
    rg = t.global_indices(n_slave)
    cg = _gidx(gap, n_slave)
    h = gap.size // 2
    if _halves(gap, n_slave) and np.array_equal(t.nodes[:h], t.nodes[h:]):
        # as in _hessian_triplets: one weighted Jacobian per pair
        wa, wb, keep = _pair_weights(gap, w)
        vals = t.pair_jacobian(wa, wb, keep)
        rg, cg = rg[:h][keep], cg[:h][keep]
    else:
        keep = np.flatnonzero(w != 0.0)
        vals = t.jac[keep] * w[keep, None, None]
        rg, cg = rg[keep], cg[keep]
    rows = np.broadcast_to(rg[:, :, None], vals.shape).ravel()
    cols = np.broadcast_to(cg[:, None, :], vals.shape).ravel()
    return rows, cols, vals.ravel()


def _outer_rows(L: sp.csr_matrix, C: sp.csr_matrix, lay: Layouts):
    """(rows, cols, vals) of Lᵀ C = Σ_j L_j ⊗ C_j over the common rows j (repeated entries
    to be summed, as the insertion does anyway): one product per pair of entries of a row,
    gathered through an index layout that is kept while the patterns repeat (Newton
    iterations) — cheaper than a sparse matrix product and its conversions."""
    outer = lay.outer
    lay = outer[0] if outer else None
    if lay is None or not all(a.shape == b.shape and np.array_equal(a, b) for a, b in
                              zip(lay[0], (L.indptr, L.indices, C.indptr, C.indices))):
        lc, cc = np.diff(L.indptr), np.diff(C.indptr)
        row = np.repeat(np.arange(lc.shape[0]), lc)          # the row of each entry of L
        size = cc[row]                                      # its products: the row of C
        a = np.repeat(np.arange(L.indptr[-1]), size)
        start = np.cumsum(size) - size
        b = np.repeat(C.indptr[row] - start, size) + np.arange(size.sum())
        lay = ((L.indptr.copy(), L.indices.copy(), C.indptr.copy(), C.indices.copy()),
               a, b, L.indices[a], C.indices[b])
        outer[:] = [lay]
    _, a, b, rows, cols = lay
    return rows, cols, L.data[a] * C.data[b]


def _tangent(gap: NodalContributions, area: NodalContributions, d1: np.ndarray,
             d2: np.ndarray, hw: np.ndarray, n_slave: int, n_coords: int,
             G: sp.csr_matrix, lay: Layouts, left: sp.csr_matrix | None = None
             ) -> sp.coo_matrix:
    """Σ_j d1_j ∇g̃_j ⊗ ∇g̃_j − d2_j ∇g̃_j ⊗ ∇A_j − Σ_k hw[node_k] ∇²g̃_k, i.e.
    Gᵀ (D1 G − D2 G_A) − H, as COO triplets with repeated entries (summed on insertion;
    ``tocsr()`` sums them too). With test vectors (``left`` = their matrix T, rows over the
    node coordinates): Tᵀ (D1 G − D2 G_A) − Σ_k hw[node_k] ∂T_k/∂x."""
    shape = (n_coords if left is None else left.shape[1], n_coords)
    if left is None:
        left = G
    on = (d1 != 0.0) | (d2 != 0.0)
    parts_r, parts_c, parts_v = [], [], []
    if gap.size and on.any():
        # C = D1 G − D2 G_A in one CSR build over the contributions of nodes with a factor
        sg = np.flatnonzero(on[gap.node])
        sa = np.flatnonzero(on[area.node]) if area.size else sg[:0]
        gg = _gidx(gap, n_slave)[sg]
        nd = gap.node[sg]
        vals = [(gap.grad[sg] * d1[nd, None]).ravel()]
        rows, cols = [np.repeat(nd, gg.shape[1])], [gg.ravel()]
        if len(sa):
            ga = _gidx(area, n_slave)[sa]
            na = area.node[sa]
            vals.append((area.grad[sa] * -d2[na, None]).ravel())
            rows.append(np.repeat(na, ga.shape[1]))
            cols.append(ga.ravel())
        C = _csr(np.concatenate(vals), np.concatenate(rows), np.concatenate(cols),
                 (n_slave, n_coords), lay)
        r, c, v = _outer_rows(left, C, lay)
        parts_r.append(r), parts_c.append(c), parts_v.append(v)
    if gap.size and np.any(hw[gap.node] != 0.0):
        if gap.test is None:
            r, c, v = _hessian_triplets(gap, hw, n_slave, lay)
        else:
            r, c, v = _test_jacobian_triplets(gap, hw, n_slave, lay)
        parts_r.append(r), parts_c.append(c), parts_v.append(-v)
    if not parts_r:
        return sp.coo_matrix(shape)
    return sp.coo_matrix((np.concatenate(parts_v),
                          (np.concatenate(parts_r), np.concatenate(parts_c))), shape=shape)


def normal_force(st, weight: np.ndarray) -> np.ndarray:
    """−Σ_j weight_j ∇g̃_j over the pair's stacked node coordinates [slave, master] (with
    Petrov–Galerkin test vectors on the gap, mortar.py: −Σ_j weight_j T_j); ``weight`` is
    usually the pressure times the 0/1 selection of this rank's nodes."""
    if st.gap.test is not None:
        T = test_matrix(st.gap, st.n_slave, st.n_test, st.layouts)
        return -(T.T @ weight)
    return st.to_nodes(-(st.G.T @ weight))


def normal_tangent(st, d1: np.ndarray, d2: np.ndarray, hw: np.ndarray) -> sp.spmatrix:
    """The tangent of :func:`normal_force` with weight = p w for a nodal law p(g̃, A):
    d1 = −∂p/∂g̃ w and d2 = ∂p/∂A w on the nodes whose law is differentiated (the active
    ones), hw = p w (docs/design.md §5)::

        K = Σ_j d1_j ∇g̃_j ⊗ ∇g̃_j − d2_j ∇g̃_j ⊗ ∇A_j − hw_j ∇²g̃_j

    (∂p_j/∂x = −ε ∇g̃_j/A_j + ε g̃_j ∇A_j/A_j² for the penalty law; the A-term makes K
    unsymmetric). Over the stacked node coordinates, COO with repeated entries."""
    left = None
    if st.gap.test is not None:
        left = test_matrix(st.gap, st.n_slave, st.n_test, st.layouts)
    K = _tangent(st.gap, st.area, d1, d2, hw, st.n_slave, st.n_coords, st.G, st.layouts,
                 left)
    return st.to_nodes(K=K, rows_in_nodes=left is not None)


def test_rows(st) -> sp.csr_matrix:
    """(n_slave, n_test): the rows T_j over the stacked node coordinates along which node
    j's pressure acts, −p_j T_j (∇g̃_j, or the Petrov–Galerkin test vector)."""
    if st.gap.test is not None:
        return test_matrix(st.gap, st.n_slave, st.n_test, st.layouts)
    return sp.csr_matrix(st.to_nodes(K=st.G, rows_in_nodes=True))


def pressure_rows(st, dp_dg: np.ndarray, dp_dA: np.ndarray) -> sp.csr_matrix:
    """(n_slave, n_test): ∇p_j = ∂p/∂g̃ ∇g̃_j + ∂p/∂A ∇A_j over the stacked node
    coordinates, for the given nodal derivatives (zero rows where they are zero)."""
    rows = sp.diags(dp_dg) @ st.G + sp.diags(dp_dA) @ st.G_area
    return sp.csr_matrix(st.to_nodes(K=rows, rows_in_nodes=True))


def friction_terms(st, slip: NodalContributions, t: np.ndarray, dt_dg: np.ndarray,
                   dt_dp: np.ndarray, weight: np.ndarray, tangent: bool = True):
    """Tangential terms (friction.py) of the state ``st``: R_T = Σ_j W_j t_j ∇g_T,j and

        K_T = Σ_j W_j ∂t/∂g_T ∇g_T⊗∇g_T + W_j t_j ∇²g_T + t_j ∇g_T⊗∇W_j
                  + W_j ∂t/∂p ∇g_T⊗∇p_j ,   ∇p_j = ∂p/∂g̃ ∇g̃_j + ∂p/∂A ∇A_j

    with W_j the load area of node j's pressure (``st.tangential.load``: ∫ψ_j, the nodal
    area A_j but for the dual basis on partly supported segments) and the enforcement's own
    ∂p/∂g̃, ∂p/∂A (``st.law``) on its active nodes, so any nodal law (not only
    ⟨p̂ − ε g̃/A⟩₊) gets its exact friction tangent.

    Returns:
        (R_T, K_T) over the kernels' coordinates (K_T None unless ``tangent``).
    """
    n_slave, n_coords, lay = st.n_slave, st.n_coords, st.layouts
    W, GW = st.tangential.load, st.tangential.load_rows
    GT = gradient_matrix(slip, n_slave, n_coords, lay)
    R = GT.T @ (W * t * weight)
    if not tangent:
        return R, None
    act = st.active * weight
    law = st.law
    Gp = sp.diags(law.dp_dg * act) @ st.G + sp.diags(law.dp_dA * act) @ st.G_area
    K = (GT.T @ sp.diags(W * dt_dg * weight) @ GT
         + hessian_sum(slip, W * t * weight, n_slave, n_coords, lay)
         + GT.T @ sp.diags(t * weight) @ GW()
         + GT.T @ sp.diags(W * dt_dp * weight) @ Gp)
    return R, K


def add_to_vector(b: PETSc.Vec, dofs: np.ndarray, values: np.ndarray) -> None:
    """b[dofs] += values (global dof numbers; off-process entries are communicated)."""
    nz = values != 0.0
    b.setValues(dofs[nz].astype(PETSc.IntType), values[nz], addv=PETSc.InsertMode.ADD)
    b.assemble()


def _skipped(dofs: np.ndarray, skip: np.ndarray, lay: Layouts) -> np.ndarray:
    """Boolean mask over ``dofs``: which are in ``skip`` (kept for the same arrays)."""
    hit = lay.skipped
    if hit is not None and hit[0] is dofs and hit[1] is skip:
        return hit[2]
    mask = np.isin(dofs, skip)
    lay.skipped = (dofs, skip, mask)
    return mask


class _Pattern:
    """The CSR layout of the last insertion into a matrix: for the same triplet structure
    (the usual case between Newton iterations) the values are summed into it with one
    bincount instead of a fresh COO → CSR conversion (sort). The CSR holds the touched
    rows only (``rows``: their global numbers), not the whole ownership range: PETSc then
    visits a few hundred rows instead of every local row. It keeps the matrix's ownership
    range, not the matrix: a reference would keep the matrix alive on the ranks that cache
    a layout and not on the others, and PETSc's next collective creation on that
    communicator then deadlocks (one rank duplicates the communicator, the other not)."""

    __slots__ = ("range", "dofs", "skip", "row", "col", "sel", "slot", "indptr", "indices",
                 "rows")


def _repeats(pat: _Pattern | None, K: sp.coo_matrix, dofs: np.ndarray,
             skip: np.ndarray) -> bool:
    """Whether ``K`` has the triplet structure of the insertion ``pat``."""
    return (pat is not None and pat.dofs is dofs and pat.skip is skip
            and np.array_equal(pat.row, K.row) and np.array_equal(pat.col, K.col))


def new_slots(K: sp.spmatrix, dofs: np.ndarray, skip: np.ndarray,
              lay: Layouts = _shared) -> tuple[np.ndarray, np.ndarray]:
    """The global (rows, columns) :func:`add_to_matrix` would insert ``K`` at, when its
    triplet structure is not that of the last insertion (else none: those slots exist)."""
    K = K.tocoo()
    if _repeats(lay.insertion, K, dofs, skip):
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    out = _skipped(dofs, skip, lay)
    sel = ~out[K.row] & ~out[K.col]
    return dofs[K.row[sel]].astype(np.int64), dofs[K.col[sel]].astype(np.int64)


def pattern_with(indptr: np.ndarray, indices: np.ndarray, n_cols: int,
                 rows: np.ndarray | None = None, cols: np.ndarray | None = None
                 ) -> sp.csr_matrix:
    """A CSR pattern (rows local, columns global) with the slots (rows, cols) added,
    sorted (values: ones).

    Args:
        indptr, indices: The pattern.
        n_cols: The number of columns.
        rows, cols: Slots to add (local rows).

    Returns:
        The pattern as an int8 matrix.
    """
    P = sp.csr_matrix((np.ones(len(indices), dtype=np.int8), indices, indptr),
                      shape=(len(indptr) - 1, n_cols))
    if rows is not None and len(rows):
        P = P + sp.csr_matrix((np.ones(len(rows), dtype=np.int8), (rows, cols)), shape=P.shape)
    P.sort_indices()
    return P


def reserve(A: PETSc.Mat, rows: np.ndarray, cols: np.ndarray) -> bool:
    """Give the assembled ``A`` the slots (rows, cols) (global, any rank's rows) it lacks,
    in one re-preallocation: PETSc's own growth copies the whole matrix for every row that
    overflows, a few thousand times when a slave slides past new master nodes (large
    sliding at 242k dofs: 25 s of a 131 s run). ``A``'s values are lost when it grows:
    call it before the assembly. Collective.

    Returns:
        Whether ``A`` grew.
    """
    comm = A.getComm().tompi4py()
    if comm.size > 1:
        parts = comm.allgather((rows, cols))
        rows = np.concatenate([r for r, _ in parts])
        cols = np.concatenate([c for _, c in parts])
    if not len(rows):       # the tangents' structure repeats: their slots are there
        return False
    r0, r1 = A.getOwnershipRange()
    own = (rows >= r0) & (rows < r1)
    rows, cols = rows[own] - r0, cols[own]
    missing = _missing_slots(A, r0, rows, cols)
    if not comm.allreduce(bool(missing.any()), op=MPI.LOR):
        return False
    indptr, indices, _ = A.getValuesCSR()
    P = pattern_with(indptr, indices, A.getSize()[1], rows[missing], cols[missing])
    A.setPreallocationCSR((P.indptr.astype(PETSc.IntType), P.indices.astype(PETSc.IntType)))
    A.setOption(PETSc.Mat.Option.NEW_NONZERO_ALLOCATION_ERR, False)
    return True


def _missing_slots(A: PETSc.Mat, r0: int, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
    """Which slots (local rows, global columns) the assembled ``A`` lacks, from the rows
    asked about only, not a copy of the whole pattern (under MPI, where the tangents'
    insertion structure is not remembered, it is asked at every Newton iteration)."""
    if not len(rows):
        return np.zeros(0, dtype=bool)
    n = np.int64(A.getSize()[1])
    have = [np.asarray(A.getRow(int(r0 + r))[0], dtype=np.int64) + n * r
            for r in np.unique(rows).astype(np.int64)]
    return ~np.isin(rows.astype(np.int64) * n + cols.astype(np.int64), np.concatenate(have))


def add_to_matrix(A: PETSc.Mat, K: sp.spmatrix, dofs: np.ndarray, skip: np.ndarray,
                  n_global: int, lay: Layouts = _shared) -> None:
    """A[dofs, dofs] += K, leaving out the rows and columns of Dirichlet dofs ``skip``
    (the matrix keeps identity rows/columns there)."""
    K = K.tocoo()
    pat = lay.insertion
    r0, r1 = A.getOwnershipRange()
    if _repeats(pat, K, dofs, skip) and pat.range == (r0, r1):
        vals = np.bincount(pat.slot, weights=K.data[pat.sel], minlength=pat.indices.shape[0])
        A.setValuesIJV(pat.indptr, pat.indices, vals, addv=PETSc.InsertMode.ADD,
                       rowmap=pat.rows)
        return
    out = _skipped(dofs, skip, lay)
    structural = ~out[K.row] & ~out[K.col]
    r = dofs[K.row]
    if np.all((r[structural] >= r0) & (r[structural] < r1)):
        # serial (or all rows owned): remember the layout of all structural entries (explicit
        # zeros included: adding 0 changes no value, and the slots lie in the contact
        # couplings preallocated with the matrix)
        sel = np.flatnonzero(structural)
        rl = (r[sel] - r0).astype(np.int64)
        cl = dofs[K.col[sel]].astype(np.int64)
        key = rl * np.int64(n_global) + cl
        uniq, slot = np.unique(key, return_inverse=True)
        rows, count = np.unique(uniq // n_global, return_counts=True)
        indptr = np.zeros(rows.shape[0] + 1, dtype=PETSc.IntType)
        np.cumsum(count, out=indptr[1:])
        pat = _Pattern()
        pat.range, pat.dofs, pat.skip = (r0, r1), dofs, skip
        pat.row, pat.col = K.row.copy(), K.col.copy()
        pat.sel, pat.slot = sel, slot
        pat.indptr, pat.indices = indptr, (uniq % n_global).astype(PETSc.IntType)
        pat.rows = (rows + r0).astype(PETSc.IntType)
        lay.insertion = pat
        vals = np.bincount(slot, weights=K.data[sel], minlength=uniq.shape[0])
        A.setValuesIJV(pat.indptr, pat.indices, vals, addv=PETSc.InsertMode.ADD,
                       rowmap=pat.rows)
        return
    # explicit zeros too: new_slots reserved their slots, and a slot left empty is dropped
    # at the assembly's end, to be reserved again (on 2 ranks the Jacobian grew, and MUMPS
    # analysed it afresh, at every Newton iteration)
    keep = structural
    r, c, v = r[keep], dofs[K.col[keep]], K.data[keep]
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
