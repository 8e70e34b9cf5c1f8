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


def gmres(pc: str, rtol: float) -> PETSc.KSP:
    """Right-preconditioned GMRES with ``pc``, as the condensed path's Krylov solve."""
    ksp = PETSc.KSP().create(PETSc.COMM_SELF)
    ksp.setType("gmres")
    ksp.getPC().setType(pc)
    ksp.setPCSide(PETSc.PC.Side.RIGHT)
    ksp.setNormType(PETSc.KSP.NormType.UNPRECONDITIONED)
    ksp.setTolerances(rtol=rtol, max_it=1000)
    return ksp


def test_a_kept_preconditioner_solves_the_current_matrix():
    rtol = 1e-10
    ksp = gmres("gamg", rtol)
    rng = np.random.default_rng(0)
    b = rng.standard_normal(N * N)
    lag = Lag()
    for kx, kept in ((1.0, False), (1.02, True), (1e4, True)):
        A = laplacian(kx)
        M = petsc(A)
        ksp.setOperators(M)
        f, y = M.createVecs()
        f.array[:] = b
        budget = lag.budget(rtol, False) if kept else None
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


def test_a_weak_preconditioner_hands_over_to_a_kept_factorization():
    """A fresh preconditioner slower than Lag.slow decades an iteration stops at that
    rate's budget and leaves the record weak; the direct KSP that replaces it (GMRES on a
    MUMPS factorization) solves to the tolerance, and solves a slightly changed matrix with
    the kept factorization in a few iterations."""
    from fenicsx_mortar.condensation.ksp import direct_ksp
    rtol = 1e-10
    amg = gmres("jacobi", rtol)
    b = np.random.default_rng(1).standard_normal(N * N)
    A = laplacian(1.0)
    M = petsc(A)
    amg.setOperators(M)
    f, y = M.createVecs()
    f.array[:] = b
    lag = Lag()
    its, reason = solve_lagged(amg, lag, f, y)
    # Jacobi on a 40 x 40 Laplacian: about 0.03 decades an iteration
    assert lag.weak and reason < 0 and its == lag.budget(rtol, True)
    direct, dlag = direct_ksp(amg)
    assert direct.getOptionsPrefix() == amg.getOptionsPrefix()
    for kx, kept in ((1.0, False), (1.02, True)):
        A = laplacian(kx)
        M2 = petsc(A)
        direct.setOperators(M2)
        assert dlag.reuse == kept
        its, reason = solve_lagged(direct, dlag, f, y)
        assert reason > 0 and not dlag.weak
        assert its <= (6 if kept else 2)
        assert np.linalg.norm(A @ y.array - b) <= 1.01 * rtol * np.linalg.norm(b)
        M2.destroy()
    for obj in (amg, direct, M):
        obj.destroy()


def _held(S: np.ndarray, k: float = 1e3) -> sp.csr_matrix:
    """laplacian(1) with the nodes S held by springs of stiffness k (a contact set)."""
    d = np.zeros(N * N)
    d[S] = k
    return sp.csr_matrix(laplacian(1.0) + sp.diags(d))


def test_a_preconditioner_built_before_the_contact_set_took_hold_is_rebuilt():
    """With ``moved`` (the geometric multigrid's rule), a preconditioner built while other
    multipliers were constrained is rebuilt when more than that fraction of them changed,
    and kept when fewer did. Here the preconditioner is an exact factorization, so a
    fresh one solves in one iteration and a stale one (the springs missing) takes more."""
    rtol = 1e-10
    b = np.random.default_rng(2).standard_normal(N * N)
    S = np.arange(20 * N, 20 * N + 20)
    steps = ((np.zeros(0, dtype=np.int64), False), (S, True), (S[:-1], False))
    its_of = {}
    for moved in (0.25, None):
        ksp = gmres("lu", rtol)
        lag = Lag(moved=moved)
        its_of[moved] = []
        for active, changed in steps:
            A = _held(active)
            M = petsc(A)
            ksp.setOperators(M)
            f, y = M.createVecs()
            f.array[:] = b
            lag.constrained(active)
            assert lag.reuse == (len(its_of[moved]) > 0 and (moved is None or not changed))
            its, reason = solve_lagged(ksp, lag, f, y)
            assert reason > 0
            assert np.linalg.norm(A @ y.array - b) <= 1.01 * rtol * np.linalg.norm(b)
            its_of[moved].append(its)
            M.destroy()
        ksp.destroy()
    # rebuilt on the held set: one iteration; the factorization without the springs: more
    assert its_of[0.25][1] == 1 < its_of[None][1]
    # one spring of twenty let go: the kept factorization, a few iterations
    assert 1 < its_of[0.25][2] <= 6
