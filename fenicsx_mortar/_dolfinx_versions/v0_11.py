"""DOLFINx 0.11 (PyPI's ``dolfinx-solver-real``): ``v0_10.py`` but for the geometry dofmap.

Same names, arguments and results as ``v0_9.py`` (the reference).
"""
from __future__ import annotations

import numpy as np

from .v0_10 import (apply_lifting, assemble_matrix, create_matrix, create_vector, dofmap_list,
                    expression_eval, functionspace, input_global_indices,
                    interpolation_points, jit_cache_dir, matrix_from_pattern, model_to_mesh,
                    petsc_vec, set_bc)

__all__ = ["functionspace", "petsc_vec", "geometry_dofmap", "dofmap_list",
           "input_global_indices", "model_to_mesh", "interpolation_points",
           "create_vector", "create_matrix", "assemble_matrix", "apply_lifting", "set_bc",
           "matrix_from_pattern", "expression_eval", "jit_cache_dir"]


def geometry_dofmap(msh) -> np.ndarray:
    """0.11: ``geometry.dofmap`` warns (deprecated); ``dofmaps`` is a list property, one
    array per cell type (``dofmaps(0)`` raises: a list is not callable)."""
    return msh.geometry.dofmaps[0]
