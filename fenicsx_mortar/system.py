"""The unknowns of the Newton system and their layout in PETSc.

* :class:`DisplacementSystem`: the displacement dofs alone, in DOLFINx's vector and matrix
  (penalty and Uzawa ALM contact: the pressures are functions of the displacements);
* :class:`MultiplierSystem`: the displacements and, for every pair whose enforcement owns
  unknowns (:class:`~.contact.enforcement.LagrangeMultipliers`), a 2×2 block (λ_n, λ_t) per
  slave node. Each rank owns its displacement dofs followed by the multipliers of the slave
  nodes whose dofs it owns, so the global numbering is contiguous per rank and the
  multipliers live where their nodes' rows are. The matrix has block size 2 and DOLFINx's
  local-to-global map (shifted by the multipliers of the lower ranks), so the bulk forms
  are assembled into it directly; its sparsity is the bulk's and the predicted contact
  couplings', preallocated exactly, and grown once before an assembly that needs more
  (a slave sliding past new master nodes: ``contact.assembly.reserve``).

Both give the solver the same operations: the vector ``x`` of unknowns, ``push(x)`` (x →
the displacement Function and the pairs' multipliers), ``pull(x)`` (the reverse), and the
residual and Jacobian assembly with the pairs' terms.
"""
from __future__ import annotations

import dataclasses

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from . import _dolfinx as dx

#: preconditioners that take the rigid-body modes (a near-nullspace)
AMG_TYPES = ("gamg", "hypre", "ml")


class DisplacementSystem:
    def __init__(self, residual, jacobian, u, bcs, pairs, matrix=None, timings=None):
        self.residual_form, self.jacobian_form, self.u, self.bcs = residual, jacobian, u, bcs
        self.pairs = pairs
        self.b = dx.create_vector(residual)
        self.A = matrix if matrix is not None else dx.create_matrix(jacobian)
        self.x = dx.function_vector(u).copy()
        self.bc_dofs = dx.bc_dofs(bcs)
        V = u.function_space
        l2g = dx.local_to_global_dofs(V)
        local = np.asarray(self.bc_dofs)
        g = l2g[local] if len(local) else np.zeros(0, dtype=np.int64)
        skip = np.unique(np.concatenate(V.mesh.comm.allgather(g)))
        n_global = dx.dof_count(V)
        for p in pairs:
            p.attach(p.dofs, skip, n_global)

    def push(self, x) -> None:
        """The iterate x → u (and its ghosts)."""
        x.ghostUpdate(addv=PETSc.InsertMode.INSERT, mode=PETSc.ScatterMode.FORWARD)
        x.copy(dx.function_vector(self.u))
        self.u.x.scatter_forward()

    def pull(self, x) -> None:
        """u → x."""
        dx.function_vector(self.u).copy(x)

    def assemble_residual(self, x, b, add_contact) -> None:
        dx.assemble_residual(b, self.residual_form, self.jacobian_form, self.bcs, x,
                             extra=add_contact)

    def assemble_jacobian(self, A, add_contact) -> None:
        dx.assemble_jacobian(A, self.jacobian_form, self.bcs, extra=add_contact)

    def unconstrained(self):
        """A vector in DOLFINx's layout, for F(u) without Dirichlet rows (reactions)."""
        return self.b.duplicate()

    def owned_objects(self) -> list:
        """PETSc objects of the system besides A, b and x (destroyed with the solver)."""
        return []

    def configure(self, snes: PETSc.SNES, applied) -> None:
        """Apply the solver options (``petsc_options.Applied``); an algebraic multigrid
        gets the rigid-body modes as its near-nullspace."""
        applied.set_from_options(snes)
        pc = snes.getKSP().getPC()
        if pc.getType() in AMG_TYPES and self.A.getNearNullSpace() is None:
            ns = near_nullspace(self.u.function_space)
            self.A.setNearNullSpace(ns)
            ns.destroy()


class MultiplierSystem(DisplacementSystem):
    def __init__(self, residual, jacobian, u, bcs, pairs, matrix, timings=None):
        dof_map, n_blocks, comm = self._layout(residual, jacobian, u, bcs, pairs)
        self.A = self._matrix(matrix, dof_map, n_blocks, comm)
        self.x = self.A.createVecRight()
        self.b = self.A.createVecLeft()
        self.pull(self.x)

    def _layout(self, residual, jacobian, u, bcs, pairs):
        """The extended numbering: block offsets per rank, the multiplier blocks of every
        slave node, the local-to-global map; the pairs attached to it. Returns the map of
        global displacement dofs to extended ones, the global block count and the
        communicator."""
        self.residual_form, self.jacobian_form, self.u, self.bcs = residual, jacobian, u, bcs
        self.pairs = pairs
        V = u.function_space
        comm = V.mesh.comm
        self.b_u = dx.create_vector(residual)          # the bulk residual, DOLFINx layout
        self.bc_dofs = dx.bc_dofs(bcs)
        im = V.dofmap.index_map
        nb = im.size_local                               # owned displacement blocks (nodes)
        self.n_u = 2 * nb
        # the multiplier blocks this rank owns: per pair, its owned slave nodes in order
        self._owned = [np.flatnonzero(p.slave.owned) for p in pairs]
        n_lam = sum(len(o) for o in self._owned if o is not None)
        counts = np.array(comm.allgather((nb, n_lam)))
        offset = np.concatenate([[0], np.cumsum(counts.sum(axis=1))])   # block offsets
        u_first = np.concatenate([[0], np.cumsum(counts[:, 0])])        # DOLFINx's
        self._owned_blocks = nb + n_lam
        self._first_block = int(offset[comm.rank])
        n_blocks = int(offset[-1])

        def to_ext(g_blocks: np.ndarray) -> np.ndarray:
            owner = np.searchsorted(u_first, g_blocks, side="right") - 1
            return g_blocks - u_first[owner] + offset[owner]

        l2g = dx.local_to_global_blocks(V)
        ext_blocks = to_ext(l2g.astype(np.int64))
        self._lgmap = PETSc.LGMap().create(ext_blocks.astype(PETSc.IntType), bsize=2,
                                           comm=comm)

        def dof_map(g_dofs: np.ndarray) -> np.ndarray:
            return 2 * to_ext(g_dofs // 2) + g_dofs % 2

        # multiplier block of every slave node of every pair (global, on every rank)
        start = offset[comm.rank] + nb
        self._lam_blocks = []
        for p, own in zip(pairs, self._owned):
            blocks = np.zeros(p.slave.n, dtype=np.int64)
            blocks[own] = start + np.arange(len(own))
            start += len(own)
            self._lam_blocks.append(comm.allreduce(blocks, op=MPI.SUM))
        l2g_dofs = dx.local_to_global_dofs(V)
        local = np.asarray(self.bc_dofs)
        g = l2g_dofs[local] if len(local) else np.zeros(0, dtype=np.int64)
        skip = dof_map(np.unique(np.concatenate(comm.allgather(g))))
        for p, lam in zip(pairs, self._lam_blocks):
            index = dof_map(p.dofs)
            if p.unknowns:
                index = np.concatenate([index, (2 * lam[:, None] + np.arange(2)).ravel()])
            p.attach(index, skip, 2 * n_blocks)
        return dof_map, n_blocks, comm

    def _matrix(self, A_u, dof_map, n_blocks: int, comm) -> PETSc.Mat:
        """The bulk and contact pattern of ``A_u`` (a DOLFINx matrix with the predicted
        displacement couplings) in the extended numbering, plus each multiplier block's
        couplings: its own 2×2 block and, both ways, the dofs of the nodes its weighted
        gap depends on (:meth:`~.contact.pair.ContactPair.couplings`)."""
        indptr, indices, _ = A_u.getValuesCSR()
        cols = dof_map(indices.astype(np.int64))
        n_u = self.n_u
        row_cols = [cols[indptr[i]:indptr[i + 1]] for i in range(n_u)]
        extra_u: dict[int, list] = {}
        lam_rows = []
        first_dof = 2 * self._first_block
        for p, lam, own in zip(self.pairs, self._lam_blocks, self._owned):
            if not p.unknowns:
                continue
            couplings = p.couplings_by_node()
            for j in own:
                lam_dofs = 2 * lam[j] + np.arange(2)
                u_dofs = dof_map(couplings[j])
                row = np.unique(np.concatenate([lam_dofs, u_dofs]))
                lam_rows += [row, row]          # the λ_n and the λ_t row
            for j in range(p.slave.n):
                lam_dofs = 2 * lam[j] + np.arange(2)
                for d in dof_map(couplings[j]):
                    extra_u.setdefault(int(d), []).append(lam_dofs)
        for d, lams in extra_u.items():
            local = d - first_dof
            if 0 <= local < n_u:
                row_cols[local] = np.concatenate([row_cols[local], *lams])
        all_rows = [np.unique(c) for c in row_cols] + lam_rows
        ptr = np.concatenate([[0], np.cumsum([len(c) for c in all_rows])])
        ind = np.concatenate(all_rows) if all_rows else np.zeros(0, dtype=np.int64)
        n_local = 2 * self._owned_blocks
        J = PETSc.Mat().create(comm)
        J.setSizes(((n_local, 2 * n_blocks), (n_local, 2 * n_blocks)), bsize=2)
        J.setType(PETSc.Mat.Type.AIJ)
        J.setPreallocationCSR((ptr.astype(PETSc.IntType), ind.astype(PETSc.IntType)))
        J.setLGMap(self._lgmap, self._lgmap)
        J.setOption(PETSc.Mat.Option.NEW_NONZERO_ALLOCATION_ERR, False)
        return J

    def push(self, x) -> None:
        """x → u (owned part, then the ghosts) and every pair's multipliers (gathered: each
        rank holds the whole surfaces)."""
        arr = x.array_r
        u_vec = dx.function_vector(self.u)
        with u_vec.localForm() as loc:
            loc.array[: self.n_u] = arr[: self.n_u]
        self.u.x.scatter_forward()
        offset = self.n_u
        comm = self.u.function_space.mesh.comm
        for p, own in zip(self.pairs, self._owned):
            if not p.unknowns:
                continue
            mine = arr[offset: offset + 2 * len(own)].reshape(-1, 2)
            offset += 2 * len(own)
            lam = np.zeros((p.slave.n, 2))
            if comm.size == 1:
                lam[own] = mine
            else:
                for idx, v in comm.allgather((own, mine)):
                    lam[idx] = v
            p.set_multipliers(lam)

    def pull(self, x) -> None:
        """u and the pairs' multipliers → x."""
        x.array = self._extended(dx.function_vector(self.u).array_r,
                                 lambda p: p.multipliers())

    def _extended(self, u_part, of_pair) -> np.ndarray:
        """This rank's part of an extended vector: the owned displacement entries of
        ``u_part``, then, per pair with unknowns, ``of_pair(pair)`` (n_slave, 2) at the
        slave nodes this rank owns."""
        arr = np.empty(2 * self._owned_blocks)
        arr[: self.n_u] = u_part[: self.n_u]
        offset = self.n_u
        for p, own in zip(self.pairs, self._owned):
            if not p.unknowns:
                continue
            arr[offset: offset + 2 * len(own)] = of_pair(p)[own].ravel()
            offset += 2 * len(own)
        return arr

    def assemble_residual(self, x, b, add_contact) -> None:
        b_u = self.b_u
        dx.assemble_residual(b_u, self.residual_form, self.jacobian_form, self.bcs,
                             dx.function_vector(self.u), extra=add_contact)
        b.array = self._extended(b_u.array_r, lambda p: p.multiplier_residual())

    def unconstrained(self):
        return self.b_u.duplicate()

    def owned_objects(self) -> list:
        return [self.b_u, self._lgmap]


def near_nullspace(V) -> PETSc.NullSpace:
    """The rigid-body modes of 2D displacements (two translations, one rotation) over the
    owned dofs of V, in DOLFINx's layout: AMG's near-nullspace."""
    n = dx.owned_dof_count(V) // 2
    X = dx.dof_coordinates(V)[:n]
    coords = PETSc.Vec().createMPI((2 * n, dx.dof_count(V)), bsize=2,
                                   comm=V.mesh.comm)
    coords.array[:] = X.ravel()
    ns = PETSc.NullSpace().createRigidBody(coords)
    coords.destroy()
    return ns


#: displacement dofs from which ``linear_solver = "auto"`` condenses dual multipliers and
#: solves with GMRES + GAMG (docs/performance.md §7: ahead of MUMPS on Hertz from 124k dofs,
#: 1.8-2.6x; on large sliding, where it hands over to a kept factorization, behind at 108k
#: (1.6x), by 4 % at 242k, ahead at 503k in all (1.18x)
AUTO_AMG_DOFS = 200_000


#: coarse meshes from which ``"auto"`` takes the geometric multigrid over GAMG: with one
#: (a quarter of the dofs for MUMPS at the bottom) it was as fast at 0.5M, with two 1.4x
#: faster at 2M (docs/performance.md §7)
AUTO_GMG_LEVELS = 2


def resolve_linear_solver(settings, pairs, n_dofs: int, coarse_meshes: int = 0):
    """``settings`` with ``linear_solver = "auto"`` made a solver: for a problem of at
    least :data:`AUTO_AMG_DOFS` displacement dofs whose multiplier pairs all condense (the
    dual basis), ``"gmres-gmg"`` with at least :data:`AUTO_GMG_LEVELS` coarse meshes, else
    ``"gmres-gamg"``; below that size ``"mumps"``.

    Args:
        settings: The SolverSettings.
        pairs: The contact pairs.
        n_dofs: The global number of displacement dofs.
        coarse_meshes: How many meshes the problem's mesh was refined from (given to it
            with the cell tags).

    Returns:
        The settings, replaced if ``"auto"``.
    """
    if settings.linear_solver != "auto":
        return settings
    from .condensation import condensable
    if not (n_dofs >= AUTO_AMG_DOFS and condensable(pairs)):   # (condensable: multipliers)
        return dataclasses.replace(settings, linear_solver="mumps")
    gmg = coarse_meshes >= AUTO_GMG_LEVELS
    return dataclasses.replace(settings, linear_solver="gmres-gmg" if gmg else "gmres-gamg")


def system_class(pairs, linear_solver: str):
    """The system a problem's Newton solver works on: the displacements alone without
    multipliers; with them the saddle point, or — for a linear solver of the condensed path
    (``settings.CONDENSED_SOLVERS``) when every multiplier pair uses the dual basis — the
    condensed system (condensation/).

    Args:
        pairs: The contact pairs.
        linear_solver: The (resolved) ``SolverSettings.linear_solver``.

    Returns:
        DisplacementSystem, MultiplierSystem or CondensedSystem.
    """
    from .settings import CONDENSED_SOLVERS
    if not any(p.unknowns for p in pairs):
        return DisplacementSystem
    from .condensation import CondensedSystem, condensable
    if linear_solver in CONDENSED_SOLVERS and condensable(pairs):
        return CondensedSystem
    return MultiplierSystem
