"""The condensed system: [u, λ] as the SNES sees them (the saddle point's layout and
residual), with the Jacobian assembled as the condensed displacement matrix Kc and the
linear solve done on it (the package docstring has the outline).
"""
from __future__ import annotations

import warnings
from typing import Sequence

import numpy as np
import scipy.sparse as sp
from mpi4py import MPI
from petsc4py import PETSc

from .. import _dolfinx as dx
from ..system import MultiplierSystem, near_nullspace
from ..timings import Timings
from .elimination import Elimination
from .inverses import below_round_off
from .ksp import CondensedKSP, Forcing, Lag, SaddleOperator, direct_ksp, solve_lagged
from .pattern import KcPattern


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


class CondensedSystem(KcPattern, MultiplierSystem):
    """[u, λ] for the SNES as :class:`MultiplierSystem` lays them out, solved through the
    condensed displacement matrix ``Kc`` (the package docstring).

    ``A`` is a Python matrix: the Jacobian over [u, λ] as an operator (its product, for
    line searches and tests, from Kc, the condensation's entries and the multiplier
    blocks); the SNES's KSP is :class:`CondensedKSP`, and ``inner`` the KSP on Kc that
    the options under the SNES's prefix configure.

    Args:
        residual, jacobian, u, bcs, pairs: As for :class:`MultiplierSystem`.
        matrix: A DOLFINx matrix with the bulk and the predicted contact couplings (its
            pattern seeds Kc's; destroyed here).
        timings: Seconds by phase: the condensation counts as ``contact``.
        prolongations: A geometric multigrid's prolongations, finest first
            (multigrid.prolongations): the inner PC becomes PETSc's MG on them.
    """

    condensed = True

    def __init__(self, residual, jacobian, u, bcs, pairs, matrix, timings=None,
                 prolongations: Sequence[PETSc.Mat] = ()):
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
                                          SaddleOperator(self), comm=comm)
        self.A.setUp()
        self.pull(self.x)
        self.inner = PETSc.KSP().create(comm)
        self.inner.setOperators(self.Kc)
        self._f, self._y = self.Kc.createVecs()
        #: Eisenstat–Walker forcing for a Krylov inner solve (set by configure)
        self.forcing: Forcing | None = None
        #: when a Krylov inner solve rebuilds its preconditioner (set by configure)
        self.lag: Lag | None = None
        self.last_solve = {"iterations": 0, "reason": 0, "residual": 0.0, "rtol": 0.0}
        self._prolongations = list(prolongations)

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
                D = below_round_off(D, rows, diag, r0)
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
        if self.lag is not None:
            self.lag.constrained(np.sort(elim.H))
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
        its, reason = solve_lagged(self.inner, self.lag, f, y)
        if self.lag is not None and self.lag.weak:
            its_direct, reason = self._fall_back(f, y, reason)
            its += its_direct
        self._fill_P(y, b_lam[elim.H])
        self.last_solve = {"iterations": its, "reason": int(reason),
                           "residual": float(self.inner.getResidualNorm()),
                           "rtol": float(self.inner.getTolerances()[0])}
        dlam = self._recover(b_lam, b_P, y)
        out = x.array
        out[: self.n_u] = y.array_r
        out[self.n_u:] = dlam[self._lam_owned]
        return its, reason

    def _fall_back(self, f: PETSc.Vec, y: PETSc.Vec, reason: int) -> tuple[int, int]:
        """The preconditioner is weak on this Kc (Lag.weak: on a moving contact set AMG
        took tens of iterations a decade): Kc is solved with a kept MUMPS factorization
        from here on, and ``f`` again if the solve (its ``reason``) failed."""
        weak, rate = self.inner, self.lag.last_rate
        pc = weak.getPC().getType()
        self.inner, self.lag = direct_ksp(weak)
        weak.destroy()
        if self.comm.rank == 0:
            warnings.warn(f"the {pc} preconditioner converges at {rate:.3f} decades per "
                          "iteration on the condensed system: it is solved with a kept "
                          "MUMPS factorization from here on (docs/condensation.md §4)",
                          stacklevel=1)
        if reason >= 0:
            return 0, reason
        return solve_lagged(self.inner, self.lag, f, y)

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
                self._all_cols, self._nullspace, *self._prolongations]

    def _multigrid(self) -> None:
        """The inner PC a multigrid on the prolongations (PETSc makes the Galerkin products
        again for a Kc with a grown pattern)."""
        pc = self.inner.getPC()
        n = len(self._prolongations)
        pc.setType(PETSc.PC.Type.MG)
        pc.setMGLevels(n + 1)
        for i, P in enumerate(self._prolongations):
            pc.setMGInterpolation(n - i, P)

    def configure(self, snes: PETSc.SNES, applied) -> None:
        """The SNES's KSP becomes the condensing one; the options under the prefix
        configure the inner KSP on Kc."""
        prefix = snes.getOptionsPrefix() or ""
        ksp = snes.getKSP()
        ksp.setOptionsPrefix(prefix + "condensed_")
        ksp.setType(PETSc.KSP.Type.PYTHON)
        ksp.setPythonContext(CondensedKSP(self, snes))
        ksp.getPC().setType(PETSc.PC.Type.NONE)
        self.inner.setOptionsPrefix(prefix)
        if self._prolongations:
            self._multigrid()
        applied.set_from_options(snes, extra=[self.inner])
        # a Krylov inner solve without a tolerance of the user's: inexact Newton
        krylov = self.inner.getType() != PETSc.KSP.Type.PREONLY
        self.forcing = (Forcing(applied.settings.atol)
                        if krylov and "ksp_rtol" not in applied.options else None)
        self.lag = (Lag(moved=MG_REBUILD_MOVED if self._prolongations else None)
                    if krylov else None)


#: the fraction of the constrained multipliers that may change before a multigrid's
#: Galerkin operators are rebuilt (Lag; Hertz 2M: rebuilt at the 2nd and 4th of 7)
MG_REBUILD_MOVED = 0.25


def _compress(A: sp.csr_matrix, cols: np.ndarray) -> sp.csr_matrix:
    """A with its columns renumbered as their positions in the sorted ``cols``."""
    return sp.csr_matrix((A.data, np.searchsorted(cols, A.indices), A.indptr),
                         shape=(A.shape[0], len(cols)))
