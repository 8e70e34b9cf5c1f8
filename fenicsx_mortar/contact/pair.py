"""A contact pair in the Newton loop: surfaces → search → master curve → discretization
(weighted gaps) → enforcement (pressures) → friction → the residual and tangent terms.

The pair composes one object per concept, each from its registry (:mod:`.registry`):
the method's :class:`~.discretization.Discretization`, the smoothing's
:class:`~.curves.MasterCurve`, the :class:`~.enforcement.Enforcement` and the friction law.
It owns what ties them to the mesh: MPI ownership, the dofs, the predicted sparsity and
the per-iterate :class:`~.state.ContactState`.

Every rank holds both (1D) surfaces and evaluates the kernels; each slave node's terms are
inserted by the rank that owns its dofs, so every term enters the global system once.
"""
from __future__ import annotations

import warnings
from typing import Mapping, Sequence

import numpy as np
import scipy.sparse as sp
from mpi4py import MPI
from petsc4py import PETSc

from .. import _dolfinx as dx
from . import assembly, boundary, crossing, pair_input
from .curves import make_curve
from .registry import ENFORCEMENTS, FRICTION_LAWS, METHODS
from .search import candidate_pairs, search_once
from .state import ContactState
from .surface import build_surface


class ContactPair:
    """A slave (non-mortar) and a master (mortar) boundary that may touch.

    Built from what a DOLFINx user has: the P1 vector displacement space, facet meshtags
    and the tag value(s) of the two boundaries. The slave carries the multipliers: make it
    the softer body, or the finer mesh.

    Args:
        V: The displacement space: P1 vector Lagrange on a 2D mesh.
        facet_tags: Facet meshtags of V's mesh.
        slave: Tag value(s) of the slave boundary.
        master: Tag value(s) of the master boundary (another body's).
        name: The pair's name in records, files and field names (unique per problem).
        method: ``"mortar"`` or ``"nts"`` (``registry.METHODS``).
        smoothing: The master curve: ``"none"``, ``"averaged-simple"``,
            ``"averaged-weighted"``, ``"averaged-tangent"``, ``"hermite"``, ``"bspline"``.
        enforcement: ``"lagrange"`` (multipliers, semi-smooth Newton), ``"penalty"`` or
            ``"alm"`` (Uzawa augmented Lagrangian).
        epsilon: The penalty ε (a pressure per unit gap; default E/h, h the mean slave
            segment length); with ``lagrange`` it only steers the active set.
        tolerance: The ALM's KKT tolerance, relative to the pressure scale.
        friction: ``"none"`` or ``"coulomb"`` (``registry.FRICTION_LAWS``).
        mu: The friction coefficient: required with ``"coulomb"``, refused without.
        E: Young's modulus of the slave body (for the default ε), or a mapping cell tag →
            E of every body with ``cell_tags`` (then the pair also warns when a stiffer
            slave with finer segments would over-constrain a soft master).
        cell_tags: Optional cell meshtags: each surface must bound the cells of one tag.
        n_gauss: Gauss points per mortar segment (default 2 on the polyline, 4 on smoothed
            curves).
        search_radius: Contact search distance (default twice each slave segment's length).
        basis: The weight of the weighted gaps, ``"dual"`` (default with multipliers) or
            ``"standard"``.
        slave_smoothing: ``"hermite"`` measures the gap from the slave's own smoothed curve
            too (two-sided smoothing, mortar only; docs/smoothing.md).

    Raises:
        ValueError: an argument out of its range or not among its choices, named.
    """

    def __init__(self, V: dx.FunctionSpace, facet_tags: dx.MeshTags, slave: int | Sequence[int],
                 master: int | Sequence[int],
                 *, name: str = "contact", method: str = "mortar", smoothing: str = "none",
                 enforcement: str = "lagrange", epsilon: float | None = None,
                 tolerance: float = 1e-10, friction: str = "none", mu: float | None = None,
                 E: float | Mapping[int, float] | None = None,
                 cell_tags: dx.MeshTags | None = None, n_gauss: int | None = None,
                 search_radius: float | None = None, basis: str | None = None,
                 slave_smoothing: str = "none"):
        self.name = name
        pair_input.check_arguments(name, slave=slave, master=master, method=method,
                                   smoothing=smoothing, enforcement=enforcement,
                                   friction=friction, basis=basis,
                                   slave_smoothing=slave_smoothing)
        pair_input.check_numbers(name, epsilon=epsilon, tolerance=tolerance, mu=mu, E=E,
                                 n_gauss=n_gauss, search_radius=search_radius,
                                 cell_tags=cell_tags)
        if friction == "none" and mu not in (None, 0, 0.0):
            raise ValueError(f"contact {name}: mu = {mu!r} given with friction = 'none': "
                             "pass friction='coulomb' for Coulomb friction (or drop mu)")
        if friction != "none" and mu is None:
            raise ValueError(f"contact {name}: friction = {friction!r} needs mu, the friction "
                             "coefficient")
        mu = 0.0 if mu is None else float(mu)
        #: the problem the pair belongs to (set by ContactProblem; a weak reference)
        self._problem = None
        self._fields = None
        #: the mesh of the displacement space the pair was built on
        self.mesh = V.mesh
        self._space = V
        self.slave = build_surface(V, facet_tags, slave, f"{name}:slave", cell_tags)
        self.master = build_surface(V, facet_tags, master, f"{name}:master", cell_tags)
        s, m = self.slave, self.master
        shared = np.intersect1d(s.vertices, m.vertices)
        if shared.size:
            p = s.X[np.flatnonzero(np.isin(s.vertices, shared))[0]]
            raise ValueError(f"contact {name}: the slave and master surfaces share "
                             f"{shared.size} node(s) (the first at ({p[0]:.6g}, {p[1]:.6g})): "
                             "contact joins the boundaries of two separate bodies")
        if s.body_tag >= 0 and s.body_tag == m.body_tag:
            raise ValueError(f"contact {name}: slave and master bound the same body (cell tag "
                             f"{s.body_tag}); self-contact is not supported: a contact pair "
                             "joins two bodies")
        pair_input.check_facing(name, self.slave, self.master)
        pair_input.check_overlap(name, self.slave, self.master)
        if isinstance(E, Mapping):
            missing = sorted({s.body_tag, m.body_tag} - set(E))
            if missing:
                raise ValueError(f"contact {name}: E has no value for the cell tag(s) "
                                 f"{missing} of the bodies the surfaces bound")
            E, E_master = E[s.body_tag], E[m.body_tag]
            pair_input.check_roles(name, s, m, E, E_master)
            if getattr(ENFORCEMENTS[enforcement], "unknowns", 0):
                # where ε only steers the active and stick/slip sets, the softer body's
                # stiffness steers them best (ironing, a 10x stiffer slave: E_slave/h
                # cycled at 55 cuts, E_master/h converged in 5 Newton iterations a step)
                E = min(E, E_master)
        self.h = h = s.mean_length()
        if E is None and epsilon is None:
            raise ValueError(f"contact {name}: give the slave body's Young's modulus E (for "
                             "the default epsilon = E/h) or epsilon")
        nominal = E / h if E is not None else epsilon
        eps = epsilon or nominal
        if enforcement == "penalty" and eps > 1e3 * nominal:
            warnings.warn(f"contact {name}: penalty epsilon = {eps:.3g} is "
                          f"{eps / nominal:.0e} x E/h = {nominal:.3g}: round-off in epsilon*gap "
                          "may keep Newton from converging; prefer enforcement type 'alm'",
                          stacklevel=2)
        # gaps are differences of coordinates: below ~32 ulp of the largest one they are noise
        scale = max(np.abs(s.X).max(initial=0.0), np.abs(m.X).max(initial=0.0), h)
        self.enforcement = ENFORCEMENTS[enforcement](
            eps, s.n, tolerance, 32 * np.finfo(float).eps * scale, start=nominal)
        #: unknowns of the pair's own per slave node (the enforcement's multipliers), 0: none
        self.unknowns = int(getattr(self.enforcement, "unknowns", 0))
        if self.unknowns:
            self.enforcement.scale = boundary.full_areas(s.X, s.seg, s.n)
        kind = METHODS[method]
        if basis is None:   # the dual basis where the multipliers are unknowns
            basis = "dual" if self.unknowns and "dual" in kind.bases else "standard"
        self.discretization = kind(s, m, n_gauss, basis=basis,
                                   slave_smoothing=slave_smoothing)
        self.friction = FRICTION_LAWS[friction](mu, self.enforcement.epsilon0, s.n)
        # two of the slave segment's own lengths: the mean would search a graded mesh's
        # refined zone with the coarse part's reach (Hertz a/10: 15 h_c, half the LU's work
        # in explicit zeros of the couplings' pattern)
        self.radius = search_radius or 2.0 * s.lengths()
        self.dofs = np.concatenate([s.dofs.ravel(), m.dofs.ravel()])
        # the master curve, moved with the nodes; the B-spline's parametrization is that of
        # the reference configuration for the whole run (docs/design.md §6): rebuilt from
        # each step's converged nodes it moved the curve between the nodes at every step
        # start, and on the level-3 half-rings every full turn increment then failed
        self._curve = make_curve(smoothing, m.X, m.seg)
        self.weight = s.owned.astype(float)
        # this rank integrates the slave segments touching the nodes whose dofs it owns and
        # their neighbours: the weighted gaps of its nodes are then complete here, also
        # where the master's edge hands terms one node on (boundary.py), and their terms
        # are inserted by this rank only (the rows of other ranks' nodes weigh 0)
        self.my_segments = boundary.segments_to_integrate(s.owned, s.seg, s.neighbours)
        self.layouts = assembly.Layouts()
        self.augmentations = 0
        self._first_jacobian = True
        self.index, self.skip, self.n_global = self.dofs, np.zeros(0, np.int64), dx.dof_count(V)
        self.state: ContactState | None = None
        self.timings = None
        #: slave and master nodes at the start of the step (crossing.passed_through)
        self._start = (s.X, m.X)
        r = np.broadcast_to(self.radius, (len(s.seg),))
        self._node_radius = np.zeros(s.n)
        for col in (0, 1):
            np.maximum.at(self._node_radius, s.seg[:, col], r)

    @property
    def path_dependent(self) -> bool:
        """The answer depends on the load path (friction's history)."""
        return self.friction.path_dependent

    def _timed(self, phase: str):
        if self.timings is None:
            return _Untimed()
        return self.timings(phase)

    # -- kinematics ---------------------------------------------------------------------
    def update(self, u: "dx.Function") -> None:
        """Make :attr:`state` the contact state at a displacement (collective).

        Args:
            u: The displacement Function of the pair's space.
        """
        with self._timed("contact"):
            xs = self.slave.X + self.slave.displacement(u)
            xm = self.master.X + self.master.displacement(u)
            self.state = self._evaluate(xs, xm)

    def _evaluate(self, xs: np.ndarray, xm: np.ndarray) -> ContactState:
        s, m = self.slave, self.master
        with self._timed("contact_search"):
            pairs = candidate_pairs(xs, s.seg, xm, m.seg, self.radius)
            if not self.my_segments.all():
                keep = self.my_segments[pairs[0]]
                pairs = (pairs[0][keep], pairs[1][keep])
        # projection and integration are one vectorized pass (kernel = both)
        with self._timed("contact_kernel"):
            curve = self._curve.with_nodes(xm)
            gap, area, g, A = self.discretization.weighted_gaps(xs, xm, curve, pairs)
        st = ContactState(xs, xm, curve, pairs, gap, area, g, A, self.layouts)
        self.enforcement.annotate(st)
        st.law = self.enforcement.pressure(g, A)
        self.friction.update(st, s)
        return st

    # -- residual and tangent -------------------------------------------------------------
    def nodal_forces(self, weight: np.ndarray | None = None) -> np.ndarray:
        """The contact residual over the stacked node coordinates [slave, master] (the
        forces the bodies exert on the interface): normal, plus tangential with friction.

        Args:
            weight: Per slave node, the weight of its terms (default: 1 for the nodes this
                rank owns, 0 for the others).

        Returns:
            (2 (n_slave + n_master),) forces, x and y per node.
        """
        w = self.weight if weight is None else weight
        parts = [self.enforcement.residual(self.state, w),
                 self.friction.residual(self.state, w)]
        return _sum(parts)

    def add_residual(self, b: "PETSc.Vec", bc_dofs: np.ndarray) -> None:
        """Add this rank's contact terms to a residual vector.

        Args:
            b: The residual (the pair's global dof numbering; off-process entries are sent).
            bc_dofs: Dirichlet dofs (their rows are replaced by the caller).
        """
        f = self.nodal_forces()
        with self._timed("contact_insertion"):
            assembly.add_to_vector(b, self.dofs, f)

    def tangent(self):
        """The pair's tangent over its local unknowns [stacked node coordinates, then its
        multipliers] (COO, repeated entries to be summed), rows of this rank's slave nodes;
        the first call of a load step adds the touching nodes' stiffness."""
        st, w = self.state, self.weight
        K = _sum([self.enforcement.tangent(st, w, self._first_jacobian),
                  self.friction.tangent(st, w)])
        self._first_jacobian = False
        return K

    def add_jacobian(self, A: "PETSc.Mat", bc_dofs: np.ndarray) -> None:
        """Add this rank's contact tangent to the Jacobian (Dirichlet rows and columns left
        out, at the indices :meth:`attach` gave).

        Args:
            A: The Jacobian matrix.
            bc_dofs: Dirichlet dofs (unused: the system's ``skip`` holds them globally).
        """
        self.insert_tangent(A, self.tangent())

    def insert_tangent(self, A: "PETSc.Mat", K: sp.spmatrix) -> None:
        """Add a tangent of :meth:`tangent` to the Jacobian (as :meth:`add_jacobian`).

        Args:
            A: The Jacobian matrix.
            K: The tangent.
        """
        with self._timed("contact_insertion"):
            assembly.add_to_matrix(A, K, self.index, self.skip, self.n_global, self.layouts)

    def new_slots(self, K: sp.spmatrix) -> tuple[np.ndarray, np.ndarray]:
        """The global (rows, columns) inserting the tangent ``K`` may need in the Jacobian
        (none when it has the last insertion's structure), for ``assembly.reserve``.

        Args:
            K: A tangent of :meth:`tangent`.

        Returns:
            Rows and columns.
        """
        return assembly.new_slots(K, self.index, self.skip, self.layouts)

    def attach(self, index: np.ndarray, skip: np.ndarray, n_global: int) -> None:
        """Where the pair's terms go in the global system (called by :mod:`.system`).

        Args:
            index: Global index of each of the pair's local unknowns: the stacked node
                coordinates [slave, master], then its multipliers.
            skip: Global rows and columns to leave out (Dirichlet).
            n_global: The global size.
        """
        self.index, self.skip, self.n_global = index, skip, n_global

    # -- the pair's own unknowns (multipliers) ----------------------------------------------
    def multipliers(self) -> np.ndarray:
        """(n_slave, unknowns) current values of the pair's own unknowns."""
        return self.enforcement.lam

    def set_multipliers(self, lam: np.ndarray) -> None:
        """Set the pair's own unknowns.

        Args:
            lam: (n_slave, unknowns) values, the same on every rank.
        """
        self.enforcement.lam = lam

    def multiplier_residual(self) -> np.ndarray:
        """(n_slave, unknowns) the rows of the pair's own unknowns (this rank's nodes)."""
        return self.enforcement.multiplier_residual(self.state, self.weight)

    def kkt_residual(self) -> float:
        """The Alart–Curnier KKT residual of the state, relative to the pressure scale."""
        st = self.state
        return self.enforcement.kkt_residual(st.g, st.A, st.p, st.tangential)

    def decision(self) -> np.ndarray | None:
        """What the semi-smooth Newton decides per slave node: 0 inactive, 1 active (plus,
        with friction, the stick/slip status and the slip direction)."""
        st = self.state
        if st is None:
            return None
        return st.active.astype(np.int8) + self.friction.decision(st)

    def update_due(self, fnorm: float, first: float) -> bool:
        """Within a Newton solve: whether the enforcement would rather update its
        multipliers now than have the solve converge (inexact Uzawa).

        Args:
            fnorm: The residual norm at the present iterate.
            first: The residual norm at the solve's start.

        Returns:
            True to stop the solve here for the update (never for a law without one).
        """
        st = self.state
        return st is not None and self.enforcement.update_due(st.g, st.A, st.p,
                                                               st.tangential, fnorm, first)

    # -- step lifecycle -------------------------------------------------------------------
    def augment(self) -> bool:
        """Between converged Newton solves: update the enforcement (Uzawa, ε continuation);
        True when another solve is needed."""
        st = self.state
        again = self.enforcement.augment(st.g, st.A, st.p, st.tangential)
        if again:
            self.augmentations += 1
        return again

    def begin_step(self) -> None:
        """Before the first Newton solve of a load step (or of a retry of one)."""
        self.enforcement.begin_step()
        self.friction.begin_step()
        self.augmentations = 0
        self._first_jacobian = True
        if self.state is not None:
            self._start = (self.state.xs, self.state.xm)

    def passed_through(self) -> str | None:
        """Why the current state is not a contact solution, if slave nodes passed through
        the master during the step unseen by the search (:mod:`.crossing`), else None. The
        same on every rank (the surfaces' coordinates are gathered)."""
        st = self.state
        if st is None:
            return None
        nodes, depth = crossing.passed_through(*self._start, st.xs, st.xm, self.master.seg,
                                               self._node_radius)
        if nodes.size:
            # keep those the search does not see: no master candidate for either of the
            # node's segments (the search reaches up to about twice the radius)
            s = self.slave
            mine = np.flatnonzero(np.isin(s.seg, nodes).any(axis=1))
            radius = self.radius if np.ndim(self.radius) == 0 else self.radius[mine]
            found, _ = search_once(st.xs, s.seg[mine], st.xm, self.master.seg, radius)
            seen = np.unique(s.seg[mine[found]])
            keep = ~np.isin(nodes, seen)
            nodes, depth = nodes[keep], depth[keep]
        if not nodes.size:
            return None
        j = int(np.argmax(depth))
        x = st.xs[nodes[j]]
        return (f"contact {self.name}: {nodes.size} slave node(s) passed through the master "
                f"in this increment, unseen by the contact search (deepest {depth[j]:.3g} "
                f"behind it at ({x[0]:.4g}, {x[1]:.4g}); search radius "
                f"{self._node_radius[nodes[j]]:.3g}); a smaller increment or a larger "
                "search_radius finds the contact")

    def accept_step(self) -> None:
        """Commit the step's history (multipliers, friction reference points)."""
        self.enforcement.accept()
        self.friction.accept(self.state)

    def reject_step(self) -> None:
        """Go back to the history of the last accepted step."""
        self.enforcement.reject()
        self.friction.reject()

    def state_dict(self) -> dict[str, np.ndarray]:
        """History carried between steps (for checkpoints; collective). The enforcement's
        is the same on every rank; the discretization's and the friction's hold each node's
        values on the rank that owns it."""
        d = self.enforcement.state_dict()
        for part in (self.discretization, self.friction):
            d.update({k: self._from_owners(v) for k, v in part.state_dict().items()})
        return d

    def load_state_dict(self, d: dict[str, np.ndarray]) -> None:
        """Restore the history of :meth:`state_dict` (a checkpoint).

        Args:
            d: The arrays by name.
        """
        self.enforcement.load_state_dict(d)
        self.discretization.load_state_dict(d)
        self.friction.load_state_dict(d)

    def _from_owners(self, v: np.ndarray) -> np.ndarray:
        comm = self.slave.comm
        if comm.size == 1:
            return v.copy()
        return comm.allreduce(np.where(self.slave.owned, v, np.zeros((), v.dtype)), op=MPI.SUM)

    # -- outputs ------------------------------------------------------------------------
    def interface(self) -> dict[str, np.ndarray]:
        """Nodal values along the slave surface, node by node along its chain(s), the same
        on every rank.

        Returns:
            Arrays by name: ``vertex`` (the node's global vertex number in the mesh's
            topology), ``s`` (arc length), ``x``, ``y`` (current position), ``gap`` (average
            normal gap g̃/A, a length; nan where the node sees no master), ``pressure``
            (normal traction, force per unit current length), ``active`` (0/1); with
            friction ``t_tangential`` (per unit current length), ``slip``, ``status``.
        """
        from .output import interface_table
        return interface_table(self)

    def fields(self) -> dict:
        """The pair's nodal results as DOLFINx Functions (P1 scalars on the mesh, zero off
        the slave surface), set from the last state; ready for ``XDMFFile.write_function``
        or a VTX writer (contact/fields.py).

        Returns:
            Functions by name: ``contact_pressure``, ``contact_gap`` and, with friction,
            ``tangential_traction`` and ``stick_slip`` (0 inactive, 1 stick, 2 slip); the
            same objects at every call (their names carry the pair's name).
        """
        from .fields import PairFields
        if self._fields is None:
            self._fields = PairFields(self, self._space)
        return self._fields.update()

    def record(self) -> dict:
        """The step record of the pair (:func:`.output.pair_record`)."""
        from .output import pair_record
        return pair_record(self)

    def couplings(self) -> list[np.ndarray]:
        """Per slave node: the node blocks (global) its weighted gap can depend on — its
        neighbours and the stencils of the master candidates of its segments, found with a
        generous radius — for the matrix's sparsity pattern."""
        return [np.unique(d // 2) for d in self.couplings_by_node()]

    def couplings_by_node(self) -> list[np.ndarray]:
        """For slave node j (list index): the global dofs its terms can depend on (see
        :meth:`couplings`)."""
        s, m = self.slave, self.master
        # three of the finest segment's radius: the coarse far part of a graded slave would
        # otherwise preallocate dense blocks to half the master (Hertz a/20: 460k stored
        # entries against 297k); couplings beyond it grow the matrix when they appear
        ps, pm = candidate_pairs(s.X, s.seg, m.X, m.seg, 3.0 * np.min(self.radius))
        curve = self._curve
        stencil = curve.stencil(pm) if len(pm) else np.zeros((0, curve.stencil_size),
                                                             dtype=np.int64)
        if curve.point_map is not None:  # points → the master nodes they are made of
            pm_csr = curve.point_map.tocsr()
            reach = [pm_csr.indices[pm_csr.indptr[i]:pm_csr.indptr[i + 1]]
                     for i in range(pm_csr.shape[0])]
            stencil = [np.unique(np.concatenate([reach[i] for i in row])) for row in stencil]
        per_node: dict[int, set[int]] = {}
        slave_curve = getattr(self.discretization, "slave_curve", lambda x: None)(s.X)
        stencil_s = (slave_curve.stencil(np.arange(len(s.seg))) if slave_curve is not None
                     else s.seg)
        for (a, b), row in zip(s.seg, stencil_s):
            for j in (a, b):
                per_node.setdefault(int(j), set()).update(int(i) for i in row)
        for k, seg_i in enumerate(ps):
            a, b = s.seg[seg_i]
            for j in (a, b):
                per_node[int(j)].update(int(i) + s.n for i in stencil[k])
        node_dofs = np.concatenate([s.dofs, m.dofs])
        return [np.unique(node_dofs[np.fromiter(per_node.get(j, ()), dtype=np.int64)])
                for j in range(s.n)]


class _Untimed:
    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return False


def _sum(parts):
    """The sum of the contributions that are not None."""
    parts = [p for p in parts if p is not None]
    out = parts[0]
    for p in parts[1:]:
        out = out + p
    return out
