"""The acceptance of a converged state: no answer is reported converged that is not a
physical solution of the contact problem.

Every :meth:`~fenicsx_mortar.ContactProblem.solve` ends here once Newton (and the pairs'
augmentations) stopped: the state is accepted only if

* the SNES stopped by the package's convergence rule (a PETSc option that ends the solve
  otherwise, ``-snes_type ksponly`` say, reports success after one linear solve);
* no slave node passed through the master during the step unseen by the contact search
  (it would be on the wrong side with zero pressure);
* no node moved by more than :data:`FLOWN_OFF` times the mesh's size (Newton's answer to
  loads far beyond a material's stiffness: E = 1e-12 under a pressure of 1 gave |u| = 1e14);
* no cell is inverted (J = det F ≤ 0 at a quadrature point or a corner).

The first always applies; the others can be switched off
(``ContactProblem(..., acceptance=False)``), e.g. for a deliberately unphysical test.
Checks that need the scene (the tolerance against the loads' scale, warnings of a soft
penalty) are the scene runner's.
"""
from __future__ import annotations

from typing import Mapping, Sequence

import numpy as np
import ufl
from mpi4py import MPI
from petsc4py import PETSc

from . import _dolfinx as dx

#: a state whose displacement exceeds this many times the mesh's diameter is refused
FLOWN_OFF = 1e3


class Acceptance:
    """Called with the Newton solver after a converged solve: None for an accepted state,
    else why not (collective).

    Args:
        u: The displacement Function.
        pairs: The contact pairs.
        quadrature_degree: Gauss points of the inverted-cell check (the corners are always
            checked).
        physical: Run the physical checks (passed-through nodes, flown off, inverted cells).
        cell_tags: Optional cell meshtags, to name the body of an inverted cell.
        body_names: Optional names of the cell tag values.
    """

    def __init__(self, u, pairs: Sequence = (), quadrature_degree: int = 2,
                 physical: bool = True, cell_tags=None,
                 body_names: Mapping[int, str] | None = None):
        self.u, self.pairs, self.physical = u, list(pairs), physical
        self.msh = msh = u.function_space.mesh
        F = ufl.Identity(2) + ufl.grad(u)
        self._J = dx.quadrature_expression(ufl.det(F), msh, quadrature_degree, vertices=True)
        self.cells = np.arange(dx.num_owned_cells(msh), dtype=np.int32)
        tags = np.full(dx.num_cells(msh), -1)
        if cell_tags is not None:
            tags[cell_tags.indices] = cell_tags.values
        names = dict(body_names or {})
        self.body = [names.get(int(t), f"cell tag {t}" if t >= 0 else "a cell")
                     for t in tags[self.cells]]
        x = dx.node_coordinates(msh)[:, :2]
        comm = msh.comm
        lo = [comm.allreduce(float(v), op=MPI.MIN) for v in x.min(axis=0, initial=np.inf)]
        hi = [comm.allreduce(float(v), op=MPI.MAX) for v in x.max(axis=0, initial=-np.inf)]
        #: the diameter of the mesh's bounding box
        self.size = float(np.hypot(hi[0] - lo[0], hi[1] - lo[1]))

    def __call__(self, newton) -> str | None:
        reason = newton.snes.getConvergedReason()
        if reason != PETSc.SNES.ConvergedReason.CONVERGED_FNORM_ABS:
            return (f"the SNES stopped with reason {reason}, not by the convergence rule "
                    "(a PETSc option replaced it?)")
        if not self.physical:
            return None
        for p in self.pairs:
            why = p.passed_through()
            if why:
                return why
        return self.flown_off() or self.inverted()

    def flown_off(self) -> str | None:
        """A displacement beyond FLOWN_OFF times the mesh's size (collective)."""
        umax = self.msh.comm.allreduce(float(np.abs(self.u.x.array).max(initial=0.0)),
                                       op=MPI.MAX)
        if not umax > FLOWN_OFF * self.size:
            return None
        return (f"the solution moves a node by {umax:.3g}, {umax / self.size:.3g} times the "
                "size of the mesh: not a deformation (loads far beyond a material's E?)")

    def inverted(self) -> str | None:
        """Which cells have J ≤ 0 at a quadrature point or a corner (collective). J of a P1
        or Q1 cell is affine in each reference coordinate, so the corners are the exact test;
        a folded slave (two blocks overlapping by two elements) converged with J > 0 at every
        Gauss point."""
        comm = self.msh.comm
        if len(self.cells):
            J = dx.expression_eval(self._J, self.msh, self.cells)
            J = J.reshape(len(self.cells), -1).min(axis=1)
        else:                        # a rank without cells (more ranks than cells)
            J = np.zeros(0)
        bad = np.flatnonzero(J <= 0)
        count = comm.allreduce(len(bad), op=MPI.SUM)
        if count == 0:
            return None
        worst = bad[np.argsort(J[bad])[:5]]
        mids = dx.cell_midpoints(self.msh, self.cells[worst])
        mine = [(float(J[c]), self.body[c], m) for c, m in zip(worst, mids)]
        found = sorted(sum(comm.allgather(mine), []), key=lambda r: r[0])[:5]
        where = ", ".join(f"{b!r} at ({m[0]:.4g}, {m[1]:.4g}) J = {j:.3g}"
                          for j, b, m in found)
        return (f"the solution inverts {count} cell(s) (J = det F <= 0 at a quadrature point "
                f"or a corner, not a physical deformation): {where}")
