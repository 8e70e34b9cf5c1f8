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
* no cell is inverted (J = det F ≤ 0 at a quadrature point or a corner);
* no body that only contact holds along x or y (no Dirichlet value on that component)
  touches nothing at the converged state: its stiffness is singular there and Newton's
  answer is arbitrary (an exactly touching start with a round-off slip threw a body ~9
  units sideways, and every step then "converged" with zero contact force). Needs the
  bodies: ``cell_tags``, and pairs built with them.

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
        cell_tags: Optional cell meshtags: the bodies, to name the body of an inverted cell
            and to find those only contact holds.
        body_names: Optional names of the cell tag values.
        bcs: The Dirichlet conditions (which directions of which body they hold).
    """

    def __init__(self, u, pairs: Sequence = (), quadrature_degree: int = 2,
                 physical: bool = True, cell_tags=None,
                 body_names: Mapping[int, str] | None = None, bcs: Sequence = ()):
        self.u, self.pairs, self.physical = u, list(pairs), physical
        self.msh = msh = u.function_space.mesh
        F = ufl.Identity(2) + ufl.grad(u)
        self._J = dx.quadrature_expression(ufl.det(F), msh, quadrature_degree, vertices=True)
        self.cells = np.arange(dx.num_owned_cells(msh), dtype=np.int32)
        tags = np.full(dx.num_cells(msh), -1)
        if cell_tags is not None:
            tags[cell_tags.indices] = cell_tags.values
        names = dict(body_names or {})
        self.names = names
        self.body = [names.get(int(t), f"cell tag {t}" if t >= 0 else "a cell")
                     for t in tags[self.cells]]
        #: cell tag of each body → the components (0: x, 1: y) no Dirichlet value holds
        self.free = _free_directions(u, bcs, cell_tags)
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
        return self.flown_off() or self.unsupported() or self.inverted()

    def unsupported(self) -> str | None:
        """A body that only contact holds along x or y but that no pair touches at the
        converged state (collective: the pairs' states are the same on every rank).
        Bodies count as held through the pairs with a closed gap (an active node, whether
        or not it carries pressure: an exact touch under a load of 1e-9 converges at
        p = 0), from the bodies the Dirichlet values hold."""
        if not any(self.free.values()) or any(
                p.slave.body_tag < 0 or p.master.body_tag < 0 for p in self.pairs):
            return None
        links = [(p.slave.body_tag, p.master.body_tag) for p in self.pairs
                 if p.state is not None and np.any(p.state.active)]
        for c, comp in enumerate("xy"):
            held = {tag for tag, free in self.free.items() if c not in free}
            grew = True
            while grew:
                grew = False
                for a, b in links:
                    if (a in held) != (b in held):
                        held |= {a, b}
                        grew = True
            lost = [self.names.get(tag, f"cell tag {tag}") for tag, free in self.free.items()
                    if c in free and tag not in held]
            if lost:
                return (f"body {lost[0]!r} is held along {comp} by contact alone (no "
                        f"Dirichlet value on u_{comp}) and touches nothing at the converged "
                        f"state: its stiffness is singular along {comp}, so this answer is "
                        "arbitrary (was it pushed out of contact?)")
        return None

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


def _free_directions(u, bcs: Sequence, cell_tags) -> dict[int, set[int]]:
    """Cell tag of each body → the components (0: x, 1: y) on which no node of it has a
    Dirichlet value (collective); empty without cell tags."""
    if cell_tags is None:
        return {}
    V = u.function_space
    comm = V.mesh.comm
    held = np.zeros(u.x.array.shape[0], dtype=bool)
    held[dx.bc_dofs(bcs)] = True
    blocks = dx.cell_dofs(V)
    tags = sorted(set().union(*comm.allgather(set(np.unique(cell_tags.values).tolist()))))
    out = {}
    for tag in tags:
        nodes = np.unique(blocks[cell_tags.indices[cell_tags.values == tag]])
        have = [comm.allreduce(int(np.any(held[2 * nodes + c])), op=MPI.MAX) for c in (0, 1)]
        out[int(tag)] = {c for c in (0, 1) if not have[c]}
    return out
