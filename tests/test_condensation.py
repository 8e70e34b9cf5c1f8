"""Condensed dual-mortar multipliers (fenicsx_mortar/condensation/, docs/condensation.md).

* the elimination's algebra: on a random system with every per-node structure (inactive,
  frictionless active, slip, stick, a Dirichlet dof on an active node, neighbours coupled
  through the multipliers' forces) the condensed solve and the recovery give the
  saddle-point solution;
* the condensed tangent is consistent: along a displacement direction lifted by the
  recovery, the condensed rows of R(x + h d) − R(x) − h Kc δu fall as h², and the rows the
  condensation eliminates as h² too;
* the condensed path takes the same Newton iterates as the saddle-point MUMPS solve (patch
  test, Hertz, B5 and B3 with μ = 0.3), and under mpirun the same answers as serially;
* the solver-choice rule: condensed solvers with the dual basis only, iterative methods
  never on the saddle point.
"""
import numpy as np
import pytest
import scipy.sparse as sp

from conftest import ROOT
from fenicsx_mortar import SolverSettings, load_scene
from fenicsx_mortar import petsc_options as po
from fenicsx_mortar.condensation import Elimination


# ------------------------------------------------------------------------ the algebra


def random_contact_system(rng, fix: str | None):
    """A saddle-point system [[K, B], [Cu, Cl]] with the structure of the contact
    Jacobian: 6 slave nodes (dofs 0..11) in a chain, inactive / frictionless active /
    slip / stick, 8 master and bulk nodes; each active multiplier's force dominant on its
    own node, small on the neighbours, spread over the master dofs."""
    n_u, n_s = 40, 6
    K = rng.standard_normal((n_u, n_u)) * 0.3 + np.diag(rng.uniform(8.0, 12.0, n_u))
    n_lam = 2 * n_s
    B = np.zeros((n_u, n_lam))
    Cu = np.zeros((n_lam, n_u))
    Cl = np.zeros((n_lam, n_lam))
    status = ["inactive", "active", "slip", "stick", "active", "inactive"]
    master = np.arange(24, 40)
    s = rng.uniform(0.5, 1.5, n_s)
    for j, st in enumerate(status):
        n, t = 2 * j, 2 * j + 1
        normal = np.array([0.1 * rng.standard_normal(), 1.0])
        tangent = np.array([1.0, 0.1 * rng.standard_normal()])
        if st == "inactive":
            Cl[n, n] = Cl[t, t] = s[j]
            continue
        B[2 * j: 2 * j + 2, n] = -2.0 * normal
        for k in (j - 1, j + 1):
            if 0 <= k < n_s:
                B[2 * k: 2 * k + 2, n] = 1e-3 * rng.standard_normal(2)
        B[master, n] = 0.3 * rng.standard_normal(len(master))
        Cu[n, 2 * j: 2 * j + 2] = 5.0 * normal
        Cu[n, master] = rng.standard_normal(len(master))
        if st == "active":
            Cl[t, t] = s[j]
        elif st == "slip":
            Cl[t, n], Cl[t, t] = -0.3 * s[j], s[j]
            Cu[t, :12] = rng.standard_normal(12)
            B[master, n] += 0.1 * rng.standard_normal(len(master))
        else:   # stick: the tangential multiplier acts too, and its row is kinematic
            B[2 * j: 2 * j + 2, t] = 1.5 * tangent
            B[master, t] = 0.2 * rng.standard_normal(len(master))
            Cu[t, 2 * j: 2 * j + 2] = 4.0 * tangent
            Cu[t, master] = rng.standard_normal(len(master))
    free = np.ones((n_lam, 2), dtype=bool)
    if fix is not None:   # u_x of the frictionless active node 1 or the sticking node 3
        j = 1 if fix == "active" else 3
        d = 2 * j
        K[d, :], K[:, d], K[d, d] = 0.0, 0.0, 1.0
        B[d, :], Cu[:, d] = 0.0, 0.0
        free[2 * j: 2 * j + 2, 0] = False
    node_dofs = np.repeat(np.arange(2 * n_s).reshape(n_s, 2), 2, axis=0)
    return K, B, Cu, Cl, node_dofs, free


@pytest.mark.parametrize("fix", [None, "active", "stick"])
def test_elimination_solves_the_saddle_point_system(fix):
    """Also with a Dirichlet dof on an active node (its free row serves) and on a
    sticking one (one of its multipliers is eliminated through a master row)."""
    rng = np.random.default_rng(4)
    K, B, Cu, Cl, node_dofs, free = random_contact_system(rng, fix)
    n_u, n_lam = K.shape[0], Cl.shape[0]
    J = np.block([[K, B], [Cu, Cl]])
    b = rng.standard_normal(n_u + n_lam)
    exact = np.linalg.solve(J, b)
    elim = Elimination(n_u, sp.coo_matrix(B), sp.coo_matrix(Cu), sp.coo_matrix(Cl),
                       node_dofs, free)
    # the normal multipliers of the four active nodes and the stick node's tangential
    # one; the stick node's two take both its rows
    assert len(elim.H) == 5
    assert {6, 7} <= set(elim.p_rows.tolist()) or fix == "stick"
    PK = sp.csr_matrix(K[elim.p_rows])
    coupled = elim.coupled_rows(PK)
    rows, D = elim.delta(PK, coupled, sp.csr_matrix(K[coupled][:, elim.p_rows]),
                         (0, n_u))
    Kc = K.copy()
    Kc[rows] += D.toarray()
    # the columns P are gone from the other rows, the rows P are the identity
    R = np.setdiff1d(np.arange(n_u), elim.p_rows)
    assert np.abs(Kc[np.ix_(R, elim.p_rows)]).max() <= 1e-13 * np.abs(K).max()
    assert np.array_equal(Kc[elim.p_rows], np.eye(n_u)[elim.p_rows])
    b_u, b_lam = b[:n_u], b[n_u:]
    b_P = b_u[elim.p_rows]
    f = b_u.copy()
    add_rows, add, set_rows, values = elim.rhs_update(b_P, b_lam[elim.H], (0, n_u))
    f[add_rows] += add
    f[set_rows] = values
    du = np.linalg.solve(Kc, f)
    du[elim.p_rows] = elim.displacements_P(b_lam[elim.H], elim.YG @ du)
    dlam = elim.recover(b_lam, b_P, K[elim.p_rows] @ du, elim.Cu_E @ du)
    assert np.abs(du - exact[:n_u]).max() <= 1e-12 * np.abs(exact).max()
    assert np.abs(dlam - exact[n_u:]).max() <= 1e-12 * np.abs(exact).max()
    if fix == "active":   # the multiplier of node 1 is eliminated through its row u_y
        assert 3 in elim.p_rows and 2 not in elim.p_rows
    if fix == "stick":    # node 3's: through u_y and a master row
        assert 7 in elim.p_rows and 6 not in elim.p_rows
        assert np.any(elim.p_rows >= 24)


def test_truncated_inverse_is_the_inverse_to_round_off():
    """W, the Neumann series of the block-tridiagonal M truncated below round-off, times
    M is the identity to round-off; the couplings it keeps reach a few nodes only."""
    rng = np.random.default_rng(1)
    n = 200
    d = rng.uniform(1.0, 2.0, n)
    off = 1e-3 * rng.standard_normal((2, n - 1))
    M = sp.diags([off[0], d, off[1]], [-1, 0, 1], format="csr")
    from fenicsx_mortar.condensation.inverses import inverse
    first, size = np.arange(n), np.ones(n, dtype=int)
    W = inverse(M, first, size)
    assert np.abs((W @ M).toarray() - np.eye(n)).max() <= 1e-15
    rows, cols = W.nonzero()
    assert np.abs(rows - cols).max() <= 6


# --------------------------------------------------------- the scenes, serial and MPI


def scene_variant(name: str, solver: str):
    """The demo scene ``name`` made small, solved with ``solver``."""
    scene = load_scene(ROOT / f"demos/scenes/{SCENES[name][0]}.toml")
    SCENES[name][1](scene)
    scene.solver.linear_solver = solver
    scene.output.xdmf = scene.output.plots = False
    return scene


def _hertz(scene):
    scene.mesh.params["h_contact"] = 0.012          # a/4


def _block_on_slab(scene):   # B5, μ = 0.3: pressed, then pushed (stick, then slip)
    scene.steps.times = [1.0, 1.1, 1.2]


def _half_rings(scene):      # B3 with μ = 0.3: pressed, then turned (sliding)
    scene.contacts[0].friction.law, scene.contacts[0].friction.mu = "coulomb", 0.3
    scene.steps.times = [0.5, 1.0, 1.05, 1.1]


SCENES = {"patch_test": ("patch_test", lambda s: None), "hertz": ("hertz", _hertz),
          "block_on_slab": ("block_on_slab", _block_on_slab),
          "half_rings": ("half_rings", _half_rings)}


def solve_with(scene, hook):
    """Solve ``scene`` (serial), calling ``hook(problem)`` on every ContactProblem it makes."""
    from fenicsx_mortar import problem as fm_problem
    from fenicsx_mortar import solve
    original = fm_problem.ContactProblem.__init__

    def init(self, *args, **kwargs):
        original(self, *args, **kwargs)
        hook(self)

    fm_problem.ContactProblem.__init__ = init
    try:
        res = solve(scene, log=lambda s: None)
    finally:
        fm_problem.ContactProblem.__init__ = original
    assert res.converged, res.message
    return res


def iterates(scene) -> tuple[list[np.ndarray], list]:
    """Solve ``scene`` recording every Newton iterate [u, λ] (serial) and the steps."""
    seen: list[np.ndarray] = []
    # array_r: newer PETSc (0.9's) locks the solution for reading inside a monitor; a
    # write access raised there and left the lock on for the step's restore
    res = solve_with(scene, lambda p: p.newton.snes.setMonitor(
        lambda snes, it, fnorm: seen.append(snes.getSolution().array_r.copy())))
    return seen, res


@pytest.mark.parametrize("name", list(SCENES))
def test_condensed_takes_the_saddle_point_iterates(name):
    """Every Newton iterate [u, λ] of condensed MUMPS equals the saddle-point MUMPS one
    (relative to the iterate's scale) and the steps' records agree; the patch test's
    pressures to 1e-10."""
    xs_a, res_a = iterates(scene_variant(name, "mumps"))
    xs_b, res_b = iterates(scene_variant(name, "condensed-mumps"))
    assert len(xs_a) == len(xs_b)
    worst = max(np.abs(a - b).max() / max(np.abs(a).max(), 1e-300)
                for a, b in zip(xs_a, xs_b))
    assert worst <= 1e-9, worst
    for sa, sb in zip(res_a.steps, res_b.steps):
        assert sa["newton_iterations"] == sb["newton_iterations"]
        assert sa["cuts"] == sb["cuts"]
    pa, pb = (r.pairs[0].interface()["pressure"] for r in (res_a, res_b))
    assert np.abs(pa - pb).max() <= 1e-10 * pa.max()


# ------------------------------------------------------------------ solver choice


def test_check_solver_choice():
    """Iterative and condensed solvers pass with dual multipliers, are refused on the
    saddle point (standard basis) with the reason named."""
    for name in ("condensed-mumps", "gmres-gamg", "gmres-hypre"):
        s = SolverSettings(linear_solver=name)
        po.check_solver_choice(s, {}, multipliers=True, condensable=True)
        with pytest.raises(ValueError, match="dual basis"):
            po.check_solver_choice(s, {}, multipliers=True, condensable=False)
        po.check_solver_choice(s, {}, multipliers=False)
    s = SolverSettings(linear_solver="mumps")
    with pytest.raises(ValueError, match="saddle-point"):
        po.check_solver_choice(s, {"ksp_type": "gmres", "pc_type": "gamg"},
                               multipliers=True, condensable=True)
    with pytest.raises(ValueError, match="saddle-point"):
        po.check_solver_choice(SolverSettings(linear_solver="superlu_dist"), {},
                               multipliers=True, condensable=True)
    # on the condensed path the user's KSP options reach a displacement-only system
    po.check_solver_choice(SolverSettings(linear_solver="condensed-mumps"),
                           {"pc_factor_mat_solver_type": "superlu_dist"},
                           multipliers=True, condensable=True)


def solved(scene):
    """Solve ``scene``; the result and its last problem's (Newton system, linear solver)."""
    kinds: list = []
    res = solve_with(scene, lambda p: kinds.append(
        (type(p.newton.system).__name__, p.newton.settings.linear_solver)))
    return res, kinds[-1]


def test_auto_condenses_from_its_size_and_with_the_dual_basis(monkeypatch):
    """linear_solver = "auto": MUMPS on the saddle point below AUTO_AMG_DOFS, GMRES + GAMG
    on the condensed system from there (the same pressures), MUMPS again with the standard
    basis whatever the size."""
    from fenicsx_mortar import system
    ref, kind = solved(scene_variant("hertz", "auto"))
    assert kind == ("MultiplierSystem", "mumps")
    monkeypatch.setattr(system, "AUTO_AMG_DOFS", 0)
    amg, kind = solved(scene_variant("hertz", "auto"))
    assert kind == ("CondensedSystem", "gmres-gamg")
    pa, pb = (r.pairs[0].interface()["pressure"] for r in (ref, amg))
    assert np.abs(pa - pb).max() <= 1e-8 * pa.max()
    standard = scene_variant("hertz", "auto")
    standard.contacts[0].basis = "standard"
    _, kind = solved(standard)
    assert kind == ("MultiplierSystem", "mumps")


def test_a_weak_amg_hands_over_to_a_factorization(monkeypatch):
    """B3 pressed and turned with μ = 0.3 on GMRES + GAMG, every AMG counted weak (Lag.slow
    above any rate it reaches): the first solve hands over to a kept MUMPS factorization,
    with a warning, and the run reaches the saddle-point MUMPS run's pressures."""
    from fenicsx_mortar.condensation import ksp
    ref, _ = solved(scene_variant("half_rings", "mumps"))
    original = ksp.Lag.__init__
    monkeypatch.setattr(ksp.Lag, "__init__",
                        lambda self, keep=0.5, slow=1e3, moved=None:
                        original(self, keep, slow, moved))
    with pytest.warns(UserWarning, match="kept MUMPS factorization"):
        weak, kind = solved(scene_variant("half_rings", "gmres-gamg"))
    assert kind == ("CondensedSystem", "gmres-gamg")
    pa, pb = (r.pairs[0].interface()["pressure"] for r in (ref, weak))
    assert np.abs(pa - pb).max() <= 1e-8 * pa.max()


def test_multigrid_level_options_reach_the_levels(monkeypatch):
    """A scene's -mg_levels_* option (GAMG's level smoothers) passes the checks and is
    what the levels of the condensed solve use; with MUMPS it is refused as unread."""
    from fenicsx_mortar.condensation import system as csys
    from fenicsx_mortar.scene import SceneError
    scene = scene_variant("hertz", "gmres-gamg")
    scene.solver.petsc = {"-mg_levels_ksp_max_it": 1}
    seen = []
    original = csys.solve_lagged

    def record(ksp, lag, f, y):
        out = original(ksp, lag, f, y)
        pc = ksp.getPC()
        seen.append([pc.getMGSmoother(k).getTolerances()[3]
                     for k in range(1, pc.getMGLevels())])
        return out

    monkeypatch.setattr(csys, "solve_lagged", record)
    solved(scene)
    assert seen and all(its == [1] * len(its) and its for its in seen)
    scene = scene_variant("hertz", "mumps")
    scene.solver.petsc = {"-mg_levels_ksp_max_it": 1}
    with pytest.raises(SceneError, match="mg_levels_ksp_max_it: not read by PETSc"):
        solved(scene)


# ------------------------------------------------------------------------------ MPI

MPI_SCENES = ("hertz", "block_on_slab", "half_rings")


@pytest.fixture(scope="module")
def mpi_runs(tmp_path_factory):
    """The scenes of test_mpi.py (coarse Hertz, B5 pressed and pushed, frictional B3
    pressed and turned): the saddle-point MUMPS solve serially; condensed MUMPS and
    condensed GMRES + AMG under mpirun -n 2."""
    import sys

    import test_mpi
    from conftest import run_python
    base = tmp_path_factory.mktemp("condensed_mpi")
    out = {}
    for solver, ranks in (("mumps", 1), ("condensed-mumps", 2), ("gmres-gamg", 2)):
        files = []
        for name in MPI_SCENES:
            stem, edits = test_mpi.SCENES[name]
            text = test_mpi._edit((ROOT / f"demos/scenes/{stem}.toml").read_text(), *edits)
            path = base / solver / f"{name}.toml"
            path.parent.mkdir(exist_ok=True)
            path.write_text(text + f'\n[solver]\nlinear_solver = "{solver}"\n')
            files.append(str(path))
        folder = base / f"{solver}_n{ranks}"
        folder.mkdir()
        proc = run_python([sys.executable, str(ROOT / "tests/dump_solution.py"), str(folder),
                           *files], ranks=ranks)
        assert proc.returncode == 0, proc.stdout[-1000:] + proc.stderr[-3000:]
        out[solver] = folder
    return out


@pytest.mark.mpi
@pytest.mark.parametrize("name", MPI_SCENES)
def test_condensed_under_mpi_equals_serial_saddle_point(name, mpi_runs):
    """Condensed MUMPS on 2 ranks: the serial saddle-point answers to 1e-8 with the same
    Newton iterations, cuts and stick/slip states; condensed GMRES + GAMG on 2 ranks: the
    same answers to 1e-8 (its Newton iterations may differ: inexact steps)."""
    import test_mpi
    serial = test_mpi._load(mpi_runs["mumps"], name)
    for solver in ("condensed-mumps", "gmres-gamg"):
        parallel = test_mpi._load(mpi_runs[solver], name)
        assert parallel[1]["ranks"] == 2
        diff = test_mpi.Diff()
        test_mpi.compare(serial, parallel, diff)
        if solver == "gmres-gamg":
            diff.mismatch = [m for m in diff.mismatch if "newton_iterations" not in m]
        assert not diff.mismatch, f"{solver}: " + "; ".join(diff.mismatch[:8])
        assert max(diff.worst.values()) <= 1e-8, (solver, diff.worst)


#: B3 with friction on 2 ranks, saddle-point MUMPS and GMRES + GAMG with every AMG counted
#: weak: the hand-over is collective (global norms) and reaches MUMPS's pressures
HAND_OVER = """
import sys, warnings
import numpy as np
from mpi4py import MPI
sys.path.insert(0, "tests")
from test_condensation import scene_variant
from fenicsx_mortar import solve
from fenicsx_mortar.condensation import ksp
p = {}
for solver in ("mumps", "gmres-gamg"):
    if solver == "gmres-gamg":
        init = ksp.Lag.__init__
        ksp.Lag.__init__ = (lambda self, keep=0.5, slow=1e3, moved=None:
                            init(self, keep, slow, moved))
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        res = solve(scene_variant("half_rings", solver), log=lambda s: None)
    handed = any("kept MUMPS factorization" in str(w.message) for w in seen)
    p[solver] = res.pairs[0].interface()["pressure"]
    # one line from rank 0: the ranks' own prints interleave
    every = MPI.COMM_WORLD.gather((solver, bool(res.converged), handed))
    if MPI.COMM_WORLD.rank == 0:
        print(*(f"{r} {s} {c} {h}" for r, (s, c, h) in enumerate(every)), sep="\\n")
if MPI.COMM_WORLD.rank == 0:
    d = np.abs(p["mumps"] - p["gmres-gamg"]).max() / p["mumps"].max()
    print("difference", d)
"""


@pytest.mark.mpi
def test_the_hand_over_on_two_ranks():
    import sys

    from conftest import run_python
    proc = run_python([sys.executable, "-c", HAND_OVER], ranks=2)
    out = proc.stdout
    assert proc.returncode == 0, out[-2000:] + proc.stderr[-2000:]
    # the warning on rank 0 only; both ranks converge
    assert "0 mumps True False" in out and "1 mumps True False" in out
    assert "0 gmres-gamg True True" in out and "1 gmres-gamg True False" in out
    import re
    assert float(re.search(r"difference ([-+.\deE]+)", out).group(1)) <= 1e-8
