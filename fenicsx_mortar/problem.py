"""``ContactProblem``: finite-deformation contact on a DOLFINx user's own forms.

The user brings what a DOLFINx script has — the displacement ``u`` (a P1 vector Function),
the residual form F(u; v) (and optionally its Jacobian), the Dirichlet conditions — and
the contact pairs (:class:`~fenicsx_mortar.contact.pair.ContactPair`, from facet meshtags).
The problem solves F(u) + contact = 0 with PETSc SNES (``problem.snes``; options through
``petsc_options`` or the options database under ``prefix``)::

    pair = ContactPair(V, facet_tags, slave=3, master=4, E=1000.0)
    problem = ContactProblem(F, u, bcs, [pair])
    for load in loads:
        traction.value = load
        result = problem.solve()         # Newton (+ ALM augmentations) at this load
        print(result.converged, pair.record())

The scene runner (:func:`fenicsx_mortar.solve`) is a client of this class.
"""
from __future__ import annotations

from typing import Callable, Sequence

import ufl

from . import _dolfinx as dx
from .contact.pair import ContactPair
from .scene import SolverSettings
from .solver import NewtonSolver, StepResult, Timings


class ContactProblem:
    def __init__(self, F, u, bcs: Sequence, pairs: Sequence[ContactPair], J=None, *,
                 settings: SolverSettings | None = None, petsc_options: dict | None = None,
                 prefix: str | None = None, timings: Timings | None = None,
                 should_stop: Callable[[], str | None] = lambda: None):
        """``F``, ``J``: UFL forms or compiled DOLFINx forms (J default: the Gateaux
        derivative of F in the direction of a trial function of u's space). ``settings``:
        Newton tolerances, line search, linear solver (:class:`~.scene.SolverSettings`);
        ``petsc_options`` are added to its ``petsc`` dict (keys with or without '-')."""
        pairs = list(pairs)
        if pairs and not dx.is_p1_vector_space(u.function_space):
            raise ValueError("u: contact needs the displacement in the P1 vector space of the "
                             "mesh (two dofs at every vertex)")
        for k, p in enumerate(pairs):
            if not dx.same_mesh(p.mesh, u.function_space.mesh):
                raise ValueError(f"contact {p.name}: the pair was built on another mesh than "
                                 "u's function space")
            if any(q is p for q in pairs[:k]):
                raise ValueError(f"contact {p.name}: the same pair is given twice")
        if J is None:
            J = ufl.derivative(F, u, ufl.TrialFunction(u.function_space))
        self.residual = F if not isinstance(F, ufl.Form) else dx.form(F)
        self.jacobian = J if not isinstance(J, ufl.Form) else dx.form(J)
        settings = settings or SolverSettings()
        if petsc_options:
            settings.petsc = {**settings.petsc, **petsc_options}
        self.u, self.bcs, self.pairs = u, list(bcs), list(pairs)
        self.timings = timings if timings is not None else Timings()
        for p in self.pairs:
            p.timings = self.timings
            # the ALM's KKT test asks no more of the gaps than this tolerance resolves
            p.enforcement.force_resolution = settings.atol
        matrix = None
        if self.pairs:
            with self.timings("contact"):
                blocks = [b for p in self.pairs for b in p.couplings()]
                matrix = dx.matrix_with_couplings(self.jacobian, u.function_space, blocks)
        self.solver = NewtonSolver(self.residual, self.jacobian, u, self.bcs, settings,
                                   self.pairs, self.timings, matrix, should_stop, prefix)

    @property
    def snes(self):
        """The PETSc SNES (newtonls) that solves the problem."""
        return self.solver.snes

    def solve(self, max_augmentations: int = 30) -> StepResult:
        """Newton solves at the current loads (one per augmentation) from the current u.
        Converged: the pairs' step history is committed. Not converged: u and the history
        are restored to where the solve started, and the result says why."""
        self.solver.system.pull(self.solver.x)   # the user may have set u
        saved = self.solver.save_state()
        for p in self.pairs:
            p.begin_step()
        res = self.solver.solve_step(max_augmentations)
        for p in self.pairs:
            if res.converged:
                p.accept_step()
            else:
                p.reject_step()
        if not res.converged:
            self.solver.restore_state(saved)
        return res

    def reactions(self):
        """F(u) with contact and without Dirichlet modification (a PETSc Vec): the
        reaction forces on the constrained dofs."""
        return self.solver.unconstrained_residual()
