"""Solve a scene and save the nodal displacement with its coordinates (gathered on rank 0).

Usage: python tests/dump_solution.py SCENE.toml OUT.npz   (also under mpirun)
"""
import sys

import numpy as np
from mpi4py import MPI

from fenicsx_mortar import load_scene, solve

scene = load_scene(sys.argv[1])  # (a scene file; base_dir is its folder)
res = solve(scene, log=lambda s: None)
V = res.u.function_space
n = V.dofmap.index_map.size_local
X = V.tabulate_dof_coordinates()[:n, :2]
u = res.u.x.array.reshape(-1, 2)[:n]
parts = MPI.COMM_WORLD.gather((X, u), root=0)
if MPI.COMM_WORLD.rank == 0:
    X = np.concatenate([p[0] for p in parts])
    u = np.concatenate([p[1] for p in parts])
    key = np.round(X, 9)  # the same node may differ in the last bit between partitions
    order = np.lexsort((key[:, 1], key[:, 0]))
    np.savez(sys.argv[2], X=X[order], u=u[order], converged=res.converged,
             iterations=[s["newton_iterations"] for s in res.steps])
