"""Physics and input guards of the scene runner: no answer is accepted that is not a
converged physical solution, and no input the solver would choke on reaches it unnamed.

* :func:`check_petsc_options` asks PETSc itself, before meshing, whether it takes every
  option of ``solver.petsc`` (a value it rejects, an option it never reads);
* :func:`check_tolerance` compares ``solver.atol`` with the loads' residual scale;
* :class:`StepGuard` is the solver's last word on a converged load step: the SNES stopped
  by the convergence rule, and the solution inverts no cell (J = det F ≤ 0 at a quadrature
  point or a corner: SVK, say, has such solutions); otherwise the step failed (it is cut,
  then the run stops saying which cells);
* :func:`linear_failure` turns a failed factorization (MUMPS INFOG(1) < 0, a zero pivot)
  into the step's failure message;
* :func:`penetration_warning`: a penalty pair whose penetration exceeds a tenth of the
  local slave element size (the answer is then far from the contact constraint).
"""
from __future__ import annotations

import ctypes
import ctypes.util

import numpy as np
import ufl
from mpi4py import MPI
from petsc4py import PETSc

from . import _dolfinx as dx
from .scene import Scene, SceneError, SolverSettings

#: atol against the loads' residual scale: above, u = 0 passes as converged; below, it is
#: round-off
ATOL_RANGE = (1e-15, 1e-3)


# ----------------------------------------------------------------------------- PETSc


def _libpetsc():
    """The loaded PETSc library (petsc4py's), for the calls petsc4py 3.18 lacks."""
    with open("/proc/self/maps") as f:
        paths = {line.split()[-1] for line in f if "libpetsc" in line and "/" in line}
    path = next(iter(sorted(paths)), None) or ctypes.util.find_library("petsc_real")
    return ctypes.CDLL(path) if path else None


def _petsc_message(code: int) -> str:
    lib = _libpetsc()
    text = ctypes.c_char_p()
    if lib is not None and lib.PetscErrorMessage(code, ctypes.byref(text), None) == 0 \
            and text.value:
        return text.value.decode(errors="replace")
    return f"PETSc error {code}"


def _probe(settings: SolverSettings, user: dict) -> list[str]:
    """Apply the solver's options (defaults, then ``user``) to a throw-away SNES on this
    process as NewtonSolver does, and return the user options PETSc did not read. Raises
    PETSc.Error if PETSc rejects one."""
    from .solver import FACTOR_OPTIONS, _linear_solver_options, _petsc_line_search
    prefix = "fmcheck_"
    options = {"snes_type": "newtonls",
               "snes_linesearch_type": _petsc_line_search(settings.line_search),
               "snes_max_it": settings.max_iterations}
    options.update(_linear_solver_options(settings.linear_solver))
    options.update(user)
    opts = PETSc.Options()
    for k, v in options.items():
        opts[prefix + k] = v
    A = PETSc.Mat().createAIJ([2, 2], nnz=1, comm=PETSc.COMM_SELF)
    snes = PETSc.SNES().create(PETSc.COMM_SELF)
    try:
        A.setUp()
        A.setValue(0, 0, 1.0)
        A.setValue(1, 1, 1.0)
        A.assemble()
        snes.setOptionsPrefix(prefix)
        snes.setFunction(lambda s, x, f: x.copy(f), A.createVecLeft())
        snes.setJacobian(lambda s, x, J, P: None, A)
        snes.setFromOptions()
        snes.getKSP().setFromOptions()
        if any(k.startswith(FACTOR_OPTIONS) for k in user):
            # read at the first factorization: factorize the 2 x 2 identity
            snes.getKSP().setOperators(A)
            snes.getKSP().setUp()
        lib = _libpetsc()
        if lib is None:
            return []
        unused = []
        for k in user:
            flag = ctypes.c_int(0)
            lib.PetscOptionsUsed(None, (prefix + k).encode(), ctypes.byref(flag))
            if not flag.value:
                unused.append(k)
        return unused
    finally:
        for k in options:
            opts.delValue(prefix + k)
        snes.destroy()
        A.destroy()


def check_petsc_options(settings: SolverSettings) -> None:
    """Every ``solver.petsc`` option is taken by PETSc and read when the solver is set up
    or, for ``-mat_mumps_*``, at its first factorization (an option read never, as
    ``-snes_foo``, or not for this solver, as ``-mat_mumps_*`` with SuperLU_dist, would be
    silently ignored). Raises SceneError naming the option."""
    user = {k.lstrip("-"): "" if v is True else ("false" if v is False else str(v))
            for k, v in settings.petsc.items()}
    if not user:
        return
    try:
        unused = _probe(settings, user)
    except PETSc.Error:
        for k, v in user.items():   # which one: alone with the defaults
            try:
                _probe(settings, {k: v})
            except PETSc.Error as e:
                raise SceneError(f"solver.petsc: -{k} = {v!r}: PETSc rejects it "
                                 f"({_petsc_message(e.ierr)})") from None
        raise SceneError("solver.petsc: PETSc rejects these options together") from None
    if unused:
        raise SceneError(f"solver.petsc: -{unused[0]}: not read by PETSc when the solver is "
                         "set up (unknown, misspelt, not for this solver, or read too late to "
                         "take effect)" + (f"; also {', '.join('-' + k for k in unused[1:])}"
                                           if unused[1:] else ""))


def linear_failure(snes) -> str:
    """Why the linear solve of the last Newton iteration failed: the KSP's reason and, for
    a MUMPS factorization, INFOG(1) and INFOG(2)."""
    ksp = snes.getKSP()
    reasons = {v: k for k, v in vars(PETSc.KSP.ConvergedReason).items() if isinstance(v, int)}
    return f"the linear solve failed ({reasons.get(ksp.getConvergedReason(), 'unknown')}" \
           f"{_mumps_info(ksp.getPC())})"


def petsc_failure(snes, error: PETSc.Error) -> str:
    """The step's failure message for a PETSc error raised inside SNESSolve (e.g. a failed
    factorization with -ksp_error_if_not_converged)."""
    return f"PETSc error in the Newton solve: {_petsc_message(error.ierr)}" \
           f"{_mumps_info(snes.getKSP().getPC())}"


#: MUMPS INFOG(1) values that say a workspace (integer, real, or a buffer) was too small
_WORKSPACE = {-8, -9, -11, -12, -14, -15, -17, -20}


def out_of_workspace(snes) -> bool:
    """The last factorization was MUMPS's and failed for lack of workspace."""
    return _mumps_infog(snes.getKSP().getPC())[0] in _WORKSPACE


def _mumps_infog(pc) -> tuple[int, int]:
    """MUMPS's INFOG(1), INFOG(2) of the PC's factorization ((0, 0): not MUMPS's)."""
    try:
        if pc.getType() not in ("lu", "cholesky") or pc.getFactorSolverType() != "mumps":
            return 0, 0
        F = pc.getFactorMatrix()
        return F.getMumpsInfog(1), F.getMumpsInfog(2)
    except PETSc.Error:
        return 0, 0


def _mumps_info(pc) -> str:
    info, detail = _mumps_infog(pc)
    if info >= 0:
        return ""
    return f", MUMPS factorization failed: INFOG(1) = {info}, INFOG(2) = " \
           f"{detail}{_MUMPS.get(info, '')}"


_MUMPS = {-10: ": the matrix is numerically singular (a body or a direction left free? a slave "
               "node also held by a Dirichlet condition?)",
          -8: ": the workspace is too small (raise -mat_mumps_icntl_14)",
          -9: ": the workspace is too small (raise -mat_mumps_icntl_14)",
          -13: ": out of memory", -19: ": the memory limit ICNTL(23) is too small"}


# ---------------------------------------------------------------------- tolerances


def check_tolerance(scene: Scene, bulk, samples: int = 16) -> None:
    """``solver.atol`` within ATOL_RANGE of the loads' residual scale: the largest ‖R(u =
    0)‖ (bulk forms, Dirichlet rows included, as Newton's first residual) over the load
    path, sampled at up to ``samples`` load-step targets (the last one included) and as
    many evenly spaced pseudo-times (a step's cuts visit those: a full turn in one step has
    no load at its target). A scene without loads (scale 0) is not checked. Collective;
    call before the first step (u = 0)."""
    targets = scene.steps.targets()
    m = min(samples, len(targets))
    times = {targets[round(i * (len(targets) - 1) / max(m - 1, 1))] for i in range(m)}
    times |= {targets[-1] * (i + 1) / samples for i in range(samples)}
    b = dx.create_vector(bulk.residual)
    x = b.duplicate()
    x.set(0.0)
    scale = 0.0
    for t in sorted(times):
        bulk.set_time(t)
        dx.assemble_residual(b, bulk.residual, bulk.jacobian, bulk.bcs, x)
        scale = max(scale, b.norm())
    bulk.set_time(0.0)
    b.destroy()
    x.destroy()
    atol = scene.solver.atol
    low, high = ATOL_RANGE
    if scale > 0 and not low * scale <= atol <= high * scale:
        raise SceneError(f"solver.atol = {atol:g}: must lie in [{low:g}, {high:g}] x the loads' "
                         f"residual scale {scale:.3g} (|R| at u = 0 over the load path): "
                         + ("a larger atol passes u = 0 as converged" if atol > high * scale
                            else "a smaller one is below round-off"))


# ---------------------------------------------------------------------- step guard


#: a step whose displacement exceeds this many times the mesh's diameter is refused
FLOWN_OFF = 1e3


class StepGuard:
    """``solver.check_solution``: None for a physical converged state, else why not."""

    def __init__(self, scene: Scene, bulk, solver):
        dom = bulk.domain
        self.msh, self.solver = dom.mesh, solver
        F = ufl.Identity(2) + ufl.grad(bulk.u)
        self.J = dx.quadrature_expression(ufl.det(F), self.msh,
                                            scene.solver.quadrature_degree, vertices=True)
        self.cells = np.arange(dx.num_owned_cells(self.msh), dtype=np.int32)
        names = {dom.cell_groups[b.group]: b.name for b in scene.bodies}
        self.names = names
        body = np.full(dx.num_cells(self.msh), -1)
        body[dom.cell_tags.indices] = dom.cell_tags.values
        self.body = [names.get(int(t), "?") for t in body[self.cells]]
        x = dx.node_coordinates(self.msh)[:, :2]
        comm = self.msh.comm
        lo = [comm.allreduce(float(v), op=MPI.MIN) for v in x.min(axis=0, initial=np.inf)]
        hi = [comm.allreduce(float(v), op=MPI.MAX) for v in x.max(axis=0, initial=-np.inf)]
        self.size = float(np.hypot(hi[0] - lo[0], hi[1] - lo[1]))
        self.u = bulk.u
        self.free = free_directions(scene, dom, bulk)

    def unsupported(self) -> str | None:
        """A body that only contact holds along x or y (no Dirichlet value on that
        component) but that no pair touches at the converged state: its stiffness is
        singular there and Newton's answer is arbitrary. (Seen: an exactly touching start
        with a round-off slip threw the upper body ~9 units sideways, and every step then
        "converged" with zero contact force.) Bodies count as held through the pairs with
        an active node (gap closed), from the bodies Dirichlet values hold."""
        if not any(self.free.values()):
            return None
        links = []
        for h in self.solver.hooks:
            # in contact: a closed gap (to round-off), whether or not it carries pressure
            # (an exactly touching start under a load of 1e-9 converges at p = 0)
            st = getattr(h, "state", None)
            if st is not None and np.any(st.active):
                links.append((h.slave.body_tag, h.master.body_tag))
        for c, comp in enumerate("xy"):
            held = {tag for tag, free in self.free.items() if c not in free}
            grew = True
            while grew:
                grew = False
                for a, b in links:
                    if (a in held) != (b in held):
                        held |= {a, b}
                        grew = True
            lost = [self.names.get(tag, str(tag)) for tag, free in self.free.items()
                    if c in free and tag not in held]
            if lost:
                return (f"body {lost[0]!r} is held along {comp} by contact alone (no "
                        f"Dirichlet value on u_{comp}) and touches nothing at the converged "
                        "state: its stiffness is singular along "
                        f"{comp}, so this answer is arbitrary (was it pushed out of contact?)")
        return None

    def __call__(self) -> str | None:
        reason = self.solver.snes.getConvergedReason()
        if reason != PETSc.SNES.ConvergedReason.CONVERGED_FNORM_ABS:
            return (f"the SNES stopped with reason {reason}, not by the convergence rule "
                    "(a PETSc option replaced it?)")
        for h in self.solver.hooks:
            why = getattr(h, "passed_through", lambda: None)()
            if why:
                return why
        return self.flown_off() or self.unsupported() or self.inverted()

    def flown_off(self) -> str | None:
        """A displacement beyond FLOWN_OFF times the mesh's size (collective): Newton's
        answer to loads far beyond a material's stiffness (E = 1e-12 under a pressure of 1
        gave |u| = 1e14, the follower load on a collapsed edge, and zero reactions)."""
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
            J = dx.expression_eval(self.J, self.msh, self.cells)
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


def free_directions(scene: Scene, dom, bulk) -> dict[int, set[int]]:
    """Cell tag of each body → the components (0: x, 1: y) on which no node of it has a
    Dirichlet value (collective): contact alone holds it there."""
    V = bulk.V
    held = np.zeros(2 * len(dx.dof_coordinates(V)), dtype=bool)
    held[dx.bc_dofs(bulk.bcs)] = True
    blocks = dx.cell_dofs(V)
    comm = dom.mesh.comm
    out = {}
    for b in scene.bodies:
        tag = dom.cell_groups[b.group]
        nodes = np.unique(blocks[dom.cells(b.group)])
        have = [comm.allreduce(int(np.any(held[2 * nodes + c])), op=MPI.MAX) for c in (0, 1)]
        out[tag] = {c for c in (0, 1) if not have[c]}
    return out


def penetration_warning(pair, step: int) -> str | None:
    """For a penalty pair: the largest penetration −g̃_j/A_j against a tenth of the slave
    node's element size (its segments' mean reference length), or None."""
    st, s = pair.state, pair.slave
    if st is None or not len(s.seg):
        return None
    A = st.A
    pen = np.where(A > 0, -st.g / np.where(A > 0, A, 1.0), 0.0)
    length = np.linalg.norm(s.X[s.seg[:, 1]] - s.X[s.seg[:, 0]], axis=1)
    size, count = np.zeros(s.n), np.zeros(s.n)
    for col in (0, 1):
        np.add.at(size, s.seg[:, col], length)
        np.add.at(count, s.seg[:, col], 1.0)
    size /= np.maximum(count, 1.0)
    ratio = pen / np.where(size > 0, size, np.inf)
    j = int(np.argmax(ratio))
    if not ratio[j] > 0.1:
        return None
    x = st.xs[j]
    return (f"contact {pair.name}: penetration {pen[j]:.3g} at slave node ({x[0]:.4g}, "
            f"{x[1]:.4g}) in step {step} exceeds a tenth of the local slave element size "
            f"{size[j]:.3g}: the penalty is too soft for this load (raise "
            "enforcement.epsilon, or use type = 'alm')")
