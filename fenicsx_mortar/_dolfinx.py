"""Every DOLFINx-version-specific call (written against Debian's DOLFINx 0.5.2).

Porting to DOLFINx 0.9/0.10 should touch this file alone: e.g. ``fem.VectorFunctionSpace``
→ ``fem.functionspace(mesh, ("Lagrange", 1, (2,)))``, ``u.vector`` → ``u.x.petsc_vec``,
``mesh.geometry.dofmap`` layout, ``gmshio.model_to_mesh`` return type, ``XDMFFile`` API.
"""
from __future__ import annotations

import logging

import numpy as np
import ufl
from dolfinx import cpp, fem, io, mesh as dmesh
from dolfinx.fem import petsc as fpetsc
from dolfinx.io import gmshio
from mpi4py import MPI
from petsc4py import PETSc

# The JIT's C compilation (cffi through setuptools) lowers the root logger to INFO and
# prints every compiler command; keep warnings only.
logging.getLogger().addFilter(lambda r: r.name != "root" or r.levelno >= logging.WARNING)

Mesh = dmesh.Mesh
Function = fem.Function
ScalarType = PETSc.ScalarType


def model_to_mesh(model, comm: MPI.Comm, rank: int = 0):
    """gmsh model (on ``rank``) → (mesh, cell tags, facet tags), distributed over ``comm``."""
    return gmshio.model_to_mesh(model, comm, rank, gdim=2)


def cpp_mesh(msh: Mesh):
    # Debian's patched Mesh wraps the C++ object instead of subclassing it.
    return getattr(msh, "_mesh", msh)


def vector_space(msh: Mesh):
    return fem.VectorFunctionSpace(msh, ("Lagrange", 1))


def tensor_dg0_space(msh: Mesh):
    return fem.TensorFunctionSpace(msh, ("DG", 0))


def scalar_dg0_space(msh: Mesh):
    return fem.FunctionSpace(msh, ("DG", 0))


def constant(msh: Mesh, value):
    return fem.Constant(msh, ScalarType(value) if np.isscalar(value)
                        else np.asarray(value, dtype=ScalarType))


def form(expr):
    return fem.form(expr)


def facet_dofs(V, component: int, facets: np.ndarray) -> np.ndarray:
    """Unrolled dofs of component ``component`` on the given facets (owned and ghost)."""
    tdim = V.mesh.topology.dim
    return fem.locate_dofs_topological(V.sub(component), tdim - 1, facets)


def vertex_dofs(V, component: int, vertices: np.ndarray) -> np.ndarray:
    return fem.locate_dofs_topological(V.sub(component), 0, vertices)


def dirichletbc(value: fem.Constant, dofs: np.ndarray, V, component: int):
    return fem.dirichletbc(value, dofs, V.sub(component))


def dirichletbc_function(g: fem.Function, V, facets: np.ndarray):
    """Both components on ``facets`` prescribed by the vector Function ``g`` in V."""
    dofs = fem.locate_dofs_topological(V, V.mesh.topology.dim - 1, facets)
    return fem.dirichletbc(g, dofs)


def locate_vertices(msh: Mesh, marker) -> np.ndarray:
    return dmesh.locate_entities(msh, 0, marker)


def cells_of_vertices(msh: Mesh) -> "cpp.graph.AdjacencyList_int32":
    msh.topology.create_connectivity(0, msh.topology.dim)
    return msh.topology.connectivity(0, msh.topology.dim)


def facet_cells(msh: Mesh):
    tdim = msh.topology.dim
    msh.topology.create_connectivity(tdim - 1, tdim)
    return msh.topology.connectivity(tdim - 1, tdim)


def facet_vertices(msh: Mesh):
    tdim = msh.topology.dim
    msh.topology.create_connectivity(tdim - 1, 0)
    return msh.topology.connectivity(tdim - 1, 0)


def num_owned_cells(msh: Mesh) -> int:
    return msh.topology.index_map(msh.topology.dim).size_local


def vertex_to_geometry_node(msh: Mesh) -> np.ndarray:
    """Map vertex index → geometry node index (they differ in DOLFINx; linear cells)."""
    tdim = msh.topology.dim
    msh.topology.create_connectivity(tdim, 0)
    c2v = msh.topology.connectivity(tdim, 0).array
    g = msh.geometry.dofmap.array
    nv = msh.topology.index_map(0).size_local + msh.topology.index_map(0).num_ghosts
    out = np.full(nv, -1, dtype=np.int32)
    out[c2v] = g  # same local ordering within each linear cell
    return out


def dof_owner_range(V) -> tuple[int, int]:
    im = V.dofmap.index_map
    bs = V.dofmap.index_map_bs
    r = im.local_range
    return r[0] * bs, r[1] * bs


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
    blocks = V.dofmap.list.array
    nv = msh.topology.index_map(0).size_local + msh.topology.index_map(0).num_ghosts
    v2b = np.full(nv, -1, dtype=np.int64)
    v2b[c2v] = blocks
    bs = V.dofmap.index_map_bs
    b = v2b[np.asarray(vertices)]
    return np.stack([b * bs, b * bs + 1], axis=1)


# ----------------------------------------------------------------------------- PETSc


def create_matrix(a_form) -> PETSc.Mat:
    return fpetsc.create_matrix(a_form)


def create_vector(L_form) -> PETSc.Vec:
    return fpetsc.create_vector(L_form)


def function_vector(u: fem.Function) -> PETSc.Vec:
    return u.vector


def assemble_residual(b: PETSc.Vec, L_form, a_form, bcs, x: PETSc.Vec, extra=None) -> None:
    """b = F(x) with Dirichlet rows set to x − g; ``extra(b)`` adds non-form terms first."""
    with b.localForm() as loc:
        loc.set(0.0)
    fpetsc.assemble_vector(b, L_form)
    fpetsc.apply_lifting(b, [a_form], bcs=[bcs], x0=[x], scale=-1.0)
    b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
    if extra is not None:
        extra(b)
    fpetsc.set_bc(b, bcs, x, -1.0)


def assemble_unconstrained_residual(b: PETSc.Vec, L_form) -> None:
    with b.localForm() as loc:
        loc.set(0.0)
    fpetsc.assemble_vector(b, L_form)
    b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)


def assemble_jacobian(A: PETSc.Mat, a_form, bcs, extra=None) -> None:
    """A = dF/du with identity rows/columns on Dirichlet dofs; ``extra(A)`` adds entries
    (with ADD_VALUES, rows/columns of Dirichlet dofs must be skipped by the caller)."""
    A.zeroEntries()
    fpetsc.assemble_matrix(A, a_form, bcs=bcs)
    A.assemblyBegin(PETSc.Mat.AssemblyType.FLUSH)
    A.assemblyEnd(PETSc.Mat.AssemblyType.FLUSH)
    if extra is not None:
        extra(A)
    A.assemble()


def bc_dofs(bcs) -> np.ndarray:
    """Local unrolled dof indices constrained by the Dirichlet conditions."""
    out = [bc.dof_indices()[0] for bc in bcs]
    return np.unique(np.concatenate(out)) if out else np.zeros(0, dtype=np.int32)


def expression(expr, V) -> fem.Expression:
    """Compile a UFL expression for interpolation into V."""
    return fem.Expression(expr, V.element.interpolation_points())


def interpolate(target: fem.Function, compiled: fem.Expression, cells: np.ndarray) -> None:
    target.interpolate(compiled, cells)


# ----------------------------------------------------------------------------- output


class XDMFWriter:
    """Mesh once, then functions per pseudo-time."""

    def __init__(self, comm: MPI.Comm, path: str, msh: Mesh):
        self._f = io.XDMFFile(comm, path, "w")
        self._f.write_mesh(msh)

    def write(self, functions, t: float) -> None:
        for f in functions:
            self._f.write_function(f, t)

    def close(self) -> None:
        self._f.close()


def measures(msh: Mesh, cell_tags, facet_tags, degree: int):
    """Cell and facet measures with a fixed quadrature degree (UFL's estimate for the
    Neo-Hooke forms is 10–14, i.e. 36–64 points per quadrilateral)."""
    md = {"quadrature_degree": degree}
    dx = ufl.Measure("dx", domain=msh, subdomain_data=cell_tags, metadata=md)
    ds = ufl.Measure("ds", domain=msh, subdomain_data=facet_tags, metadata=md)
    return dx, ds


def sparsity_pattern(a_form):
    """The bulk form's sparsity pattern, still open for extra (contact) couplings."""
    return fem.create_sparsity_pattern(a_form)


def matrix_from_sparsity(a_form, pattern) -> PETSc.Mat:
    """Insert extra couplings first with ``pattern.insert(local_blocks, local_blocks)``.

    The bulk form is assembled once (flush only) so that its slots are written: a final
    assembly squeezes every preallocated slot not written yet, and the first Jacobian would
    then reallocate the whole bulk pattern entry by entry (Hertz, 23k dofs: 23 s instead
    of 0.9 s)."""
    pattern.assemble()
    A = cpp.la.petsc.create_matrix(a_form.mesh.comm, pattern)
    fpetsc.assemble_matrix(A, a_form)
    return A
