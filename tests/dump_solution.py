"""Solve a scene and save the nodal displacement with its coordinates (gathered on rank 0),
ordered by the mesh file's node numbers, so that serial and parallel runs line up node by
node (coincident nodes of two touching bodies included).

Usage: python tests/dump_solution.py SCENE.toml OUT.npz   (also under mpirun)
"""
import sys

import numpy as np
from mpi4py import MPI

from fenicsx_mortar import load_scene, solve
from fenicsx_mortar.checkpoint import _owned_nodes

scene = load_scene(sys.argv[1])  # (a scene file; base_dir is its folder)
res = solve(scene, log=lambda s: None)
V = res.u.function_space
node, dofs = _owned_nodes(V)
X = V.tabulate_dof_coordinates()[dofs[:, 0] // 2, :2]
u = res.u.x.array[dofs]
parts = MPI.COMM_WORLD.gather((node, X, u), root=0)
if MPI.COMM_WORLD.rank == 0:
    node, X, u = (np.concatenate([p[i] for p in parts]) for i in range(3))
    order = np.argsort(node)
    assert np.all(np.diff(node[order]) > 0), "a node owned twice"
    np.savez(sys.argv[2], X=X[order], u=u[order], converged=res.converged,
             iterations=[s["newton_iterations"] for s in res.steps])
