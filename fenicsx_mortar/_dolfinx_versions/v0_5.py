"""DOLFINx 0.5 (Debian 12's 0.5.2): the functions of ``v0_9.py``, adapted to the old API.

Same names, arguments and results as ``v0_9.py`` (the reference); only what 0.5 spells
differently is written out here, the rest is 0.9's unchanged.
"""
from __future__ import annotations

import numpy as np
from dolfinx import cpp, fem
from dolfinx.fem import petsc as fpetsc

from .v0_9 import (assemble_matrix, create_matrix, create_vector, interpolation_points,
                   model_to_mesh)

__all__ = ["functionspace", "petsc_vec", "geometry_dofmap", "dofmap_list",
           "input_global_indices", "model_to_mesh", "interpolation_points",
           "create_vector", "create_matrix", "assemble_matrix", "apply_lifting", "set_bc",
           "matrix_from_pattern", "expression_eval", "jit_cache_dir"]


def functionspace(msh, element: tuple):
    """0.9's ``fem.functionspace(msh, (family, degree[, shape]))`` from 0.5's three
    constructors (the value shape picks Vector- or TensorFunctionSpace)."""
    family, degree, *rest = element
    shape = tuple(rest[0]) if rest else ()
    if len(shape) == 0:
        return fem.FunctionSpace(msh, (family, degree))
    if len(shape) == 1:
        return fem.VectorFunctionSpace(msh, (family, degree), dim=shape[0])
    return fem.TensorFunctionSpace(msh, (family, degree), shape=shape)


def petsc_vec(u):
    """0.5: ``Function.vector`` (the same ghosted Vec over ``u.x``)."""
    return u.vector


def geometry_dofmap(msh) -> np.ndarray:
    """0.5: an AdjacencyList, made the 2D array of 0.9 (its row length from the coordinate
    element, so that a rank without cells gets (0, k) too)."""
    k = msh.geometry.cmap.create_dof_layout().num_dofs
    return msh.geometry.dofmap.array.reshape(-1, k)


def dofmap_list(V) -> np.ndarray:
    """0.5: an AdjacencyList, made the 2D array of 0.9."""
    return V.dofmap.list.array.reshape(-1, V.dofmap.dof_layout.num_dofs)


def input_global_indices(msh) -> np.ndarray:
    """0.5: a Python list (empty on a rank without nodes: float64 under np.asarray)."""
    return np.asarray(msh.geometry.input_global_indices, dtype=np.int64)


def apply_lifting(b, a_forms: list, bcs: list, x0: list, alpha: float) -> None:
    """0.5 names the factor ``scale``."""
    fpetsc.apply_lifting(b, a_forms, bcs=bcs, x0=x0, scale=alpha)


def set_bc(b, bcs: list, x0, alpha: float) -> None:
    """0.5 names the factor ``scale``."""
    fpetsc.set_bc(b, bcs, x0, scale=alpha)


def matrix_from_pattern(comm, pattern):
    """0.5 closes a sparsity pattern with ``assemble`` (0.9: ``finalize``)."""
    pattern.assemble()
    return cpp.la.petsc.create_matrix(comm, pattern)


def expression_eval(expr, msh, cells) -> np.ndarray:
    """0.9's ``expr.eval(msh, cells)``: 0.5 takes the cells only."""
    return expr.eval(np.asarray(cells, dtype=np.int32))


def jit_cache_dir():
    """0.9's ``jit.get_options()["cache_dir"]``: 0.5 calls them parameters."""
    from dolfinx import jit
    return jit.get_parameters()["cache_dir"]
