"""Solve scenes and save, after every converged step, what an MPI run must reproduce of the
serial one: the nodal displacement (ordered by the mesh file's node numbers, so that serial
and parallel runs line up node by node, coincident nodes of two touching bodies included),
each contact pair's nodal pressure (and tangential traction and stick/slip status with
friction) keyed by the mesh-file number of the slave node, and the step records (Newton
iterations, reactions, contact records: what summary.json holds under "steps").

Usage (also under mpirun; several scenes share one interpreter start):

    python tests/dump_solution.py OUTDIR SCENE.toml [SCENE.toml ...]

writes OUTDIR/<scene stem>.npz (on rank 0). The scenes are solved without ``out``: the
files a run writes are checked separately (tests/test_mpi.py, test_cli_outputs).
"""
import json
import sys
from pathlib import Path

import numpy as np
from mpi4py import MPI

from fenicsx_mortar import load_scene, solve
from fenicsx_mortar import _dolfinx as dx
from fenicsx_mortar.io.checkpoint import _owned_nodes

comm = MPI.COMM_WORLD


class Recorder:
    """``on_step`` callback: gathers the step's nodal data on rank 0."""

    def __init__(self):
        self.u, self.contact = [], {}
        self.node = self.X = self.order = self.dof_to_node = None
        self._dofs = None  # local dofs (n, 2) of the nodes this rank owns

    def _numbering(self, V):
        node, dofs = _owned_nodes(V)
        gdof = dx.local_to_global_dofs(V)[dofs[:, 0]]  # global dof of each node's u_x
        X = V.tabulate_dof_coordinates()[dofs[:, 0] // 2, :2]
        parts = comm.gather((node, gdof, X), root=0)
        self._dofs = dofs
        if comm.rank == 0:
            node, gdof, X = (np.concatenate([p[i] for p in parts]) for i in range(3))
            self.order = np.argsort(node)
            self.node, self.X = node[self.order], X[self.order]
            assert np.all(np.diff(self.node) > 0), "a node owned by two ranks"
            self.dof_to_node = dict(zip(gdof.tolist(), node.tolist()))

    def __call__(self, record, state):
        V = state.u.function_space
        if self._dofs is None:
            self._numbering(V)
        parts = comm.gather(state.u.x.array[self._dofs], root=0)
        if comm.rank != 0:
            return
        self.u.append(np.concatenate(parts)[self.order])
        for h in state.pairs:
            d = h.interface()  # the same on every rank: the pair's nodal values are global
            slave_node = np.array([self.dof_to_node[int(g)] for g in h.slave.dofs[:, 0]])
            keys = ["pressure"] + (["t_tangential", "status"] if "status" in d else [])
            c = self.contact.setdefault(h.name, {"slave_node": slave_node})
            assert np.array_equal(c["slave_node"], slave_node)
            for k in keys:
                c.setdefault(k, []).append(np.asarray(d[k]))


def main(outdir: Path, scene_files: list[str]) -> None:
    for path in scene_files:
        scene = load_scene(path)
        rec = Recorder()
        res = solve(scene, log=lambda s: None, on_step=rec)
        if comm.rank != 0:
            continue
        arrays = {"node": rec.node, "X": rec.X, "u": np.array(rec.u),
                  "converged": np.array(res.converged), "ranks": np.array(comm.size),
                  "dofs": np.array(res.summary["dofs"]),
                  "steps": np.array(json.dumps(res.steps, default=float))}
        for name, c in rec.contact.items():
            for k, v in c.items():
                arrays[f"{name}:{k}"] = np.array(v)
        np.savez(outdir / f"{Path(path).stem}.npz", **arrays)


if __name__ == "__main__":
    main(Path(sys.argv[1]), sys.argv[2:])
