"""A Jacobian whose contact couplings outgrow its preallocated pattern (a slave sliding
past new master nodes) grows once, before the assembly (contact/assembly.py reserve),
instead of PETSc reallocating the whole matrix for every row that overflows."""
import mpi4py.MPI  # noqa: F401
import numpy as np
import scipy.sparse as sp
from petsc4py import PETSc

from fenicsx_mortar.contact.assembly import reserve

N = 30


def laplacian() -> sp.csr_matrix:
    t = sp.diags([-1.0, 2.0, -1.0], [-1, 0, 1], shape=(N, N))
    return sp.csr_matrix(sp.kron(sp.identity(N), t) + sp.kron(t, sp.identity(N)))


def assemble(A: PETSc.Mat, M: sp.csr_matrix) -> None:
    A.zeroEntries()
    C = M.tocoo()
    for i, j, v in zip(C.row, C.col, C.data):
        A.setValue(int(i), int(j), v, addv=PETSc.InsertMode.ADD)
    A.assemble()


def test_reserve_grows_the_pattern_once_and_keeps_the_sums():
    L = laplacian()
    A = PETSc.Mat().createAIJ(L.shape, comm=PETSc.COMM_SELF,
                              csr=(L.indptr.astype(PETSc.IntType),
                                   L.indices.astype(PETSc.IntType), L.data))
    A.setOption(PETSc.Mat.Option.NEW_NONZERO_ALLOCATION_ERR, False)
    rng = np.random.default_rng(3)
    rows = rng.integers(0, N * N, 200)
    cols = rng.integers(0, N * N, 200)
    new = sp.csr_matrix((rng.standard_normal(200), (rows, cols)), shape=L.shape)
    assert reserve(A, rows.astype(np.int64), cols.astype(np.int64))
    assemble(A, L + new)
    assert A.getInfo()["mallocs"] == 0
    indptr, indices, vals = A.getValuesCSR()
    got = sp.csr_matrix((vals, indices, indptr), shape=L.shape)
    assert abs(got - (L + new)).max() == 0.0
    # the slots are there now: nothing to grow, and the next assembly allocates nothing
    assert not reserve(A, rows.astype(np.int64), cols.astype(np.int64))
    assemble(A, L + 2.0 * new)
    assert A.getInfo()["mallocs"] == 0
    A.destroy()
