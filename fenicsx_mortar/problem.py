"""``ContactProblem``: finite-deformation contact on a DOLFINx user's own forms.

The user brings what a DOLFINx script has — the displacement ``u`` (a P1 vector Function),
the residual form F(u; v) (and optionally its Jacobian), the Dirichlet conditions — and
the contact pairs (:class:`~fenicsx_mortar.ContactPair`, from facet meshtags). The problem
solves F(u) + contact = 0 with PETSc SNES, following DOLFINx's ``NonlinearProblem``
conventions: options under a ``petsc_options_prefix`` the user chooses, ``.solver`` the
SNES, ``close()`` (or ``with``) destroys the PETSc objects::

    pair = ContactPair(V, facet_tags, slave=3, master=4, E=1000.0)
    with ContactProblem(F, u, bcs, [pair], petsc_options_prefix="hertz_") as problem:
        for load in loads:
            traction.value = load
            result = problem.solve()      # Newton (+ ALM augmentations) at this load
            print(result.converged, problem.reaction(facet_tags, BOTTOM))

Every solve ends in the acceptance check (acceptance.py): a state that is not a converged
physical solution is never reported converged. :class:`~fenicsx_mortar.LoadStepper` adds
load stepping with step cutting; the scene runner is a client of both.
"""
from __future__ import annotations

import warnings
import weakref
from typing import TYPE_CHECKING, Callable, Mapping, Sequence

import numpy as np
import ufl
from mpi4py import MPI

from . import _dolfinx as dx
from . import petsc_options as po
from .acceptance import Acceptance
from .condensation import condensable, multigrid
from .condensation.multigrid import CoarseMesh
from .contact.assembly import reserve
from .newton import NewtonSolver, StepResult
from .settings import SolverSettings, check_number
from .system import resolve_linear_solver
from .timings import Timings

if TYPE_CHECKING:
    from .contact.pair import ContactPair


class ContactProblem:
    """F(u) + contact = 0, solved by Newton's method (PETSc SNES) at the current loads.

    Args:
        F: The residual: a UFL form linear in a test function of u's space (or a compiled
            DOLFINx form, then with ``J``).
        u: The displacement, a Function in the P1 vector space of the mesh.
        bcs: Dirichlet conditions (DOLFINx ``DirichletBC``).
        pairs: The contact pairs (each used by one problem only).
        J: The Jacobian form (default: the Gateaux derivative of F in the direction of a
            trial function of u's space).
        petsc_options_prefix: The SNES's options prefix: options in PETSc's database under
            it (the command line's ``-<prefix>snes_monitor``) reach the solver. ``""``: no
            prefix.
        petsc_options: Options set under the prefix for the set-up (``{"snes_monitor":
            None, "ksp_type": "preonly"}``; keys with or without '-'); an option PETSc does
            not read is warned of.
        settings: Newton tolerances, line search, linear solver
            (:class:`~fenicsx_mortar.SolverSettings`; its ``petsc`` dict is applied before
            ``petsc_options``).
        acceptance: Run the physical checks of a converged state (passed-through nodes,
            inverted cells, a flown-off body). The convergence rule always applies.
        max_augmentations: Newton solves after the first per ``solve()`` (ALM updates).
        cell_tags: Optional cell meshtags: the bodies, named in messages; with
            ``coarse_meshes``, the bodies of the geometric multigrid (without them
            ``"auto"`` does not take it).
        body_names: Optional names of the cell tag values.
        timings: Seconds by phase (a :class:`~fenicsx_mortar.timings.Timings`), added to.
        should_stop: Called at every Newton iteration; a non-empty string (a signal's name)
            stops the solve (collective: the same on every rank).
        coarse_meshes: The meshes u's mesh was refined from, coarsest first
            (:class:`~fenicsx_mortar.condensation.multigrid.CoarseMesh`, the same on every
            rank, each refined uniformly into the next): a geometric multigrid for
            ``linear_solver = "gmres-gmg"``, which needs them and ``cell_tags``.

    Raises:
        ValueError: an argument that cannot work, named.
    """

    def __init__(self, F: ufl.Form | dx.Form, u: dx.Function, bcs: Sequence = (),
                 pairs: Sequence[ContactPair] = (), J: ufl.Form | dx.Form | None = None, *,
                 petsc_options_prefix: str = "fenicsx_mortar_",
                 petsc_options: Mapping[str, object] | None = None,
                 settings: SolverSettings | None = None, acceptance: bool = True,
                 max_augmentations: int = 30, cell_tags: dx.MeshTags | None = None,
                 body_names: Mapping[int, str] | None = None,
                 timings: Timings | None = None,
                 should_stop: Callable[[], str | None] | None = None,
                 coarse_meshes: Sequence[CoarseMesh] = ()):
        pairs = list(pairs)
        coarse_meshes = _as_tuple(coarse_meshes, "coarse_meshes",
                                  "a sequence of CoarseMesh, coarsest first")
        _check_forms(F, J, u)
        _check_pairs(pairs, u)
        settings = resolve_linear_solver((settings or SolverSettings()).check("settings"),
                                         pairs, dx.dof_count(u.function_space),
                                         len(coarse_meshes) if cell_tags is not None else 0)
        check_number("max_augmentations", max_augmentations)
        if not isinstance(petsc_options_prefix, str) or " " in petsc_options_prefix \
                or petsc_options_prefix.startswith("-"):
            raise ValueError(f"petsc_options_prefix = {petsc_options_prefix!r}: a string of "
                             "letters, digits and '_' (PETSc's prefix, without '-')")
        user = {**po.normalize(settings.petsc), **po.normalize(petsc_options)}
        multipliers = any(p.unknowns for p in pairs)
        dual = condensable(pairs)
        po.check_solver_choice(settings, user, multipliers, condensable=dual)
        _check_multigrid(settings, multipliers, coarse_meshes, cell_tags)
        po.check_packages(settings, user)
        unread = po.unread(settings, user)
        if unread:
            warnings.warn(po.unread_message(unread), stacklevel=2)
        if J is None:
            J = ufl.derivative(F, u, ufl.TrialFunction(u.function_space))
        self.residual = F if not isinstance(F, ufl.Form) else dx.form(F)
        self.jacobian = J if not isinstance(J, ufl.Form) else dx.form(J)
        self.u, self.bcs, self.pairs = u, list(bcs), pairs
        self.max_augmentations = int(max_augmentations)
        self.timings = timings if timings is not None else Timings()
        # before the pairs are claimed: a hierarchy that does not fit fails here
        prolongations = []
        if settings.linear_solver == "gmres-gmg":
            with self.timings("multigrid"):
                prolongations = multigrid.prolongations(u.function_space, cell_tags,
                                                        coarse_meshes, dx.bc_dofs(self.bcs))
        for p in self.pairs:
            p.timings = self.timings
            p._problem = weakref.ref(self)
            # the ALM's KKT test asks no more of the gaps than this tolerance resolves
            p.enforcement.force_resolution = settings.atol
        self._closed = False
        self._shared_bc_dofs: bool | None = None
        matrix = None
        if self.pairs:
            # set-up, once (part of the runner's jit), not a Newton iteration's contact work
            with self.timings("contact_setup"):
                blocks = [b for p in self.pairs for b in p.couplings()]
                matrix = dx.matrix_with_couplings(self.jacobian, u.function_space, blocks)
                if matrix.getComm().getSize() > 1:
                    # couplings of nodes on different ranks: DOLFINx's pattern holds a
                    # rank's own and ghost nodes only; without these the Jacobian grew, and
                    # MUMPS analysed it afresh, at every Newton iteration (Hertz, 2 ranks)
                    reserve(matrix, *_all_to_all(blocks))
        #: the Newton driver (newton.py): SNES callbacks, convergence rule, state
        self.newton = NewtonSolver(self.residual, self.jacobian, u, self.bcs, settings,
                                   self.pairs, self.timings, matrix,
                                   should_stop or (lambda: None), petsc_options_prefix,
                                   po.normalize(petsc_options), prolongations)
        if matrix is not None and matrix is not self.newton.A:
            matrix.destroy()   # read once for the multipliers' pattern (system.py)
        self.newton.accept = Acceptance(u, self.pairs, settings.quadrature_degree,
                                        physical=acceptance, cell_tags=cell_tags,
                                        body_names=body_names, bcs=self.bcs)

    @property
    def solver(self):
        """The PETSc SNES (``newtonls``) that solves the problem (DOLFINx's name)."""
        return self.newton.snes

    @property
    def snes(self):
        """The PETSc SNES (same as :attr:`solver`)."""
        return self.newton.snes

    def solve(self, max_augmentations: int | None = None) -> StepResult:
        """Newton solves at the current loads (one per augmentation) from the current u.

        Converged (and accepted): the pairs' step history is committed. Not converged: u
        and the history are put back where the solve started, and the result says why.

        Args:
            max_augmentations: Overrides the problem's for this solve.

        Returns:
            The :class:`~fenicsx_mortar.newton.StepResult` (``converged``, ``iterations``,
            ``residuals``, ``augmentations``, ``reason``).
        """
        if self._closed:
            raise RuntimeError("ContactProblem: closed (its PETSc objects are destroyed); "
                               "make a new one")
        self._check_supports()
        newton = self.newton
        newton.system.pull(newton.x)   # the user may have set u
        saved = newton.save_state()
        for p in self.pairs:
            p.begin_step()
        res = newton.solve_step(self.max_augmentations if max_augmentations is None
                                else max_augmentations)
        for p in self.pairs:
            if res.converged:
                p.accept_step()
            else:
                p.reject_step()
        if not res.converged:
            newton.restore_state(saved)
        saved.destroy()
        return res

    def _check_supports(self) -> None:
        """Two Dirichlet conditions on one dof must prescribe one value: DOLFINx applies
        one of them silently, and the other support's reaction is then meaningless (two
        support groups sharing a corner, one at y = 0, one at y = 0.1: reactions −26.2 and
        +32.3 for a load of 1). Checked at every solve: the values change with the loads
        (collective)."""
        V = self.u.function_space
        conflict = None
        if self._shared_bc_dofs is None:     # whether two conditions share a dof at all
            dofs = [bc.dof_indices()[0] for bc in self.bcs]
            local = len(dofs) > 1 and len(np.unique(np.concatenate(dofs))) < \
                sum(len(d) for d in dofs)
            self._shared_bc_dofs = V.mesh.comm.allreduce(bool(local), op=MPI.LOR)
        values = dx.bc_values(self.bcs, V) if self._shared_bc_dofs else []
        if values:
            dofs = np.concatenate([d for d, _ in values])
            vals = np.concatenate([v for _, v in values])
            which = np.concatenate([np.full(len(d), k) for k, (d, _) in enumerate(values)])
            order = np.lexsort((which, dofs))
            dofs, vals, which = dofs[order], vals[order], which[order]
            same = dofs[1:] == dofs[:-1]
            tol = 1e-12 * np.maximum(np.maximum(np.abs(vals[1:]), np.abs(vals[:-1])), 1e-300)
            bad = np.flatnonzero(same & (np.abs(vals[1:] - vals[:-1]) > tol))
            if bad.size:
                i = bad[0]
                x = np.round(dx.dof_coordinates(V)[dofs[i] // 2], 12) + 0.0
                conflict = (int(which[i]), int(which[i + 1]), float(vals[i]),
                            float(vals[i + 1]), int(dofs[i] % 2), float(x[0]), float(x[1]))
        found = [c for c in V.mesh.comm.allgather(conflict) if c]
        if found:
            j, k, w, v, comp, x, y = found[0]
            raise ValueError(f"bcs[{j}] and bcs[{k}] prescribe different values, {w:.6g} and "
                             f"{v:.6g}, to the {'xy'[comp]} component at ({x:.6g}, {y:.6g}): "
                             "one support would silently win; give each dof one value "
                             "(leave the shared node out of one condition)")

    def reactions(self):
        """F(u) with contact and without Dirichlet rows, a PETSc Vec in u's layout: at a
        constrained dof, the force its support exerts on the body."""
        return self.newton.unconstrained_residual()

    def reaction(self, facet_tags: dx.MeshTags, tag: int | Sequence[int]) -> np.ndarray:
        """The force (x, y) that the supports on the tagged facets exert on the body: the
        sum of F(u) (contact included, Dirichlet rows not replaced) over the dofs of those
        facets, summed over the ranks (collective).

        Args:
            facet_tags: Facet meshtags of u's mesh.
            tag: The tag value(s) of the boundary.

        Returns:
            ``np.array([R_x, R_y])``; on a free boundary at equilibrium it is the external
            load there (zero if none).
        """
        V = self.u.function_space
        tdim = dx.topological_dimension(V.mesh)
        if getattr(facet_tags, "dim", tdim - 1) != tdim - 1:
            raise ValueError(f"facet_tags: meshtags of dimension {facet_tags.dim}; the "
                             f"facets are of dimension {tdim - 1}")
        facets = facet_tags.indices[np.isin(facet_tags.values, np.atleast_1d(tag))]
        comm = V.mesh.comm
        if comm.allreduce(len(facets), op=MPI.SUM) == 0:
            raise ValueError(f"reaction: no facet has the tag {tag!r}")
        b = self.reactions()
        n_owned = dx.owned_dof_count(V)
        arr = b.array_r
        out = np.zeros(2)
        for k in range(2):
            d = dx.facet_dofs(V, k, facets)
            out[k] = arr[d[d < n_owned]].sum()
        b.destroy()
        return comm.allreduce(out, op=MPI.SUM)

    def close(self) -> None:
        """Destroy the PETSc objects (SNES, matrix, vectors) now; the pairs are free for
        another problem."""
        if not self._closed:
            self._closed = True
            self.newton.close()
            for p in self.pairs:
                p._problem = None

    def __enter__(self) -> ContactProblem:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def _check_forms(F, J, u) -> None:
    """F (and J) forms of u: a UFL form must be linear in one test function of u's space
    and contain u; a compiled form comes with its compiled Jacobian."""
    if not isinstance(u, dx.Function):
        raise ValueError(f"u: a DOLFINx Function (the displacement), not {type(u).__name__}")
    if isinstance(F, ufl.Form):
        args = F.arguments()
        if len(args) != 1:
            raise ValueError(f"F: a residual form has one argument (a TestFunction); this "
                             f"one has {len(args)}")
        if u not in F.coefficients():
            raise ValueError("F does not depend on u: the residual must be written in terms "
                             "of the u passed (a form of another Function would never "
                             "change with the solution)")
        if J is not None and (not isinstance(J, ufl.Form) or len(J.arguments()) != 2):
            raise ValueError("J: a bilinear UFL form (test and trial function), or omit it "
                             "for dF/du")
        return
    if not hasattr(F, "function_spaces"):
        raise ValueError(f"F: a UFL form or a compiled DOLFINx form, not {type(F).__name__}")
    if J is None:
        raise ValueError("F is a compiled form: pass its compiled Jacobian J too (or pass "
                         "the UFL form, and J is derived)")


def _check_multigrid(settings: SolverSettings, multipliers: bool, coarse_meshes,
                     cell_tags) -> None:
    """``gmres-gmg`` has its hierarchy: multipliers to condense, coarse meshes, cell tags."""
    if settings.linear_solver != "gmres-gmg":
        return
    key = "settings.linear_solver = 'gmres-gmg'"
    if not multipliers:
        raise ValueError(f"{key} solves the condensed system of dual multipliers; without "
                         "multipliers (penalty, ALM) use 'gmres-gamg' or 'mumps'")
    if not coarse_meshes or cell_tags is None:
        raise ValueError(f"{key} needs the meshes u's mesh was refined from "
                         "(coarse_meshes, coarsest first) and cell_tags (the bodies); "
                         "without them use 'gmres-gamg'")
    for i, c in enumerate(coarse_meshes):
        if not isinstance(c, CoarseMesh):
            raise ValueError(f"coarse_meshes[{i}]: a CoarseMesh, got {type(c).__name__}")
        p, cells, body = (np.asarray(a) for a in (c.points, c.cells, c.cell_body))
        ok = (p.ndim == 2 and p.shape[1] == 2 and np.isfinite(p).all()
              and cells.ndim == 2 and cells.shape[1] in (3, 4) and len(cells) > 0
              and np.issubdtype(cells.dtype, np.integer) and body.shape == (len(cells),)
              and cells.min() >= 0 and cells.max() < len(p))
        if not ok:
            raise ValueError(f"coarse_meshes[{i}]: points (n, 2) finite, cells (m, 3 or 4) "
                             "node indices below n, cell_body (m,)")
        unused = len(p) - len(np.unique(cells))
        if unused:
            raise ValueError(f"coarse_meshes[{i}]: {unused} of its points are in no cell "
                             "(a coarse node without a cell has no equation): remove them")


def _all_to_all(blocks: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """The global (rows, columns) of node blocks coupled all to all (2 dofs a node)."""
    rows, cols = [np.zeros(0, np.int64)], [np.zeros(0, np.int64)]
    for blk in blocks:
        d = (2 * np.asarray(blk, dtype=np.int64)[:, None] + np.arange(2)).ravel()
        rows.append(np.repeat(d, len(d)))
        cols.append(np.tile(d, len(d)))
    return np.concatenate(rows), np.concatenate(cols)


def _as_tuple(value, key: str, what: str) -> tuple:
    """``value`` (None: empty) as a tuple, or a ValueError naming ``key``."""
    try:
        return tuple(value) if value is not None else ()
    except TypeError:
        raise ValueError(f"{key}: {what}, not {type(value).__name__}") from None


def _check_pairs(pairs: list, u) -> None:
    if pairs and not dx.is_p1_vector_space(u.function_space):
        raise ValueError("u: contact needs the displacement in the P1 vector space of the "
                         "mesh (two dofs at every vertex)")
    names = {}
    for k, p in enumerate(pairs):
        if not hasattr(p, "couplings"):
            raise ValueError(f"pairs[{k}]: a ContactPair, not {type(p).__name__}")
        if not dx.same_mesh(p.mesh, u.function_space.mesh):
            raise ValueError(f"contact {p.name}: the pair was built on another mesh than "
                             "u's function space")
        if any(q is p for q in pairs[:k]):
            raise ValueError(f"contact {p.name}: the same pair is given twice")
        if p.name in names:
            raise ValueError(f"contact {p.name}: pairs[{names[p.name]}] and pairs[{k}] have "
                             "the same name (records and files are by name): give each its "
                             "own name=")
        names[p.name] = k
        owner = p._problem() if p._problem is not None else None
        if owner is not None and not owner._closed:
            raise ValueError(f"contact {p.name}: the pair belongs to another ContactProblem "
                             "(a pair carries its problem's state): build a new ContactPair, "
                             "or close() the other problem first")
