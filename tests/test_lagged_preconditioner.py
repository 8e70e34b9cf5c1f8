"""A Krylov solve that keeps its AMG preconditioner between Newton iterations
(condensation/ksp.py Lag, solve_lagged) solves the current system, not the one the
preconditioner was built for: a slightly changed matrix is solved with the kept one; a
very different one exceeds the kept one's budget and is solved again with a fresh one."""
import mpi4py.MPI  # noqa: F401
import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from petsc4py import PETSc

from fenicsx_mortar.condensation.ksp import Lag, solve_lagged

N = 40


def laplacian(kx: float) -> sp.csr_matrix:
    """-kx ∂xx - ∂yy on an N×N grid (Dirichlet)."""
    t = sp.diags([-1.0, 2.0, -1.0], [-1, 0, 1], shape=(N, N))
    eye = sp.identity(N)
    return sp.csr_matrix(kx * sp.kron(eye, t) + sp.kron(t, eye))


def petsc(A: sp.csr_matrix) -> PETSc.Mat:
    return PETSc.Mat().createAIJ(A.shape, csr=(A.indptr.astype(PETSc.IntType),
                                               A.indices.astype(PETSc.IntType), A.data),
                                 comm=PETSc.COMM_SELF)


def test_a_kept_preconditioner_solves_the_current_matrix():
    rtol = 1e-10
    ksp = PETSc.KSP().create(PETSc.COMM_SELF)
    ksp.setType("gmres")
    ksp.getPC().setType("gamg")
    ksp.setPCSide(PETSc.PC.Side.RIGHT)
    ksp.setNormType(PETSc.KSP.NormType.UNPRECONDITIONED)
    ksp.setTolerances(rtol=rtol, max_it=1000)
    rng = np.random.default_rng(0)
    b = rng.standard_normal(N * N)
    lag = Lag()
    for kx, kept in ((1.0, False), (1.02, True), (1e4, True)):
        A = laplacian(kx)
        M = petsc(A)
        ksp.setOperators(M)
        f, y = M.createVecs()
        f.array[:] = b
        budget = lag.budget(rtol) if kept else None
        assert lag.reuse == kept
        its, reason = solve_lagged(ksp, lag, f, y)
        assert reason > 0
        x = spla.spsolve(sp.csc_matrix(A), b)
        assert np.linalg.norm(A @ y.array - b) <= 1.01 * rtol * np.linalg.norm(b)
        assert np.allclose(y.array, x, rtol=1e-6, atol=1e-8 * np.abs(x).max())
        if kx == 1e4:
            # the isotropic hierarchy on a strongly anisotropic operator: stopped at its
            # budget, solved again with a hierarchy of the new operator
            assert its > budget
            assert lag.reuse
        M.destroy()
    ksp.destroy()
