"""DOLFINx 0.9 (Debian 13): the calls whose form depends on the DOLFINx version.

This module is the reference shape: ``fenicsx_mortar/_dolfinx.py`` is written against these
functions, and every other generation (``v0_5.py``) gives the same functions with the same
arguments and results. Each function is one DOLFINx call, or the few lines that one call
became; "0.10:"/"0.11:" notes say what those generations change (``v0_10.py``,
``v0_11.py``, docs/dolfinx-versions.md).
Nothing here runs at import time, so every generation's module imports on any DOLFINx
(tests/test_dolfinx_layer.py compares them).
"""
from __future__ import annotations

import numpy as np
from dolfinx import cpp, fem
from dolfinx.fem import petsc as fpetsc

__all__ = ["functionspace", "petsc_vec", "geometry_dofmap", "dofmap_list",
           "input_global_indices", "model_to_mesh", "interpolation_points",
           "create_vector", "create_matrix", "assemble_matrix", "apply_lifting", "set_bc",
           "matrix_from_pattern", "expression_eval", "jit_cache_dir"]


def functionspace(msh, element: tuple):
    """The space of ``element`` = (family, degree) or (family, degree, value shape), e.g.
    ("Lagrange", 1, (2,)) or ("DG", 0, (2, 2)): 0.9's one constructor for every space."""
    return fem.functionspace(msh, element)


def petsc_vec(u):
    """The ghosted PETSc Vec sharing ``u.x``'s memory (owned entries, then ghosts)."""
    return u.x.petsc_vec


def geometry_dofmap(msh) -> np.ndarray:
    """(num_cells, nodes_per_cell) int32 geometry node indices of every local cell (owned,
    then ghosts). 0.11: ``geometry.dofmap`` is deprecated for ``geometry.dofmaps[0]`` (a
    list property)."""
    return msh.geometry.dofmap


def dofmap_list(V) -> np.ndarray:
    """(num_cells, blocks_per_cell) int32 dof blocks of every local cell."""
    return V.dofmap.list


def input_global_indices(msh) -> np.ndarray:
    """The mesh file's (0-based) number of every local geometry node, int64."""
    return np.asarray(msh.geometry.input_global_indices, dtype=np.int64)


def model_to_mesh(model, comm, rank: int, gdim: int):
    """gmsh model on ``rank`` → (mesh, cell tags, facet tags) distributed over ``comm``.
    0.10: the module is ``dolfinx.io.gmsh`` and returns a ``MeshData`` named tuple whose
    tags are None for a dimension without physical groups."""
    from dolfinx.io import gmshio
    msh, cell_tags, facet_tags = gmshio.model_to_mesh(model, comm, rank, gdim=gdim)
    return msh, cell_tags, facet_tags


def interpolation_points(V) -> np.ndarray:
    """The reference points at which V's element interpolates (for ``fem.Expression``).
    0.10: ``V.element.interpolation_points`` is a property."""
    return V.element.interpolation_points()


def create_vector(L_form):
    """A ghosted PETSc Vec for the compiled linear form. 0.10: takes the function space,
    ``create_vector(L_form.function_spaces[0])``."""
    return fpetsc.create_vector(L_form)


def create_matrix(a_form):
    """A PETSc Mat with the compiled bilinear form's sparsity. 0.10: ``kind=`` replaces
    ``mat_type=`` (unused here)."""
    return fpetsc.create_matrix(a_form)


def assemble_matrix(A, a_form, bcs) -> None:
    """Add the form into A (flushed), with 1 on the diagonal of Dirichlet rows."""
    fpetsc.assemble_matrix(A, a_form, bcs=bcs)


def apply_lifting(b, a_forms: list, bcs: list, x0: list, alpha: float) -> None:
    """b −= alpha · A (g − x0) on the Dirichlet columns (0.9 names the factor ``alpha``)."""
    fpetsc.apply_lifting(b, a_forms, bcs=bcs, x0=x0, alpha=alpha)


def set_bc(b, bcs: list, x0, alpha: float) -> None:
    """b = alpha · (g − x0) on the owned Dirichlet rows."""
    fpetsc.set_bc(b, bcs, x0, alpha=alpha)


def matrix_from_pattern(comm, pattern):
    """A PETSc Mat from a sparsity pattern still open for insertions (closed here: 0.9's
    ``SparsityPattern.finalize``)."""
    pattern.finalize()
    return cpp.la.petsc.create_matrix(comm, pattern)


def expression_eval(expr, msh, cells) -> np.ndarray:
    """Values of a compiled ``fem.Expression`` on the given local cells, (n_cells, ...).
    0.9 takes the mesh as well."""
    return expr.eval(msh, np.asarray(cells, dtype=np.int32))


def jit_cache_dir():
    """The directory of DOLFINx's JIT cache (FFCx modules)."""
    from dolfinx import jit
    return jit.get_options()["cache_dir"]
