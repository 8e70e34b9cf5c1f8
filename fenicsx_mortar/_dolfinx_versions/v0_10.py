"""DOLFINx 0.10: the functions of ``v0_9.py`` where 0.10 spells them differently.

Same names, arguments and results as ``v0_9.py`` (the reference); what 0.10 kept from 0.9
is imported from there. ``v0_11.py`` takes this module whole but for the geometry dofmap.
Checked against the v0.10.0 source only: no 0.10 build runs here (0.11 does, from PyPI).
"""
from __future__ import annotations

import numpy as np
from dolfinx.fem import petsc as fpetsc

from .v0_9 import (apply_lifting, assemble_matrix, create_matrix, dofmap_list,
                   expression_eval, functionspace, geometry_dofmap, input_global_indices,
                   jit_cache_dir, matrix_from_pattern, petsc_vec, set_bc)

__all__ = ["functionspace", "petsc_vec", "geometry_dofmap", "dofmap_list",
           "input_global_indices", "model_to_mesh", "interpolation_points",
           "create_vector", "create_matrix", "assemble_matrix", "apply_lifting", "set_bc",
           "matrix_from_pattern", "expression_eval", "jit_cache_dir"]


def model_to_mesh(model, comm, rank: int, gdim: int):
    """0.10: ``dolfinx.io.gmsh`` (``gmshio`` is gone) returns a ``MeshData`` named tuple
    whose tags are None for a dimension without physical groups; 0.9 gave empty tags, which
    callers index without a check, so None becomes empty tags here."""
    from dolfinx import mesh as dmesh
    from dolfinx.io import gmsh as dgmsh
    data = dgmsh.model_to_mesh(model, comm, rank, gdim=gdim)
    msh = data.mesh
    tdim = msh.topology.dim

    def tags(t, dim: int):
        if t is not None:
            return t
        none = np.zeros(0, dtype=np.int32)
        return dmesh.meshtags(msh, dim, none, none)
    return msh, tags(data.cell_tags, tdim), tags(data.facet_tags, tdim - 1)


def interpolation_points(V) -> np.ndarray:
    """0.10: a property of the (now Python) ``V.element``."""
    return V.element.interpolation_points


def create_vector(L_form):
    """0.10: ``create_vector`` takes the space(s), not the form."""
    return fpetsc.create_vector(L_form.function_spaces[0])

