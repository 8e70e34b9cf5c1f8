"""PETSc options of the Newton solver, applied under an options prefix, and PETSc's own
word on them: which options PETSc rejects or never reads, and why a factorization failed.

DOLFINx's convention (``fem.petsc.NonlinearProblem``): the solver's options live in PETSc's
global options database under a prefix the user chooses, so the command line and the
database reach the solver (``-<prefix>snes_monitor``); the options given as a dict are set
there, read once, and removed again. Ours: the package's defaults are set only where the
database has no value of its own, so a command-line ``-<prefix>ksp_type`` is not
overwritten; MUMPS's ``-mat_mumps_*`` options are read at every new factorization, not at
set-up, so they stay in the database while the solver lives.
"""
from __future__ import annotations

import ctypes
import ctypes.util
import weakref
from typing import Iterable, Mapping

from mpi4py import MPI  # noqa: F401  (before petsc4py: the PyPI wheel needs it, _dolfinx.py)
from petsc4py import PETSc

from . import _dolfinx as dx
from .settings import SolverSettings

#: options read at a factorization or a preconditioner's set-up, not at the solver's: kept
#: in the database while the solver lives (a multigrid's level solvers are made and read
#: their options at its first set-up)
FACTOR_OPTIONS = ("mat_mumps_", "mg_levels_", "mg_coarse_")
#: which live solver set a kept option last: two solvers under one prefix share the keys,
#: and a dead one must not take the live one's options with it
_OWNER: dict[str, object] = {}
#: SNES types whose iterations our convergence rule and active-set callbacks steer
NEWTON_TYPES = ("newtonls",)


def normalize(options: Mapping[str, object] | None) -> dict[str, str]:
    """Options as PETSc's database takes them: keys without '-', True → '' (a flag),
    False → 'false', numbers as text.

    Args:
        options: ``{"-ksp_type": "gmres", "snes_monitor": True, ...}`` or None.

    Returns:
        ``{"ksp_type": "gmres", "snes_monitor": "", ...}``.
    """
    out = {}
    for k, v in (options or {}).items():
        if not isinstance(k, str) or not k.lstrip("-"):
            raise ValueError(f"petsc_options: {k!r} is not a PETSc option name")
        out[k.lstrip("-")] = "" if v is True else ("false" if v is False else str(v))
    return out


def line_search_type(kind: str) -> str:
    """PETSc's line-search type for ours: ``l2-full`` is ``basic`` with a precheck; ``l2``
    is PETSc's secant search, whatever this PETSc calls it."""
    return "basic" if kind == "l2-full" else (dx.LINE_SEARCH_SECANT if kind == "l2" else kind)


def line_search_options(kind: str) -> dict[str, str]:
    """PETSc options of our line search ``kind`` (PETSc >= 3.24's secant search also
    needs its step range set to l2's)."""
    petsc = line_search_type(kind)
    extra = dx.LINE_SEARCH_SECANT_OPTIONS if petsc == dx.LINE_SEARCH_SECANT else {}
    return {"snes_linesearch_type": petsc, **{k: str(v) for k, v in extra.items()}}


#: GMRES on the condensed contact Jacobian (nonsymmetric): right preconditioning, so
#: that the tolerance (Eisenstat–Walker's, condensation/ksp.py Forcing) bounds the true
#: residual; flexible GMRES, which keeps the preconditioned vectors and so builds the
#: solution without one more V-cycle (GMRES's right-preconditioned update costs one a
#: solve: 54 V-cycles against 46 on Hertz's 8 Newton systems at 2M)
_KRYLOV = {"ksp_type": "fgmres", "ksp_gmres_restart": "50", "ksp_pc_side": "right",
           "ksp_norm_type": "unpreconditioned", "ksp_max_it": "1000"}
#: the condensed path's AMG settings (tried on the Hertz iterates while the path was
#: developed; docs/condensation.md §3-4, §6)
_AMG = {"gmres-gamg": {"pc_type": "gamg", "pc_gamg_type": "agg", "pc_gamg_agg_nsmooths": "1",
                       "pc_gamg_threshold": "0.02"},
        "gmres-hypre": {"pc_type": "hypre", "pc_hypre_type": "boomeramg",
                        "pc_hypre_boomeramg_coarsen_type": "HMIS",
                        "pc_hypre_boomeramg_interp_type": "ext+i",
                        "pc_hypre_boomeramg_P_max": "4"},
        # a V-cycle with one symmetric SOR sweep each way and MUMPS on the coarsest mesh:
        # 0.6 decades an iteration on Hertz at 2M dofs, the fastest of Chebyshev(2, 3) and
        # SOR (1, 2 sweeps) there (docs/condensation.md §6)
        "gmres-gmg": {"pc_type": "mg", "pc_mg_galerkin": "both",
                      "mg_levels_ksp_type": "richardson", "mg_levels_ksp_max_it": "1",
                      "mg_levels_pc_type": "sor", "mg_coarse_ksp_type": "preonly",
                      "mg_coarse_pc_type": "lu",
                      "mg_coarse_pc_factor_mat_solver_type": "mumps"}}


def linear_solver_options(name: str, condensed: bool = False) -> dict[str, str]:
    """The KSP and PC options of a :data:`~.settings.LINEAR_SOLVERS` name.

    Args:
        name: The linear solver.
        condensed: For the condensed system of dual multipliers (condensation/): MUMPS
            on it for "condensed-mumps", and the Krylov methods without a fixed tolerance
            (inexact Newton decides it).

    Returns:
        Options without the prefix.
    """
    if name in _AMG and (condensed or name == "gmres-gmg"):
        # (gmres-gmg has no other path: without condensation its options are only probed)
        return {**_KRYLOV, **_AMG[name]}
    if name == "gmres-hypre":
        return {"ksp_type": "gmres", "pc_type": "hypre", "ksp_rtol": "1e-12"}
    if name == "gmres-gamg":
        return {"ksp_type": "gmres", "pc_type": "gamg", "ksp_rtol": "1e-12"}
    # "auto" before it is resolved (scene checks before meshing): its small-problem choice
    lu = "mumps" if name in ("condensed-mumps", "auto") else name
    return {"ksp_type": "preonly", "pc_type": "lu", "pc_factor_mat_solver_type": lu}


def defaults(settings: SolverSettings, condensed: bool = False) -> dict[str, str]:
    """The package's options for ``settings``, before the user's (``condensed``: for the
    inner solve of the condensed system)."""
    out = {"snes_type": "newtonls", **line_search_options(settings.line_search),
           "snes_max_it": str(settings.max_iterations), "snes_max_funcs": "100000"}
    out.update(linear_solver_options(settings.linear_solver, condensed))
    return out


class Applied:
    """The options of one solver in the database under its prefix: applied with
    :meth:`set_from_options`, the kept (factorization) ones removed by :meth:`drop` or when
    the object is garbage."""

    def __init__(self, prefix: str, settings: SolverSettings,
                 user: Mapping[str, str], condensed: bool = False):
        self.prefix = prefix
        self.settings = settings
        opts = PETSc.Options()
        own = {k: v for k, v in defaults(settings, condensed).items()
               if not opts.hasName(prefix + k)}
        self.options = {**own, **user}
        self.factor_keys = [prefix + k for k in self.options if k.startswith(FACTOR_OPTIONS)]
        self._token = object()
        # (grow_workspace adds to the list; the finalizer sees it)
        self._finalizer = weakref.finalize(self, _drop, self.factor_keys, self._token)

    def set_from_options(self, snes: PETSc.SNES, extra: Iterable = ()) -> None:
        """Put the options in the database, let SNES and KSP (and the ``extra`` objects:
        the condensed system's inner KSP) read them, and remove them again (but the
        factorization options; a value the database had before returns)."""
        opts = PETSc.Options()
        before = {k: opts.getString(self.prefix + k) for k in self.options
                  if opts.hasName(self.prefix + k)}
        for k, v in self.options.items():
            opts[self.prefix + k] = v
        snes.setFromOptions()
        snes.getKSP().setFromOptions()
        for obj in extra:
            obj.setFromOptions()
        for k in self.options:
            if self.prefix + k in self.factor_keys:
                continue
            if k in before:
                opts[self.prefix + k] = before[k]
            else:
                opts.delValue(self.prefix + k)
        for k in self.factor_keys:
            _OWNER[k] = self._token

    def set_factor_option(self, key: str, value) -> None:
        """Set a factorization option (read at the next factorization)."""
        PETSc.Options()[self.prefix + key] = value
        _OWNER[self.prefix + key] = self._token
        if self.prefix + key not in self.factor_keys:
            self.factor_keys.append(self.prefix + key)

    def drop(self) -> None:
        self._finalizer()


def _drop(keys: list[str], token: object) -> None:
    opts = PETSc.Options()
    for k in keys:
        if _OWNER.get(k) is token:
            opts.delValue(k)
            del _OWNER[k]


# ------------------------------------------------------------------- checks of options


def check_solver_choice(settings: SolverSettings, user: Mapping[str, str],
                        multipliers: bool, key: str = "petsc_options",
                        condensable: bool = False) -> None:
    """Options that cannot work with this problem, refused by name: an SNES type other
    than Newton's (``ksponly`` does one linear solve and reports success; our convergence
    rule and the active set live in the Newton iterations), a replaced convergence test,
    and, with multipliers solved as a saddle point (zero pivots), a factorization without
    MUMPS's pivoting or an iterative method. With dual multipliers a linear solver of the
    condensed path (``settings.CONDENSED_SOLVERS``) solves a displacement-only system:
    any KSP and PC are taken there.

    Args:
        settings: The solver settings.
        user: The user's options (normalized).
        multipliers: Some pair has multipliers as unknowns.
        key: How messages name the options.
        condensable: Every pair with multipliers uses the dual basis.

    Raises:
        ValueError: naming the option.
    """
    from .settings import CONDENSED_SOLVERS
    snes = user.get("snes_type", "newtonls")
    if snes not in NEWTON_TYPES:
        raise ValueError(f"{key}: -snes_type {snes}: the contact solver is Newton's method "
                         "(newtonls): its convergence rule and active-set updates run in "
                         "the Newton iterations (a type that does not iterate, as ksponly, "
                         "would report a wrong answer as converged)")
    if "snes_convergence_test" in user:
        raise ValueError(f"{key}: -snes_convergence_test would replace the convergence rule "
                         "(residual below atol and rtol, docs/design.md §5)")
    if not multipliers:
        return
    if settings.linear_solver in CONDENSED_SOLVERS:
        if condensable:
            return
        raise ValueError(f"{key}: linear_solver = {settings.linear_solver!r} condenses the "
                         "multipliers, which needs the dual basis on every pair with "
                         "multipliers (mortar, basis 'dual'); with the standard basis or "
                         "node-to-segment the saddle-point system needs 'mumps'")
    options = {**defaults(settings), **user}
    lu = options.get("pc_factor_mat_solver_type", "mumps")
    iterative = options.get("ksp_type") != "preonly" or options.get("pc_type") != "lu"
    if iterative or lu != "mumps":
        what = (f"-ksp_type {options.get('ksp_type')} -pc_type {options.get('pc_type')}"
                if iterative else f"-pc_factor_mat_solver_type {lu}")
        raise ValueError(f"{key}: {what} cannot solve the saddle-point system of the "
                         "Lagrange multipliers (zero pivots that need MUMPS's pivoting, no "
                         "preconditioner for the multiplier rows): use MUMPS, or with the "
                         "dual basis a condensed linear solver ('condensed-mumps', "
                         "'gmres-gamg', 'gmres-hypre', 'gmres-gmg'), or enforcement 'alm' "
                         "or 'penalty'")


#: the external packages a linear solver may name, and the option that names them
_PACKAGES = {"hypre": "pc_type", "mumps": "pc_factor_mat_solver_type",
             "superlu_dist": "pc_factor_mat_solver_type"}


def check_packages(settings: SolverSettings, user: Mapping[str, str],
                   key: str = "petsc_options", settings_key: str = "settings") -> None:
    """The linear solver's external package is in this PETSc build (PyPI's DOLFINx wheel
    has no hypre; without this check PETSc fails inside SNESSetFromOptions).

    Args:
        settings: The Newton settings (their ``linear_solver``).
        user: The user's PETSc options, normalized.
        key: How messages name ``user``.
        settings_key: How messages name ``settings``.

    Raises:
        ValueError: naming the package and the setting that asks for it.
    """
    options = {**defaults(settings), **user}
    for package, option in _PACKAGES.items():
        if options.get(option) == package and not PETSc.Sys.hasExternalPackage(package):
            source = (f"{key}: -{option} {package}" if user.get(option) == package else
                      f"{settings_key}.linear_solver = {settings.linear_solver!r}")
            raise ValueError(f"{source}: this PETSc is built without {package} (PyPI's "
                             "DOLFINx wheel has no hypre); choose another linear solver, "
                             "e.g. 'mumps'")


def _libpetsc():
    """The loaded PETSc library (petsc4py's), for the calls petsc4py lacks."""
    with open("/proc/self/maps") as f:
        paths = {line.split()[-1] for line in f if "libpetsc" in line and "/" in line}
    path = next(iter(sorted(paths)), None) or ctypes.util.find_library("petsc_real")
    return ctypes.CDLL(path) if path else None


def error_message(code: int) -> str:
    """PETSc's text for an error code."""
    lib = _libpetsc()
    text = ctypes.c_char_p()
    if lib is not None and lib.PetscErrorMessage(code, ctypes.byref(text), None) == 0 \
            and text.value:
        return text.value.decode(errors="replace")
    return f"PETSc error {code}"


def _probe(settings: SolverSettings, user: Mapping[str, str]) -> list[str]:
    """Apply the defaults and ``user`` to a throw-away SNES as the solver does and return
    the user options PETSc did not read. Raises PETSc.Error if PETSc rejects one."""
    prefix = "fmcheck_"
    options = {**defaults(settings), **user}
    opts = PETSc.Options()
    for k, v in options.items():
        opts[prefix + k] = v
    # a multigrid makes (and configures) its levels only for a matrix large enough to
    # coarsen: a 1D Laplacian then, else the 2 x 2 identity
    n = 1000 if any(k.startswith(("mg_levels_", "mg_coarse_")) for k in user) \
        or options.get("pc_type") == "mg" else 2
    P = None
    A = PETSc.Mat().createAIJ([n, n], nnz=3, comm=PETSc.COMM_SELF)
    snes = PETSc.SNES().create(PETSc.COMM_SELF)
    try:
        A.setUp()
        for i in range(n):
            A.setValue(i, i, 2.0 if n > 2 else 1.0)
            if n > 2 and i > 0:
                A.setValue(i, i - 1, -1.0)
                A.setValue(i - 1, i, -1.0)
        A.assemble()
        snes.setOptionsPrefix(prefix)
        snes.setFunction(lambda s, x, f: x.copy(f), A.createVecLeft())
        snes.setJacobian(lambda s, x, J, P: None, A)
        snes.setFromOptions()
        P = _two_levels(snes.getKSP().getPC(), n)
        snes.getKSP().setFromOptions()
        if P is not None or any(k.startswith(FACTOR_OPTIONS) for k in user):
            # read at the first factorization or multigrid set-up
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
        if P is not None:
            P.destroy()


def _two_levels(pc: PETSc.PC, n: int) -> PETSc.Mat | None:
    """A geometric multigrid probed gets two levels (linear interpolation from n/2 points
    to n), as the condensed system gives it its prolongations: its level and coarse
    options are read only then. Returns the interpolation (None: not a multigrid)."""
    if pc.getType() != PETSc.PC.Type.MG or n < 4:
        return None
    m = n // 2
    P = PETSc.Mat().createAIJ([n, m], nnz=2, comm=PETSc.COMM_SELF)
    P.setUp()
    for j in range(m):
        P.setValue(2 * j, j, 1.0)
        P.setValue(2 * j + 1, j, 0.5)
        if j + 1 < m:
            P.setValue(2 * j + 1, j + 1, 0.5)
    P.assemble()
    pc.setMGLevels(2)
    pc.setMGInterpolation(1, P)
    return P


def unread(settings: SolverSettings, user: Mapping[str, str],
           key: str = "petsc_options") -> list[str]:
    """The options of ``user`` that PETSc does not read when the solver is set up (or, for
    ``-mat_mumps_*``, at its first factorization): unknown, misspelt, or not for this
    solver (``-mat_mumps_*`` with SuperLU_dist).

    Returns:
        The unread option names (without '-').

    Raises:
        ValueError: naming an option whose value PETSc rejects.
    """
    if not user:
        return []
    try:
        return _probe(settings, user)
    except PETSc.Error:
        for k, v in user.items():   # which one: alone with the defaults
            try:
                _probe(settings, {k: v})
            except PETSc.Error as e:
                raise ValueError(f"{key}: -{k} = {v!r}: PETSc rejects it "
                                 f"({error_message(e.ierr)})") from None
        raise ValueError(f"{key}: PETSc rejects these options together") from None


def unread_message(names: Iterable[str], key: str = "petsc_options") -> str:
    names = list(names)
    return (f"{key}: -{names[0]}: not read by PETSc when the solver is set up (unknown, "
            "misspelt, not for this solver, or read too late to take effect)"
            + (f"; also {', '.join('-' + k for k in names[1:])}" if names[1:] else ""))


# ------------------------------------------------------------ why a linear solve failed


def solver_ksp(snes: PETSc.SNES) -> PETSc.KSP:
    """The KSP that solves the linear systems: the SNES's, or, on the condensed path
    (condensation/: the SNES's KSP is a Python one), the inner KSP on the condensed
    matrix."""
    ksp = snes.getKSP()
    if ksp.getType() == PETSc.KSP.Type.PYTHON:
        inner = getattr(ksp.getPythonContext(), "inner", None)
        if inner is not None:
            return inner
    return ksp


def linear_failure(snes: PETSc.SNES) -> str:
    """Why the linear solve of the last Newton iteration failed: the KSP's reason and, for
    a MUMPS factorization, INFOG(1) and INFOG(2); for an iterative method, the Newton
    iteration, its iterations, residual and tolerance."""
    ksp = solver_ksp(snes)
    reasons = {v: k for k, v in vars(PETSc.KSP.ConvergedReason).items() if isinstance(v, int)}
    what = reasons.get(ksp.getConvergedReason(), "unknown")
    if ksp.getType() != "preonly":
        what += f" in Newton iteration {snes.getIterationNumber()}: " \
                f"{ksp.getIterationNumber()} {ksp.getType()} iterations (at most " \
                f"{ksp.getTolerances()[3]}), residual {ksp.getResidualNorm():.3e}, " \
                f"relative tolerance {ksp.getTolerances()[0]:.1e}, preconditioner " \
                f"{ksp.getPC().getType()}"
    hint = "" if ksp.getType() == "preonly" else \
        "; a smaller load increment, or solver.linear_solver = 'condensed-mumps'"
    return f"the linear solve failed ({what}{_mumps_info(ksp.getPC())}){hint}"


def petsc_failure(snes: PETSc.SNES, error: PETSc.Error) -> str:
    """The step's failure message for a PETSc error raised inside SNESSolve (e.g. a failed
    factorization with -ksp_error_if_not_converged)."""
    return f"PETSc error in the Newton solve: {error_message(error.ierr)}" \
           f"{_mumps_info(solver_ksp(snes).getPC())}"


#: MUMPS INFOG(1) values that say a workspace (integer, real, or a buffer) was too small
_WORKSPACE = {-8, -9, -11, -12, -14, -15, -17, -20}


def out_of_workspace(snes: PETSc.SNES) -> bool:
    """The last factorization was MUMPS's and failed for lack of workspace."""
    return _mumps_infog(solver_ksp(snes).getPC())[0] in _WORKSPACE


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
