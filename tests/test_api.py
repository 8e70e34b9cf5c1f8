"""The library API as a DOLFINx user meets it (issue 27): every argument checked by name,
the acceptance of a converged state in every solve, PETSc options by DOLFINx's
convention, fields and reactions, load stepping, and deterministic release of the
PETSc objects."""
from __future__ import annotations

import gc
import math
import weakref

import numpy as np
import pytest
import ufl
from mpi4py import MPI
from petsc4py import PETSc

import fenicsx_mortar as fm
from conftest import ROOT
from fenicsx_mortar import _dolfinx as dx
from fenicsx_mortar import load_scene
from fenicsx_mortar.scene.bulk import build_bulk
from fenicsx_mortar.scene.meshing import build_domain
from fenicsx_mortar.scene.runner import scene_pairs


@pytest.fixture(scope="module")
def slab():
    """The block on the slab of tests/bad_input/_base.toml: its mesh, forms, supports."""
    scene = load_scene(ROOT / "tests/bad_input/_base.toml")
    dom = build_domain(scene)
    return scene, dom


def new_problem(slab, **kw):
    """(problem, bulk, pairs) of the block on the slab, built afresh."""
    scene, dom = slab
    bulk = build_bulk(scene, dom)
    pairs = scene_pairs(scene, dom, bulk.V)
    problem = fm.ContactProblem(bulk.residual, bulk.u, bulk.bcs, pairs, bulk.jacobian,
                                **kw)
    return problem, bulk, pairs


def pair(slab, **kw):
    scene, dom = slab
    V = dx.vector_space(dom.mesh)
    tags = (dom.facet_groups["block_bottom"], dom.facet_groups["slab_top"])
    return fm.ContactPair(V, dom.facet_tags, *tags, **({"E": 1000.0} | kw))


# ------------------------------------------------------------------ inputs, by name


@pytest.mark.parametrize("kw, match", [
    ({"mu": 0.2}, "pass friction='coulomb'"),
    ({"friction": "coulomb"}, "needs mu"),
    ({"method": "mortr"}, "method = 'mortr': must be one of 'mortar'"),
    ({"enforcement": "lagrangian"}, "enforcement = 'lagrangian': must be one of"),
    ({"friction": "tresca", "mu": 0.1}, "friction = 'tresca': must be one of"),
    ({"smoothing": "spline"}, "smoothing = 'spline': must be one of"),
    ({"basis": "dual", "method": "nts"}, "basis = 'dual'"),
    ({"epsilon": [1e4, 1e5]}, "epsilon"),
    ({"enforcement": "alm", "tolerance": 1e6}, r"tolerance = 1000000.0: must be .*1e-14, 0.01"),
    ({"n_gauss": 2.5}, "n_gauss"),
])
def test_pair_arguments_are_refused_by_name(slab, kw, match):
    with pytest.raises(ValueError, match=match):
        pair(slab, **kw)


def test_slave_and_master_must_be_distinct_boundaries(slab):
    scene, dom = slab
    V = dx.vector_space(dom.mesh)
    top = dom.facet_groups["slab_top"]
    with pytest.raises(ValueError, match="share the tag"):
        fm.ContactPair(V, dom.facet_tags, top, [top, dom.facet_groups["block_bottom"]],
                       E=1000.0)
    # two boundaries of one body that meet at a corner share a node
    with pytest.raises(ValueError, match="share 1 node"):
        fm.ContactPair(V, dom.facet_tags, dom.facet_groups["block_bottom"],
                       dom.facet_groups["block_left"], E=1000.0)


def test_two_pairs_with_one_name_are_refused(slab):
    scene, dom = slab
    bulk = build_bulk(scene, dom)
    a, b = pair(slab, name="c"), pair(slab, name="c")
    with pytest.raises(ValueError, match="same name"):
        fm.ContactProblem(bulk.residual, bulk.u, bulk.bcs, [a, b], bulk.jacobian)


def test_a_pair_serves_one_problem_at_a_time(slab):
    problem, bulk, pairs = new_problem(slab)
    with pytest.raises(ValueError, match="belongs to another ContactProblem"):
        fm.ContactProblem(bulk.residual, bulk.u, bulk.bcs, pairs, bulk.jacobian)
    problem.close()
    fm.ContactProblem(bulk.residual, bulk.u, bulk.bcs, pairs, bulk.jacobian).close()


def test_the_residual_must_be_a_form_of_u(slab):
    scene, dom = slab
    bulk = build_bulk(scene, dom)
    other = dx.Function(bulk.V)
    v = ufl.TestFunction(bulk.V)
    F_other = ufl.inner(ufl.grad(other), ufl.grad(v)) * ufl.dx(domain=dom.mesh)
    with pytest.raises(ValueError, match="F does not depend on u"):
        fm.ContactProblem(F_other, bulk.u, bulk.bcs)
    with pytest.raises(ValueError, match="pass its compiled Jacobian"):
        fm.ContactProblem(bulk.residual, bulk.u, bulk.bcs)


@pytest.mark.parametrize("options, match", [
    ({"snes_type": "ksponly"}, "ksponly"),
    ({"-snes_convergence_test": "skip"}, "convergence rule"),
    ({"pc_factor_mat_solver_type": "superlu_dist"}, "superlu_dist cannot solve the saddle"),
    ({"ksp_type": "gmres", "pc_type": "gamg"}, "gmres -pc_type gamg cannot solve"),
])
def test_solver_options_that_cannot_work_are_refused(slab, options, match):
    with pytest.raises(ValueError, match=match):
        new_problem(slab, petsc_options=options)


def test_a_linear_solver_this_petsc_lacks_is_refused_by_name(slab):
    """gmres-hypre needs hypre: PyPI's DOLFINx wheel has none (PETSc failed inside
    SNESSetFromOptions); where it exists the problem is built."""
    import copy

    from petsc4py import PETSc
    scene, dom = slab
    scene = copy.deepcopy(scene)
    scene.contacts[0].enforcement.type = "penalty"
    settings = fm.SolverSettings(linear_solver="gmres-hypre")
    if PETSc.Sys.hasExternalPackage("hypre"):
        new_problem((scene, dom), settings=settings)[0].close()
    else:
        with pytest.raises(ValueError, match="settings.linear_solver = 'gmres-hypre': this "
                           "PETSc is built without hypre"):
            new_problem((scene, dom), settings=settings)


@pytest.mark.parametrize("field, value", [("atol", math.inf), ("rtol", 0.0),
                                          ("max_iterations", 0), ("line_search", "l3"),
                                          ("linear_solver", "umfpack")])
def test_solver_settings_are_checked_by_name(slab, field, value):
    settings = fm.SolverSettings(**{field: value})
    with pytest.raises(ValueError, match=f"settings.{field}"):
        new_problem(slab, settings=settings)


def _unread_warnings(slab, options):
    """The 'not read by PETSc' warnings of building a problem with ``options``, and the
    problem's SNES max_it."""
    import warnings
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        problem, _, _ = new_problem(slab, petsc_options=options)
    max_it = problem.solver.getTolerances()[3]
    problem.close()
    return [str(w.message) for w in seen if "not read by PETSc" in str(w.message)], max_it


def test_an_option_petsc_never_reads_is_reported(slab):
    """A misspelt option is named in one warning; spelt right, it is read, silently."""
    unread, _ = _unread_warnings(slab, {"snes_monitr": None})
    assert len(unread) == 1 and "-snes_monitr: not read by PETSc" in unread[0]
    unread, max_it = _unread_warnings(slab, {"snes_max_it": 7})
    assert unread == [] and max_it == 7


@pytest.mark.parametrize("kw, match", [({"times": [0.5, 0.25]}, "strictly increasing"),
                                       ({"times": [1.0], "max_cuts": -1}, "max_cuts"),
                                       ({"times": [math.nan]}, "positive pseudo-times")])
def test_stepper_arguments_are_refused_by_name(slab, kw, match):
    problem, bulk, _ = new_problem(slab)
    with pytest.raises(ValueError, match=match):
        fm.LoadStepper(problem, bulk.set_time, **kw)
    problem.close()


# ------------------------------------------------------ the acceptance of every solve


def svk_square(n: int = 2):
    """A unit square of St Venant–Kirchhoff material (E = 1, ν = 0) pressed by a dead
    load on its top, the bottom on rollers and the left side held in x."""
    msh = dx.unit_square(MPI.COMM_WORLD, n, n)
    V = dx.vector_space(msh)
    u, v = dx.Function(V), ufl.TestFunction(V)
    F = ufl.Identity(2) + ufl.grad(u)
    E_gl = 0.5 * (F.T * F - ufl.Identity(2))
    S = 0.5 * E_gl                      # μ = 1/2, λ = 0
    load = dx.constant(msh, 0.0)
    x = ufl.SpatialCoordinate(msh)
    top = ufl.conditional(ufl.gt(x[1], 1.0 - 1e-9), 1.0, 0.0)
    md = {"quadrature_degree": 2}
    R = ufl.inner(F * S, ufl.grad(v)) * ufl.dx(domain=msh, metadata=md) \
        + load * top * v[1] * ufl.ds(domain=msh, metadata=md)
    bottom = dx.locate_vertices(msh, lambda X: np.isclose(X[1], 0.0))
    left = dx.locate_vertices(msh, lambda X: np.isclose(X[0], 0.0))
    bcs = [dx.dirichletbc(dx.constant(msh, 0.0), dx.vertex_dofs(V, 1, bottom), V, 1),
           dx.dirichletbc(dx.constant(msh, 0.0), dx.vertex_dofs(V, 0, left), V, 0)]
    return R, u, bcs, load


def test_an_inverted_solution_is_not_converged_unless_acceptance_is_off():
    """SVK past its limit load: Newton finds the inverted branch (J < 0 in every cell), a
    root of the residual but no deformation. The solve says so, and puts u back; with
    acceptance=False the same root is returned as converged."""
    R, u, bcs, load = svk_square()
    load.value = 0.6                    # beyond the limit load of SVK in compression
    with fm.ContactProblem(R, u, bcs, petsc_options_prefix="svk_") as problem:
        res = problem.solve()
        assert not res.converged and "inverts" in res.reason, res.reason
        assert np.all(u.x.array == 0.0)
    R, u, bcs, load = svk_square()
    load.value = 0.6
    with fm.ContactProblem(R, u, bcs, acceptance=False, petsc_options_prefix="svk_") as p:
        res = p.solve()
        assert res.converged, res.reason
        J = np.linalg.det(np.eye(2) + _grad_at_a_cell(u))
        assert J < 0


def _grad_at_a_cell(u) -> np.ndarray:
    """∇u of the (uniformly deformed) square from two of its dofs' displacements."""
    X = dx.dof_coordinates(u.function_space)
    d = u.x.array.reshape(-1, 2)
    i = np.argmax(X[:, 0] + X[:, 1])     # the corner (1, 1): u = (∇u) (1, 1) for u(0) = 0
    j = np.argmax(X[:, 0] - X[:, 1])     # the corner (1, 0)
    gx = d[j]                            # (∂u/∂x)
    gy = d[i] - d[j]                     # (∂u/∂y)
    return np.column_stack([gx, gy])


def test_the_options_database_reaches_the_solver_under_its_prefix(slab):
    """DOLFINx's convention: ``-<prefix>snes_max_it 1`` in PETSc's database (the command
    line) reaches the SNES — and the solve that stopped there is not converged."""
    opts = PETSc.Options()
    opts["dbtest_snes_max_it"] = 1
    try:
        problem, bulk, _ = new_problem(slab, petsc_options_prefix="dbtest_")
        assert problem.solver.getOptionsPrefix() == "dbtest_"
        bulk.set_time(0.5)
        res = problem.solve()
        assert not res.converged and "DIVERGED_MAX_IT after 1 iterations" in res.reason
        problem.close()
    finally:
        opts.delValue("dbtest_snes_max_it")
    problem, bulk, _ = new_problem(slab, petsc_options_prefix="")
    assert problem.solver.getOptionsPrefix() in ("", None)
    bulk.set_time(0.5)
    assert problem.solve().converged
    problem.close()


# ------------------------------------------------------------ fields, forces, steps


def test_fields_reactions_and_steps_agree_with_the_scene_runner(slab, tmp_path):
    """The block pressed on the slab through the API (LoadStepper): the reaction of the
    slab's support equals the scene runner's, the pressure field holds the interface's
    pressures at the slave nodes and zero elsewhere, and the contact force balances the
    load."""
    scene, dom = slab
    ref = fm.solve(load_scene(ROOT / "tests/bad_input/_base.toml"), log=lambda s: None)
    problem, bulk, pairs = new_problem(slab, petsc_options_prefix="steps_")
    done = []
    stepper = fm.LoadStepper(problem, bulk.set_time, scene.steps.targets(),
                             on_step=done.append, on_event=None)
    assert stepper.run().completed
    assert [d.step for d in done] == [s["step"] for s in ref.steps]
    R = problem.reaction(dom.facet_tags, dom.facet_groups["slab_bottom"])
    expect = ref.steps[-1]["reactions"]
    support = next(k for k in expect if "slab_bottom" in k)
    assert R[1] == pytest.approx(expect[support]["y"], rel=1e-12)
    p = pairs[0]
    rows = p.interface()
    f = p.fields()["contact_pressure"]
    # by reference position: the block's bottom nodes sit on slab nodes (the trap of
    # matching by coordinates), so each point holds the slave's value and the slab's zero
    X = np.round(dx.dof_coordinates(f.function_space), 12)
    at: dict[tuple, list] = {}
    for xy, value in zip(map(tuple, X), f.x.array):
        at.setdefault(xy, []).append(value)
    slave = {tuple(xy): pr for xy, pr in zip(np.round(p.slave.X, 12), rows["pressure"])}
    for xy, values in at.items():
        expect = sorted([slave[xy]] + [0.0] * (len(values) - 1)) if xy in slave \
            else [0.0] * len(values)
        assert sorted(values) == expect, xy
    assert np.max(rows["pressure"]) > 0
    assert sorted(rows["vertex"]) == sorted(set(rows["vertex"]))
    problem.close()


def test_problems_are_released_without_the_garbage_collector(slab):
    """No reference cycle through the SNES callbacks: the solver goes when the problem
    goes (MPICH allows 2048 communicators per process)."""
    gc.collect()
    gc.disable()
    try:
        problem, bulk, _ = new_problem(slab)
        bulk.set_time(0.5)
        assert problem.solve().converged
        ref = weakref.ref(problem.newton)
        del problem
        assert ref() is None
    finally:
        gc.enable()


def test_the_library_api_is_listed():
    names = set(dir(fm))
    assert {"ContactPair", "ContactProblem", "LoadStepper", "SolverSettings"} <= names
    assert set(fm.__all__) <= names


def test_the_command_line_reaches_the_solver_under_its_prefix(tmp_path):
    """A script that hands PETSc its command line (``petsc4py.init(sys.argv)``, PETSc's
    way) steers the solver with ``-<prefix>...`` options."""
    import subprocess
    import sys
    script = tmp_path / "script.py"
    script.write_text(
        "import sys\nfrom mpi4py import MPI  # noqa: F401 (first: the pip wheel's MPICH)\n"
        "import petsc4py\npetsc4py.init(sys.argv)\n"
        "from conftest import ROOT\n"
        "import fenicsx_mortar as fm\nfrom fenicsx_mortar import load_scene\n"
        "from fenicsx_mortar.scene.bulk import build_bulk\n"
        "from fenicsx_mortar.scene.meshing import build_domain\n"
        "from fenicsx_mortar.scene.runner import scene_pairs\n"
        "scene = load_scene(ROOT / 'tests/bad_input/_base.toml')\n"
        "dom = build_domain(scene)\nbulk = build_bulk(scene, dom)\n"
        "pairs = scene_pairs(scene, dom, bulk.V)\n"
        "p = fm.ContactProblem(bulk.residual, bulk.u, bulk.bcs, pairs, bulk.jacobian,\n"
        "                      petsc_options_prefix='cl_')\n"
        "bulk.set_time(0.5)\nprint('REASON', p.solve().reason)\n")
    env = {"PYTHONPATH": f"{ROOT / 'tests'}:{ROOT}"}
    import os
    proc = subprocess.run([sys.executable, str(script), "-cl_snes_max_it", "1"],
                          capture_output=True, text=True, env={**os.environ, **env},
                          timeout=300)
    assert "REASON Newton failed: DIVERGED_MAX_IT after 1 iterations" in proc.stdout, \
        proc.stdout[-2000:] + proc.stderr[-2000:]


def test_two_supports_with_two_values_for_one_dof_are_refused():
    """Two conditions sharing the corner (0, 0): y = 0 on the bottom and y = 0.1 on the
    left side. DOLFINx would apply one silently; the solve refuses, naming both."""
    msh = dx.unit_square(MPI.COMM_WORLD, 2, 2)
    V = dx.vector_space(msh)
    u, v = dx.Function(V), ufl.TestFunction(V)
    F = ufl.inner(ufl.grad(u), ufl.grad(v)) * ufl.dx(domain=msh)
    bottom = dx.locate_vertices(msh, lambda X: np.isclose(X[1], 0.0))
    left = dx.locate_vertices(msh, lambda X: np.isclose(X[0], 0.0))
    zero, lift = dx.constant(msh, 0.0), dx.constant(msh, 0.1)
    bcs = [dx.dirichletbc(zero, dx.vertex_dofs(V, 1, bottom), V, 1),
           dx.dirichletbc(zero, dx.vertex_dofs(V, 0, left), V, 0),
           dx.dirichletbc(lift, dx.vertex_dofs(V, 1, left), V, 1)]
    with fm.ContactProblem(F, u, bcs, petsc_options_prefix="bc_") as problem:
        with pytest.raises(ValueError, match=r"bcs\[0\] and bcs\[2\] prescribe different "
                                             r"values, 0 and 0.1, to the y component at \(0, 0\)"):
            problem.solve()
        lift.value = 0.0                 # one value again: solves
        assert problem.solve().converged
