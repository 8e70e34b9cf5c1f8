"""Every DOLFINx call of the package, on DOLFINx 0.5 (Debian 12), 0.9 (Debian 13), 0.10 and
0.11 (PyPI's ``dolfinx-solver-real``).

The rest of the package (and the tests and benchmarks) calls DOLFINx only through this
module. Written against the DOLFINx 0.9 API: what is spelled differently in another
version is one function of ``_dolfinx_versions`` (``api`` below: ``v0_5``, ``v0_9``,
``v0_10`` or ``v0_11``, picked by ``dolfinx.__version__``); the calls made here directly are
the same in 0.5 to 0.11 (docs/dolfinx-versions.md), and petsc4py's renamings are feature
tests here (``SNES_DIVERGED_NAN``, ``LINE_SEARCH_SECANT``). Array shapes are 0.9's: the
geometry and dof maps are (num_cells, k) arrays.
"""
from __future__ import annotations

import atexit
import ctypes
import errno
import logging

# mpi4py.MPI first: the PyPI wheel's petsc4py and DOLFINx find MPICH's libmpi.so.12 only
# once mpi4py has loaded it
from mpi4py import MPI  # isort: skip

import dolfinx
import numpy as np
import ufl
from dolfinx import fem, io, mesh as dmesh
from dolfinx.fem import petsc as fpetsc
from petsc4py import PETSc

from ._dolfinx_versions import select

# The JIT's C compilation (cffi through setuptools) lowers the root logger to INFO and
# prints every compiler command; keep warnings only.
logging.getLogger().addFilter(lambda r: r.name != "root" or r.levelno >= logging.WARNING)

VERSION = dolfinx.__version__
api = select(VERSION)

Mesh = dmesh.Mesh
Function = fem.Function
#: types for annotations (0.5 names some of them ...MetaClass)
FunctionSpace = fem.FunctionSpace
MeshTags = getattr(dmesh, "MeshTags", None) or getattr(dmesh, "MeshTagsMetaClass")
Form = getattr(fem, "Form", None) or getattr(fem.forms, "FormMetaClass")
ScalarType = PETSc.ScalarType

_REASON = PETSc.SNES.ConvergedReason
#: SNES's reason for a residual norm that is NaN or infinite (petsc4py 3.25 renamed
#: DIVERGED_FNORM_NAN)
SNES_DIVERGED_NAN = (_REASON.DIVERGED_FUNCTION_NANORINF
                     if hasattr(_REASON, "DIVERGED_FUNCTION_NANORINF")
                     else _REASON.DIVERGED_FNORM_NAN)
#: PETSc's name of the secant line search on ‖F‖² that 3.24 renamed from "l2" ("l2" now
#: names another algorithm)
LINE_SEARCH_SECANT = "secant" if PETSc.Sys.getVersion() >= (3, 24, 0) else "l2"
#: and what keeps it the same algorithm: 3.24 caps its step at maxlambda = 1 (l2 took steps
#: up to maxstep = 1e8)
LINE_SEARCH_SECANT_OPTIONS = ({"snes_linesearch_maxlambda": 1e8}
                              if PETSc.Sys.getVersion() >= (3, 24, 0) else {})


def model_to_mesh(model, comm: MPI.Comm, rank: int = 0):
    """gmsh model (on ``rank``) → (mesh, cell tags, facet tags), distributed over ``comm``."""
    return api.model_to_mesh(model, comm, rank, gdim=2)


def vector_space(msh: Mesh):
    """P1 displacements: the vector Lagrange space of degree 1."""
    return api.functionspace(msh, ("Lagrange", 1, (2,)))


def scalar_p1_space(V):
    """The P1 scalar space of V's mesh and, for each of its local dofs, V's local unrolled
    dof of the same node's x component (``V.sub(0).collapse()``)."""
    W, parent = V.sub(0).collapse()
    # 0.11 returns the map inside a one-element list
    return W, np.asarray(parent, dtype=np.int64).reshape(-1)


def tensor_dg0_space(msh: Mesh):
    """Cellwise constant 2×2 tensors (the Cauchy stress output)."""
    return api.functionspace(msh, ("DG", 0, (2, 2)))


def constant(msh: Mesh, value):
    return fem.Constant(msh, ScalarType(value) if np.isscalar(value)
                        else np.asarray(value, dtype=ScalarType))


def form(expr):
    return fem.form(expr)


def _locate_dofs(V, dim: int, entities: np.ndarray) -> np.ndarray:
    """``fem.locate_dofs_topological`` with the entity-cell connectivity it needs made
    first (0.5 made it itself; 0.9 raises "Entity-to-cell connectivity has not been
    computed")."""
    msh = V.mesh
    tdim = msh.topology.dim
    msh.topology.create_connectivity(dim, tdim)
    msh.topology.create_connectivity(tdim, dim)
    return fem.locate_dofs_topological(V, dim, np.asarray(entities, dtype=np.int32))


def facet_dofs(V, component: int, facets: np.ndarray) -> np.ndarray:
    """Unrolled dofs of component ``component`` on the given facets (owned and ghost)."""
    return _locate_dofs(V.sub(component), V.mesh.topology.dim - 1, facets)


def vertex_dofs(V, component: int, vertices: np.ndarray) -> np.ndarray:
    return _locate_dofs(V.sub(component), 0, vertices)


def dirichletbc(value: fem.Constant, dofs: np.ndarray, V, component: int):
    return fem.dirichletbc(value, dofs, V.sub(component))


def dirichletbc_function(g: fem.Function, V, facets: np.ndarray):
    """Both components on ``facets`` prescribed by the vector Function ``g`` in V."""
    return fem.dirichletbc(g, _locate_dofs(V, V.mesh.topology.dim - 1, facets))


def locate_vertices(msh: Mesh, marker) -> np.ndarray:
    return dmesh.locate_entities(msh, 0, marker)


def cells_of_vertices(msh: Mesh):
    """AdjacencyList vertex → its cells (``.links(v)``)."""
    msh.topology.create_connectivity(0, msh.topology.dim)
    return msh.topology.connectivity(0, msh.topology.dim)


def facet_cells(msh: Mesh):
    tdim = msh.topology.dim
    msh.topology.create_connectivity(tdim - 1, tdim)
    return msh.topology.connectivity(tdim - 1, tdim)


def topological_dimension(msh: Mesh) -> int:
    return msh.topology.dim


def num_vertices_global(msh: Mesh) -> int:
    return msh.topology.index_map(0).size_global


def is_p1_vector_space(V) -> bool:
    """Two dofs at every vertex and no others: the P1 vector space of its mesh."""
    return (V.dofmap.index_map_bs == 2
            and V.dofmap.index_map.size_global == num_vertices_global(V.mesh))


def same_mesh(a: Mesh, b: Mesh) -> bool:
    return a is b


def exterior_facets(msh: Mesh) -> np.ndarray:
    """The owned facets that bound one cell globally (collective)."""
    tdim = msh.topology.dim
    msh.topology.create_connectivity(tdim - 1, tdim)
    return dmesh.exterior_facet_indices(msh.topology)


def facet_vertices(msh: Mesh):
    tdim = msh.topology.dim
    msh.topology.create_connectivity(tdim - 1, 0)
    return msh.topology.connectivity(tdim - 1, 0)


def unit_square(comm: MPI.Comm, nx: int, ny: int) -> Mesh:
    """The unit square in 2·nx·ny triangles (tests)."""
    return dmesh.create_unit_square(comm, nx, ny)


def midpoints(msh: Mesh, dim: int, entities: np.ndarray) -> np.ndarray:
    """(n, 3) midpoints of the given local entities of dimension ``dim``."""
    msh.topology.create_connectivity(dim, msh.topology.dim)   # 0.9 needs it, 0.5 not
    return dmesh.compute_midpoints(msh, dim, np.asarray(entities, dtype=np.int32))


def num_owned_cells(msh: Mesh) -> int:
    return msh.topology.index_map(msh.topology.dim).size_local


def num_cells(msh: Mesh) -> int:
    """Owned and ghost cells on this rank."""
    im = msh.topology.index_map(msh.topology.dim)
    return im.size_local + im.num_ghosts


def num_owned_facets(msh: Mesh) -> int:
    """(The facets are made first: 0.9's ``index_map`` raises for entities not made yet.)"""
    msh.topology.create_entities(msh.topology.dim - 1)
    return msh.topology.index_map(msh.topology.dim - 1).size_local


def num_vertices(msh: Mesh, ghosts: bool = True) -> int:
    im = msh.topology.index_map(0)
    return im.size_local + (im.num_ghosts if ghosts else 0)


def num_cells_global(msh: Mesh) -> int:
    return msh.topology.index_map(msh.topology.dim).size_global


def node_coordinates(msh: Mesh) -> np.ndarray:
    """(n_nodes, 2) geometry node coordinates (a view)."""
    return msh.geometry.x[:, :2]


def cell_nodes(msh: Mesh) -> np.ndarray:
    """(n_cells, k) geometry nodes of each cell (linear cells of one type)."""
    return api.geometry_dofmap(msh)


def input_node_numbers(msh: Mesh) -> np.ndarray:
    """The mesh file's (gmsh's) number of every geometry node on this rank."""
    return api.input_global_indices(msh)


def cell_dofs(V) -> np.ndarray:
    """(n_cells, k) dof blocks (nodes) of each cell, in the cell's reference order."""
    return api.dofmap_list(V)


def dof_coordinates(V) -> np.ndarray:
    """(n_blocks, 2) coordinates of the dof blocks (owned, then ghosts)."""
    return V.tabulate_dof_coordinates()[:, :2]


def dof_count(V) -> int:
    """Global number of (unrolled) dofs."""
    return V.dofmap.index_map.size_global * V.dofmap.index_map_bs


def owned_dof_count(V) -> int:
    """Unrolled dofs this rank owns (they come first in the local numbering)."""
    return V.dofmap.index_map.size_local * V.dofmap.index_map_bs


def vertex_to_geometry_node(msh: Mesh) -> np.ndarray:
    """Map vertex index → geometry node index (they differ in DOLFINx; linear cells)."""
    tdim = msh.topology.dim
    msh.topology.create_connectivity(tdim, 0)
    c2v = msh.topology.connectivity(tdim, 0).array
    g = api.geometry_dofmap(msh).ravel()
    nv = msh.topology.index_map(0).size_local + msh.topology.index_map(0).num_ghosts
    out = np.full(nv, -1, dtype=np.int32)
    out[c2v] = g  # same local ordering within each linear cell
    return out


def global_vertices(msh: Mesh, vertices: np.ndarray) -> np.ndarray:
    """Global (topology) numbers of local vertices."""
    im = msh.topology.index_map(0)
    return np.asarray(im.local_to_global(np.asarray(vertices, dtype=np.int32)), dtype=np.int64)


def local_to_global_blocks(V) -> np.ndarray:
    """Global block (node) number of every local block, owned then ghosts."""
    im = V.dofmap.index_map
    return im.local_to_global(np.arange(im.size_local + im.num_ghosts, dtype=np.int32))


def local_to_global_dofs(V) -> np.ndarray:
    """Global (unrolled) dof number of every local dof, owned then ghosts."""
    im = V.dofmap.index_map
    bs = V.dofmap.index_map_bs
    n = im.size_local + im.num_ghosts
    blocks = im.local_to_global(np.arange(n, dtype=np.int32))
    return (blocks[:, None] * bs + np.arange(bs)[None, :]).ravel()


def vertex_dofs_all(V, vertices: np.ndarray) -> np.ndarray:
    """(n, 2) local unrolled dofs (x, y) of the P1 vector space at ``vertices``, in order.
    (P1 cell dofs follow the cell's vertex order.)"""
    msh = V.mesh
    tdim = msh.topology.dim
    msh.topology.create_connectivity(tdim, 0)
    c2v = msh.topology.connectivity(tdim, 0).array
    blocks = api.dofmap_list(V).ravel()
    nv = msh.topology.index_map(0).size_local + msh.topology.index_map(0).num_ghosts
    v2b = np.full(nv, -1, dtype=np.int64)
    v2b[c2v] = blocks
    bs = V.dofmap.index_map_bs
    b = v2b[np.asarray(vertices)]
    return np.stack([b * bs, b * bs + 1], axis=1)


# ----------------------------------------------------------------------------- PETSc


def create_matrix(a_form) -> PETSc.Mat:
    return api.create_matrix(a_form)


def create_vector(L_form) -> PETSc.Vec:
    return api.create_vector(L_form)


def function_vector(u: fem.Function) -> PETSc.Vec:
    """The ghosted PETSc Vec over ``u.x`` (writes to it are writes to u)."""
    return api.petsc_vec(u)


def assemble_residual(b: PETSc.Vec, L_form, a_form, bcs, x: PETSc.Vec, extra=None) -> None:
    """b = F(x) with Dirichlet rows set to x − g; ``extra(b)`` adds non-form terms first."""
    with b.localForm() as loc:
        loc.set(0.0)
    fpetsc.assemble_vector(b, L_form)
    api.apply_lifting(b, [a_form], bcs=[bcs], x0=[x], alpha=-1.0)
    b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
    if extra is not None:
        extra(b)
    api.set_bc(b, bcs, x, alpha=-1.0)


def assemble_unconstrained_residual(b: PETSc.Vec, L_form) -> None:
    with b.localForm() as loc:
        loc.set(0.0)
    fpetsc.assemble_vector(b, L_form)
    b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)


def assemble_jacobian(A: PETSc.Mat, a_form, bcs, extra=None) -> None:
    """A = dF/du with identity rows/columns on Dirichlet dofs; ``extra(A)`` adds entries
    (with ADD_VALUES, rows/columns of Dirichlet dofs must be skipped by the caller)."""
    A.zeroEntries()
    api.assemble_matrix(A, a_form, bcs)
    A.assemblyBegin(PETSc.Mat.AssemblyType.FLUSH)
    A.assemblyEnd(PETSc.Mat.AssemblyType.FLUSH)
    if extra is not None:
        extra(A)
    A.assemble()


def bc_dofs(bcs) -> np.ndarray:
    """Local unrolled dof indices constrained by the Dirichlet conditions."""
    out = [bc.dof_indices()[0] for bc in bcs]
    return np.unique(np.concatenate(out)) if out else np.zeros(0, dtype=np.int32)


def bc_values(bcs, V) -> list[tuple[np.ndarray, np.ndarray]]:
    """Per Dirichlet condition on V, its owned (unrolled) dofs and the values it prescribes
    there now."""
    f = fem.Function(V)
    vec = api.petsc_vec(f)
    n_owned = owned_dof_count(V)
    out = []
    for bc in bcs:
        with vec.localForm() as loc:
            loc.set(0.0)
        api.set_bc(vec, [bc], None, 1.0)
        dofs = bc.dof_indices()[0]
        dofs = dofs[dofs < n_owned]
        out.append((dofs, vec.array_r[dofs].copy()))
    return out


def expression(expr, V) -> fem.Expression:
    """Compile a UFL expression for interpolation into V."""
    return fem.Expression(expr, api.interpolation_points(V))


def interpolate(target: fem.Function, compiled: fem.Expression, cells: np.ndarray) -> None:
    target.interpolate(compiled, np.asarray(cells, dtype=np.int32))


# ----------------------------------------------------------------------------- output


class XDMFWriter:
    """Mesh once, then functions per pseudo-time. A failed write (HDF5: a full disk, say)
    is an OSError naming the .h5 file, not HDF5's RuntimeError and its error stack on
    stderr."""

    def __init__(self, comm: MPI.Comm, path: str, msh: Mesh):
        _quiet_hdf5()
        self._h5 = path[: -len(".xdmf")] + ".h5" if path.endswith(".xdmf") else path
        #: True once a write failed: the file must not be touched again (closing it would
        #: fail again, under MPI wait for ranks that left the collective call)
        self.broken = False
        self._f = None
        self._f = self._io(lambda: io.XDMFFile(comm, path, "w"))
        self._io(lambda: self._f.write_mesh(msh))

    def _io(self, call, file=None):
        try:
            return call()
        except RuntimeError as e:
            self.broken = True
            _abandon(file if file is not None else self._f)
            raise OSError(errno.EIO, f"the HDF5 library failed ({e})", self._h5) from None

    def write(self, functions, t: float) -> None:
        for f in functions:
            self._io(lambda: self._f.write_function(f, t))

    def close(self) -> None:
        if self._f is not None and not self.broken:
            f, self._f = self._f, None
            self._io(f.close, f)


def _abandon(xdmf_file) -> None:
    """Never close a file whose write failed: closing fails again (an operation that failed
    half-way leaves HDF5's cache entries protected), and PyPI's HDF5, built with
    assertions, then aborts the process (-6 instead of the run's exit 1). Neither DOLFINx's
    destructor (the object is kept for ever) nor HDF5's shutdown at exit or at
    MPI_Finalize (told the library is closed already) gets to it."""
    if xdmf_file is not None:      # (None: the open itself failed, inside DOLFINx)
        ctypes.pythonapi.Py_IncRef(ctypes.py_object(xdmf_file))
    global _hdf5_abandoned
    if not _hdf5_abandoned:
        _hdf5_abandoned = True
        atexit.register(_skip_hdf5_shutdown)   # runs before mpi4py's MPI_Finalize


def _skip_hdf5_shutdown() -> None:
    for lib in _hdf5_libs:
        try:
            # H5_term_library does nothing while H5_libinit_g is false (HDF5 1.8 to 1.14)
            ctypes.c_bool.in_dll(lib, "H5_libinit_g").value = False
        except (ValueError, AttributeError):
            pass                                     # another HDF5: as before


_hdf5_abandoned = False


def has_vtx() -> bool:
    """Whether this DOLFINx writes VTX files (built with ADIOS2: PyPI's 0.11 is, Debian's
    0.5.2 is not)."""
    return hasattr(io, "VTXWriter")


class VTXWriter:
    """ParaView's VTX output (an ADIOS2 ``.bp`` folder): functions of one element type on
    one mesh (a P1 vector and a DG0 tensor need a writer each), written per pseudo-time.

    Args:
        comm: the mesh's communicator (collective).
        path: the ``.bp`` folder to write.
        functions: the functions, all of the same space type.

    Raises:
        RuntimeError: this DOLFINx has no VTX output (built without ADIOS2).
    """

    def __init__(self, comm: MPI.Comm, path: str, functions) -> None:
        if not has_vtx():
            raise RuntimeError(f"VTX output needs DOLFINx built with ADIOS2; DOLFINx {VERSION} "
                               "here is not (write XDMF instead: XDMFWriter)")
        # (comm, filename, output): the same in 0.5 to 0.11
        self._w = io.VTXWriter(comm, str(path), list(functions))

    def write(self, t: float) -> None:
        self._w.write(float(t))

    def close(self) -> None:
        self._w.close()

    def __enter__(self) -> "VTXWriter":
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def _quiet_hdf5() -> None:
    """Switch off HDF5's automatic printing of its error stack (tens of lines on stderr for
    one failed write; the failure still reaches us as DOLFINx's RuntimeError). Process-wide
    and for the rest of the process, once the package writes an XDMF file."""
    global _hdf5_quiet
    if _hdf5_quiet:
        return
    _hdf5_quiet = True
    try:
        with open("/proc/self/maps") as maps:
            paths = {line.split()[-1] for line in maps if "/libhdf5" in line
                     and "libhdf5_hl" not in line and "_hl." not in line}
    except OSError:
        return                                       # not Linux: noisy only
    for path in paths:
        try:
            lib = ctypes.CDLL(path)
            _hdf5_libs.append(lib)
            # herr_t H5Eset_auto2(hid_t estack, H5E_auto2_t func, void *data); hid_t is
            # int64_t since HDF5 1.10, H5E_DEFAULT = 0 (the default error stack)
            lib.H5Eset_auto2.argtypes = [ctypes.c_int64, ctypes.c_void_p, ctypes.c_void_p]
            lib.H5Eset_auto2(0, None, None)
        except (OSError, AttributeError):
            pass                                     # another HDF5: noisy only


_hdf5_quiet = False
_hdf5_libs: list[ctypes.CDLL] = []


def measures(msh: Mesh, cell_tags, facet_tags, degree: int):
    """Cell and facet measures with a fixed quadrature degree (UFL's estimate for the
    Neo-Hooke forms is 10–14, i.e. 36–64 points per quadrilateral)."""
    md = {"quadrature_degree": degree}
    dx = ufl.Measure("dx", domain=msh, subdomain_data=cell_tags, metadata=md)
    ds = ufl.Measure("ds", domain=msh, subdomain_data=facet_tags, metadata=md)
    return dx, ds


def matrix_with_couplings(a_form, V, blocks: list[np.ndarray]) -> PETSc.Mat:
    """The Jacobian matrix: the form's sparsity plus the extra couplings ``blocks`` (each:
    global node-block numbers of V that couple all-to-all), written once with zeros so
    PETSc keeps the slots. Under MPI only couplings among the nodes a rank holds (owned or
    ghost) enter DOLFINx's pattern; the others are the caller's to reserve
    (ContactProblem: contact.assembly.reserve). Couplings beyond the prediction (large
    sliding) still go in, by dynamic allocation.

    The bulk form is assembled once (flush only) so that its slots are written too: a final
    assembly squeezes every preallocated slot not written yet, and the first Jacobian would
    then reallocate the whole bulk pattern entry by entry (Hertz, 23k dofs: 23 s instead
    of 0.9 s)."""
    l2g = local_to_global_blocks(V)
    order = np.argsort(l2g)
    pattern = fem.create_sparsity_pattern(a_form)
    known = []
    for blk in blocks:
        local = _held_blocks(l2g, order, np.asarray(blk))
        if len(local):
            pattern.insert(local, local)
            known.append(local)
    A = api.matrix_from_pattern(a_form.mesh.comm, pattern)
    api.assemble_matrix(A, a_form, [])
    bs = V.dofmap.index_map_bs
    for local in known:
        g = (l2g[local][:, None] * bs + np.arange(bs)).ravel().astype(PETSc.IntType)
        A.setValues(g, g, np.zeros((len(g), len(g))), addv=PETSc.InsertMode.ADD)
    A.assemble()
    A.setOption(PETSc.Mat.Option.NEW_NONZERO_ALLOCATION_ERR, False)
    return A


def _held_blocks(l2g: np.ndarray, order: np.ndarray, blk: np.ndarray) -> np.ndarray:
    """Local numbers (int32) of the global blocks ``blk`` this rank holds (owned or ghost),
    given its local-to-global map and that map's argsort. Only these can enter the local
    sparsity pattern; a rank that holds no dofs at all gets none (the search below would
    index an empty array)."""
    if len(l2g) == 0 or len(blk) == 0:
        return np.zeros(0, dtype=np.int32)
    pos = np.minimum(np.searchsorted(l2g, blk, sorter=order), len(order) - 1)
    return order[pos][l2g[order[pos]] == blk].astype(np.int32)


def quadrature_expression(expr, msh: Mesh, degree: int, vertices: bool = False
                          ) -> fem.Expression:
    """Compile a scalar UFL expression for evaluation at the Gauss points of ``degree`` on
    the mesh's cell type, with ``vertices`` also at the reference cell's corners
    (``.eval(cells)`` → (n_cells, n_points))."""
    import basix
    cell = getattr(basix.CellType, msh.topology.cell_type.name)
    points, _ = basix.make_quadrature(cell, degree)
    if vertices:
        points = np.vstack([points, basix.geometry(cell)])
    return fem.Expression(expr, points)


def cell_midpoints(msh: Mesh, cells: np.ndarray) -> np.ndarray:
    """(n, 2) mean of the geometry nodes of the given local cells."""
    return node_coordinates(msh)[cell_nodes(msh)[cells]].mean(axis=1)


def expression_eval(expr: fem.Expression, msh: Mesh, cells: np.ndarray) -> np.ndarray:
    """Values of a compiled expression on the given local cells."""
    return api.expression_eval(expr, msh, cells)


def jit_cache_dir():
    """The directory of DOLFINx's JIT cache (FFCx modules)."""
    return api.jit_cache_dir()
