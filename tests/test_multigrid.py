"""The geometric multigrid of ``linear_solver = "gmres-gmg"`` (condensation/multigrid.py):
its prolongation interpolates linearly from the coarse mesh (constants everywhere, affine
fields off the curved boundary, whose new nodes are moved onto the arc), a mesh that is not
a refinement of the coarse one is refused, and the solve reaches condensed MUMPS's
pressures, serially and on 2 ranks."""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest
from mpi4py import MPI

from fenicsx_mortar import _dolfinx as dx
from fenicsx_mortar import load_scene
from fenicsx_mortar.condensation.multigrid import CoarseMesh, prolongations
from fenicsx_mortar.scene.meshing import build_domain
from fenicsx_mortar.scene.model import SceneError

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))


def hertz(refine: int, solver: str = "gmres-gmg", cell: str = "quadrilateral"):
    """Coarse Hertz (B2) refined ``refine`` times, solved with ``solver``."""
    scene = load_scene(ROOT / "demos/scenes/hertz.toml")
    scene.mesh.cell = cell
    scene.mesh.params.update({"h_contact": 0.024, "h_far": 0.1, "refine": refine})
    scene.solver.linear_solver = solver
    scene.output.xdmf = scene.output.plots = False
    return scene


@pytest.fixture(scope="module")
def refined_twice():
    dom = build_domain(hertz(2), MPI.COMM_WORLD)
    V = dx.vector_space(dom.mesh)
    return dom, V


def test_prolongation_interpolates_linearly(refined_twice):
    """P_l u_c: constants exactly at every node; an affine field exactly at every node
    farther than a coarse cell (h_far = 0.1) from the disk's arc. Nearer, gmsh moved the
    new nodes onto the arc (and the centres of the cells along it by half that): P gives
    the value at the chord's midpoint, off by |A| h²/(8R) at most."""
    dom, V = refined_twice
    assert len(dom.coarse_meshes) == 2
    Ps = prolongations(V, dom.cell_tags, dom.coarse_meshes, np.zeros(0, dtype=np.int32))
    grids = [dx.dof_coordinates(V)[: dx.owned_dof_count(V) // 2]] + \
        [c.points for c in dom.coarse_meshes[::-1]]
    A, b = np.array([[0.3, -1.2], [0.7, 0.4]]), np.array([0.5, -0.25])
    for P, fine, coarse in zip(Ps, grids[:-1], grids[1:]):
        uc = P.createVecRight()
        assert uc.getSize() == 2 * len(coarse)
        for field, exact_off_arc in ((lambda x: np.ones_like(x), False),
                                     (lambda x: x @ A.T + b, True)):
            uc.array[:] = field(coarse[slice(*np.array(uc.getOwnershipRange()) // 2)]).ravel()
            uf = P.createVecLeft()
            P.mult(uc, uf)
            err = np.abs(uf.array.reshape(-1, 2) - field(fine)).max(axis=1)
            on_arc = np.abs(np.hypot(fine[:, 0], fine[:, 1] - 1.0) - 1.0) < 0.1
            keep = ~on_arc if exact_off_arc else np.ones(len(fine), dtype=bool)
            assert err[keep].max() <= 1e-12
            if exact_off_arc:
                assert err[on_arc].max() <= np.abs(A).sum(axis=1).max() * 0.1 ** 2 / 8


def test_the_finest_prolongation_leaves_dirichlet_dofs_alone(refined_twice):
    """The rows of the Dirichlet dofs in the finest prolongation are zero (the coarse
    correction must not move a held dof); every other row still interpolates a constant
    exactly, and the coarser prolongation keeps all its rows."""
    dom, V = refined_twice
    n_own = dx.owned_dof_count(V)
    fine = dx.dof_coordinates(V)[: n_own // 2]
    # the x component of the nodes in the lowest tenth of the block, the y of the rest
    low = np.flatnonzero(fine[:, 1] < fine[:, 1].min() + 0.1 * np.ptp(fine[:, 1]))
    fixed = np.concatenate([2 * low, 2 * np.setdiff1d(np.arange(len(fine)), low)[::7] + 1])
    Ps = prolongations(V, dom.cell_tags, dom.coarse_meshes, fixed.astype(np.int32))
    for P, held in zip(Ps, (fixed, np.zeros(0, dtype=np.int64))):
        ones = P.createVecRight()
        ones.set(1.0)
        uf = P.createVecLeft()
        P.mult(ones, uf)
        free = np.setdiff1d(np.arange(len(uf.array)), held)
        assert np.all(uf.array[held] == 0.0)
        assert np.abs(uf.array[free] - 1.0).max() <= 1e-12
        indptr = P.getValuesCSR()[0]
        assert np.all(np.diff(indptr)[held] == 0)
    for P in Ps:
        P.destroy()


def test_a_mesh_not_refined_from_the_coarse_one_is_refused(refined_twice):
    """Coarse meshes that the mesh was not refined from: one node per refinement point is
    checked, so a shifted mesh or a missing body is named."""
    dom, V = refined_twice
    c = dom.coarse_meshes[-1]
    shifted = CoarseMesh(c.points + [0.003, 0.0], c.cells, c.cell_body)
    with pytest.raises(ValueError, match="not a uniform refinement"):
        prolongations(V, dom.cell_tags, [shifted], np.zeros(0, dtype=np.int32))
    one_body = CoarseMesh(c.points, c.cells[c.cell_body == c.cell_body[0]],
                          c.cell_body[c.cell_body == c.cell_body[0]])
    with pytest.raises(ValueError, match="bodies"):
        prolongations(V, dom.cell_tags, [one_body], np.zeros(0, dtype=np.int32))
    with pytest.raises(ValueError, match="not a uniform refinement"):
        prolongations(V, dom.cell_tags, dom.coarse_meshes[:1], np.zeros(0, dtype=np.int32))


def test_scene_without_a_hierarchy_is_refused():
    from fenicsx_mortar.scene.validation import validate
    with pytest.raises(SceneError, match="refine >= 1"):
        validate(hertz(0))
    scene = hertz(1)
    scene.contacts[0].enforcement.type = "penalty"
    with pytest.raises(SceneError, match="no contact has them"):
        validate(scene)


def pressures(scene):
    from test_condensation import solved
    res, kind = solved(scene)
    assert kind == ("CondensedSystem", scene.solver.linear_solver)
    return res.pairs[0].interface()["pressure"]


@pytest.mark.parametrize("cell", ["quadrilateral", "triangle"])
def test_gmg_reaches_condensed_mumps_pressures(cell):
    """Hertz refined twice: GMRES + the geometric multigrid gives condensed MUMPS's nodal
    pressures to 1e-8 of the peak (triangles: refined without a centre node)."""
    p_lu, p_mg = (pressures(hertz(2, s, cell)) for s in ("condensed-mumps", "gmres-gmg"))
    assert np.abs(p_lu - p_mg).max() <= 1e-8 * p_lu.max()


MPI_SCRIPT = """
import sys
import numpy as np
from mpi4py import MPI
sys.path.insert(0, "tests")
from test_multigrid import hertz, pressures
p = pressures(hertz(2))
if MPI.COMM_WORLD.rank == 0:
    np.save(sys.argv[1], p)
"""


@pytest.mark.mpi
def test_gmg_on_two_ranks_equals_serial(tmp_path):
    """The hierarchy split among 2 ranks: the serial condensed MUMPS pressures to 1e-8."""
    from conftest import run_python
    out = tmp_path / "p.npy"
    proc = run_python([sys.executable, "-c", MPI_SCRIPT, str(out)], ranks=2)
    assert proc.returncode == 0, proc.stdout[-1000:] + proc.stderr[-3000:]
    p_lu = pressures(hertz(2, "condensed-mumps"))
    p_mg = np.load(out)
    assert np.abs(p_lu - p_mg).max() <= 1e-8 * p_lu.max()


def test_api_needs_the_hierarchy():
    """ContactProblem's check of ``gmres-gmg``'s input: coarse meshes and cell tags, each
    mesh well formed, multipliers to condense."""
    from fenicsx_mortar.problem import _check_multigrid
    from fenicsx_mortar.settings import SolverSettings
    s = SolverSettings(linear_solver="gmres-gmg")
    good = CoarseMesh(np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]), np.array([[0, 1, 2]]),
                      np.array([1]))
    with pytest.raises(ValueError, match="coarse_meshes"):
        _check_multigrid(s, True, (), None)
    with pytest.raises(ValueError, match="coarse_meshes"):
        _check_multigrid(s, True, [good], None)
    with pytest.raises(ValueError, match="without multipliers"):
        _check_multigrid(s, False, [good], object())
    bad = CoarseMesh(good.points, np.array([[0, 1, 3]]), good.cell_body)
    with pytest.raises(ValueError, match=r"coarse_meshes\[0\]"):
        _check_multigrid(s, True, [bad], object())
    _check_multigrid(s, True, [good], object())
    stray = CoarseMesh(np.vstack([good.points, [[5.0, 5.0]]]), good.cells, good.cell_body)
    with pytest.raises(ValueError, match=r"coarse_meshes\[0\]: 1 of its points are in no cell"):
        _check_multigrid(s, True, [stray], object())
    _check_multigrid(SolverSettings(linear_solver="gmres-gamg"), True, (), None)


def test_a_hierarchy_that_does_not_fit_leaves_the_pairs_free():
    """Coarse meshes given finest first: ContactProblem names coarse_meshes and says what
    they must be, before it claims the pairs: the same pairs then serve a problem with
    the hierarchy in order, whose multigrid has a level per mesh."""
    import fenicsx_mortar as fm
    from fenicsx_mortar.scene.bulk import build_bulk
    from fenicsx_mortar.scene.runner import scene_pairs
    scene = hertz(2)
    dom = build_domain(scene, MPI.COMM_WORLD)
    bulk = build_bulk(scene, dom)
    pairs = scene_pairs(scene, dom, bulk.V)
    args = (bulk.residual, bulk.u, bulk.bcs, pairs, bulk.jacobian)
    kw = {"settings": scene.solver, "cell_tags": dom.cell_tags}
    # (the traceback kept: it holds the failed problem, as a notebook's would)
    with pytest.raises(ValueError, match=r"coarse_meshes\[\d\].*coarsest first") as failed:
        fm.ContactProblem(*args, coarse_meshes=dom.coarse_meshes[::-1], **kw)
    with fm.ContactProblem(*args, coarse_meshes=dom.coarse_meshes, **kw) as problem:
        assert problem.newton.system.inner.getPC().getMGLevels() == 3
    assert failed.traceback


def test_the_multigrid_reads_its_level_options():
    """``gmres-gmg``'s level, coarse and Krylov options are read (a scene's solver.petsc
    takes them), a misspelt one is reported."""
    from fenicsx_mortar import petsc_options as po
    from fenicsx_mortar.settings import SolverSettings
    s = SolverSettings(linear_solver="gmres-gmg")
    read = {"mg_levels_ksp_max_it": "2", "mg_coarse_mat_mumps_icntl_14": "50",
            "ksp_rtol": "1e-6", "ksp_gmres_restart": "30"}
    assert po.unread(s, read) == []
    assert po.unread(s, {"mg_levels_ksp_maxit": "2"}) == ["mg_levels_ksp_maxit"]


def test_a_pattern_growth_after_set_up_keeps_the_multigrid_working(monkeypatch):
    """Kc rebuilt with a larger pattern (large sliding) after the multigrid was set up: the
    next set-up takes the new pattern and the pressures stay condensed MUMPS's. (The slot
    added is zero: what is checked is that the solve goes on, not the coarse operators'
    values.)"""
    from fenicsx_mortar.condensation.system import CondensedSystem
    original = CondensedSystem.assemble_jacobian
    grown = []

    def assemble(self, A, add_contact):
        pc = self.inner.getPC()
        if not grown and pc.getType() == "mg" and self.inner.getIterationNumber() > 0:
            # one slot the pattern lacks: the first owned row's coupling to the last dof
            r0 = self.Kc.getOwnershipRange()[0]
            free = np.setdiff1d(np.arange(r0, r0 + 8), self.skip_u)[:1]
            far = np.setdiff1d(np.arange(self.n_global_u - 8, self.n_global_u),
                               self.skip_u)[-1:]
            missing = self._missing(free, far)
            assert missing.all()
            self._grow(free, far)
            grown.append(pc.getMGLevels())
        original(self, A, add_contact)

    monkeypatch.setattr(CondensedSystem, "assemble_jacobian", assemble)
    p_mg = pressures(hertz(2))
    assert grown == [3]
    monkeypatch.setattr(CondensedSystem, "assemble_jacobian", original)
    p_lu = pressures(hertz(2, "condensed-mumps"))
    assert np.abs(p_lu - p_mg).max() <= 1e-8 * p_lu.max()


def test_auto_takes_the_geometric_multigrid_on_a_twice_refined_mesh(monkeypatch):
    """``"auto"`` above AUTO_AMG_DOFS: the geometric multigrid with two coarse meshes (and
    condensed MUMPS's pressures), GAMG with one."""
    from fenicsx_mortar import system
    from test_condensation import solved
    monkeypatch.setattr(system, "AUTO_AMG_DOFS", 0)
    (res, kind), (_, kind1) = (solved(hertz(k, "auto")) for k in (2, 1))
    assert kind == ("CondensedSystem", "gmres-gmg")
    assert kind1 == ("CondensedSystem", "gmres-gamg")
    p_lu = pressures(hertz(2, "condensed-mumps"))
    p = res.pairs[0].interface()["pressure"]
    assert np.abs(p_lu - p).max() <= 1e-8 * p_lu.max()


def test_refine_gmsh_refuses_what_it_cannot_describe():
    """A negative count, and a mesh without physical surface groups (no bodies), are
    refused by name; a square of 2 x 2 quadrilaterals refined once keeps the 9 nodes and
    4 cells before the refinement."""
    import gmsh

    import fenicsx_mortar as fm
    from fenicsx_mortar.scene.meshing import _gmsh_initialize
    _gmsh_initialize(gmsh)  # (our signal handlers kept)
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.model.add("square")
        s = gmsh.model.occ.addRectangle(0, 0, 0, 1, 1)
        gmsh.model.occ.synchronize()
        for c in gmsh.model.getEntities(1):
            gmsh.model.mesh.setTransfiniteCurve(c[1], 3)
        gmsh.model.mesh.setTransfiniteSurface(s)
        gmsh.model.mesh.setRecombine(2, s)
        gmsh.model.mesh.generate(2)
        with pytest.raises(ValueError, match="times = -1"):
            fm.refine_gmsh(gmsh.model, -1)
        with pytest.raises(ValueError, match="physical surface groups"):
            fm.refine_gmsh(gmsh.model, 1)
        gmsh.model.addPhysicalGroup(2, [s], 7)
        (coarse,) = fm.refine_gmsh(gmsh.model, 1)
        assert (len(coarse.points), coarse.cells.shape) == (9, (4, 4))
        assert set(coarse.cell_body) == {7}
        assert len(gmsh.model.mesh.getNodes()[0]) == 25
    finally:
        gmsh.finalize()
