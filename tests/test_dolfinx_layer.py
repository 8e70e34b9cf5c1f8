"""The DOLFINx version layer: fenicsx_mortar/_dolfinx.py over one module per API generation
(fenicsx_mortar/_dolfinx_versions/). The suite as a whole runs on each version (.ci/run:
0.5.2 on Debian 12, 0.9 in a Debian 13 root); these tests check the layer's own promises."""
import ast
import inspect
import re
import sys
import textwrap

import pytest

from conftest import ROOT, run_python
from fenicsx_mortar import _dolfinx as dx
from fenicsx_mortar._dolfinx_versions import GENERATIONS, select, v0_5, v0_9, v0_10, v0_11

LAYER = {ROOT / "fenicsx_mortar" / "_dolfinx.py", ROOT / "fenicsx_mortar" / "_dolfinx_versions"}


@pytest.mark.parametrize("gen", [v0_5, v0_10, v0_11], ids=lambda m: m.__name__[-4:])
def test_generations_offer_the_same_functions(gen):
    # _dolfinx.py calls whatever the running version's module offers: every generation
    # must offer the reference's (0.9's) functions with the same parameters
    assert gen.__all__ == v0_9.__all__
    for name in v0_9.__all__:
        ref = inspect.signature(getattr(v0_9, name))
        assert inspect.signature(getattr(gen, name)) == ref, name


def test_every_generation_is_selectable():
    assert sorted(GENERATIONS) == [(0, 5), (0, 9), (0, 10), (0, 11)]
    for (major, minor), name in GENERATIONS.items():
        assert select(f"{major}.{minor}.3.post1").__name__.endswith(name)


def test_the_running_version_is_selected():
    major, minor = (int(p) for p in dx.VERSION.split(".")[:2])
    assert dx.api.__name__.endswith(GENERATIONS[(major, minor)])


@pytest.mark.parametrize("version", ["0.12.0", "0.8.0", "1.0", "main"])
def test_untested_versions_are_refused_by_name(version):
    with pytest.raises(ImportError, match=rf"DOLFINx 0\.5, 0\.9, 0\.10 or 0\.11, not "
                                          rf"{re.escape(version)}: install .*python3-dolfinx-"
                                          r"real, or DOLFINx 0\.11 from PyPI"):
        select(version)


def _dolfinx_uses(path) -> list[str]:
    """The DOLFINx imports of one file other than ``import dolfinx`` read only for
    ``dolfinx.__version__``, and module names ``"dolfinx.…"`` given as strings (importlib,
    pytest.importorskip)."""
    tree = ast.parse(path.read_text(), str(path))
    found, plain = [], []
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and (node.module or "").split(".")[0] == "dolfinx":
            found.append(f"line {node.lineno}: from {node.module} import ...")
        elif isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name.split(".")[0] == "dolfinx":
                    (plain if alias.name == "dolfinx" and not alias.asname else found).append(
                        f"line {node.lineno}: import {alias.name}")
        elif isinstance(node, ast.Constant) and isinstance(node.value, str) \
                and re.fullmatch(r"dolfinx(\.\w+)+", node.value):
            found.append(f"line {node.lineno}: {node.value!r}")
    if plain:
        attrs = {n.attr for n in ast.walk(tree) if isinstance(n, ast.Attribute)
                 and isinstance(n.value, ast.Name) and n.value.id == "dolfinx"}
        if attrs - {"__version__"}:
            found += plain
    return found


def test_only_the_layer_uses_dolfinx():
    # demos/ are user scripts (they may branch on the DOLFINx API themselves)
    offenders = {}
    for folder in ("fenicsx_mortar", "meshes", "tests", "benchmarks"):
        for path in sorted((ROOT / folder).rglob("*.py")):
            if path in LAYER or path.parent in LAYER:
                continue
            uses = _dolfinx_uses(path)
            if uses:
                offenders[str(path.relative_to(ROOT))] = uses
    assert not offenders, f"DOLFINx used outside fenicsx_mortar/_dolfinx*: {offenders}"


def test_the_scan_sees_what_it_must(tmp_path):
    # the scan above finds nothing in the tree: make sure it would
    f = tmp_path / "x.py"
    f.write_text("import dolfinx\nfrom dolfinx.io import gmshio\nimport dolfinx.fem as fem\n"
                 "pytest.importorskip('dolfinx.io.gmshio')\nV = dolfinx.fem.functionspace\n")
    lines = sorted(int(u.split(":")[0].split()[1]) for u in _dolfinx_uses(f))
    assert lines == [1, 2, 3, 4]          # line 1 for dolfinx.fem on line 5
    f.write_text("import dolfinx\nprint(dolfinx.__version__)\n")
    assert _dolfinx_uses(f) == []


EMPTY_RANK = textwrap.dedent("""
    import numpy as np, ufl
    from mpi4py import MPI
    from petsc4py import PETSc
    from fenicsx_mortar import _dolfinx as dx
    comm = MPI.COMM_WORLD
    msh = dx.unit_square(comm, 1, 1)                 # two triangles: some rank gets none
    V = dx.vector_space(msh)
    n = dx.num_cells(msh)
    assert comm.allreduce(int(n == 0)) >= 1, "no rank without cells: nothing tested"
    assert dx.cell_nodes(msh).shape == (n, 3) and dx.cell_dofs(V).shape == (n, 3)
    assert dx.input_node_numbers(msh).dtype == np.int64
    u, v = ufl.TrialFunction(V), ufl.TestFunction(V)
    a = dx.form(ufl.inner(ufl.grad(u), ufl.grad(v)) * ufl.dx)
    A = dx.matrix_with_couplings(a, V, [np.arange(4)])   # every node with every node
    nz = A.getInfo(PETSc.Mat.InfoType.GLOBAL_SUM)["nz_used"]
    if comm.rank == 0:
        print("OK", int(nz))
""")


@pytest.mark.mpi
def test_a_rank_without_cells_builds_its_part(tmp_path):
    # more ranks than cells: the ranks without cells or dofs take part in every collective
    # call (before: the reshape of an empty dofmap and the search in an empty
    # local-to-global map raised there, and the other ranks waited for ever)
    script = tmp_path / "empty_rank.py"
    script.write_text(EMPTY_RANK)
    proc = run_python([sys.executable, str(script)], ranks=3, timeout=300)
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-3000:]
    # 4 nodes x 2 components, all coupled: 64 entries (the bulk alone: 56)
    assert proc.stdout.split() == ["OK", "64"]


def test_a_mesh_without_facet_groups_has_empty_facet_tags():
    # DOLFINx 0.10's io.gmsh gives None for a dimension without physical groups, 0.5-0.9
    # empty tags; callers index the tags without a check
    import gmsh
    from mpi4py import MPI
    gmsh.initialize(readConfigFiles=False)
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        if MPI.COMM_WORLD.rank == 0:
            geo = gmsh.model.geo
            pts = [geo.addPoint(x, y, 0.0, 0.5) for x, y in ((0, 0), (1, 0), (1, 1), (0, 1))]
            lines = [geo.addLine(pts[i], pts[(i + 1) % 4]) for i in range(4)]
            geo.addPlaneSurface([geo.addCurveLoop(lines)])
            geo.synchronize()
            gmsh.model.addPhysicalGroup(2, [1], 7)
            gmsh.model.mesh.generate(2)
        msh, cell_tags, facet_tags = dx.model_to_mesh(gmsh.model, MPI.COMM_WORLD, 0)
    finally:
        gmsh.finalize()
    assert dx.num_cells_global(msh) > 0
    assert set(cell_tags.values.tolist()) <= {7} and len(cell_tags.indices) == dx.num_cells(msh)
    assert len(facet_tags.indices) == 0 and len(facet_tags.find(1)) == 0


def test_vtx_output_where_the_version_has_it(tmp_path):
    from mpi4py import MPI
    msh = dx.unit_square(MPI.COMM_WORLD, 2, 2)
    u = dx.Function(dx.vector_space(msh))
    u.x.array[:] = 1.0
    path = tmp_path / "u.bp"
    if not dx.has_vtx():
        with pytest.raises(RuntimeError, match=rf"VTX output needs DOLFINx built with ADIOS2; "
                                               rf"DOLFINx {re.escape(dx.VERSION)}"):
            dx.VTXWriter(msh.comm, path, [u])
        return
    with dx.VTXWriter(msh.comm, path, [u]) as w:
        w.write(0.0)
        w.write(1.0)
    assert path.is_dir() and (path / "md.idx").is_file() and (path / "data.0").is_file()


def test_mpi4py_is_imported_before_petsc4py_and_dolfinx():
    # PyPI's DOLFINx wheel: petsc4py and DOLFINx find MPICH's libmpi.so.12 only after
    # mpi4py.MPI loaded it ("libmpi.so.12: cannot open shared object file" otherwise)
    # (the generation modules are imported by _dolfinx.py's select(), after mpi4py)
    late = {}
    for path in sorted((ROOT / "fenicsx_mortar").rglob("*.py")):
        if path.parent.name == "_dolfinx_versions":
            continue
        first = {}
        for node in ast.parse(path.read_text()).body:       # module level only
            names = [a.name for a in node.names] if isinstance(node, ast.Import) else \
                [node.module or ""] if isinstance(node, ast.ImportFrom) else []
            for name in names:
                first.setdefault(name.split(".")[0], node.lineno)
        mpi = first.get("mpi4py", float("inf"))
        if any(first.get(m, mpi) < mpi for m in ("petsc4py", "dolfinx")):
            late[str(path.relative_to(ROOT))] = first
    assert not late, late
