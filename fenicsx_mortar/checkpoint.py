"""Checkpoints of the last converged step, for ``fenicsx-mortar run --restart DIR``.

The displacement is stored per ORIGINAL mesh node (gmsh input numbering), so a restart may
use another number of MPI ranks; each contact pair adds its history (ALM multipliers, NTS
segment choices, friction reference points) through ``state_dict``/``load_state_dict``.
Written atomically.
"""
from __future__ import annotations

import io
import json
import os
import tempfile
from pathlib import Path

import numpy as np
from mpi4py import MPI

from . import _dolfinx as dx

FILE = "checkpoint.npz"


def _owned_nodes(V):
    """(input node index, local dofs (n, 2)) of the vertices this rank owns."""
    msh = V.mesh
    verts = np.arange(dx.num_vertices(msh, ghosts=False), dtype=np.int32)
    geom = dx.vertex_to_geometry_node(msh)[verts]
    return dx.input_node_numbers(msh)[geom], dx.vertex_dofs_all(V, verts)


def save(out: Path, comm: MPI.Comm, u, pairs, t: float, k: int, steps: list[dict]) -> None:
    idx, dofs = _owned_nodes(u.function_space)
    parts = comm.gather((idx, u.x.array[dofs]), root=0)
    # state_dict is collective (it gathers per-node history from the owning ranks)
    states = [p.state_dict() for p in pairs]
    if comm.rank != 0:
        return
    idx = np.concatenate([p[0] for p in parts])
    vals = np.concatenate([p[1] for p in parts])
    order = np.argsort(idx)
    arrays = {"node": idx[order], "u": vals[order], "time": np.array(t), "step": np.array(k),
              "steps": np.array(json.dumps(steps, default=float))}
    for i, state in enumerate(states):
        for key, value in state.items():
            arrays[f"pair{i}_{key}"] = value
    buf = io.BytesIO()
    np.savez(buf, **arrays)
    fd, tmp = tempfile.mkstemp(dir=out, prefix=f".{FILE}.")
    with os.fdopen(fd, "wb") as f:
        f.write(buf.getvalue())
    os.replace(tmp, out / FILE)


def load(out: Path, comm: MPI.Comm, u, pairs) -> tuple[float, int, list[dict]]:
    """Set ``u`` and the pairs' history from the checkpoint; return (time, step, records)."""
    data = None
    if comm.rank == 0:
        with np.load(out / FILE) as f:
            data = {key: f[key] for key in f.files}
    data = comm.bcast(data, root=0)
    V = u.function_space
    msh = V.mesh
    verts = np.arange(dx.num_vertices(msh), dtype=np.int32)
    idx = dx.input_node_numbers(msh)[dx.vertex_to_geometry_node(msh)[verts]]
    node = data["node"]
    pos = np.searchsorted(node, idx)
    if np.any(pos >= len(node)) or np.any(node[np.minimum(pos, len(node) - 1)] != idx):
        raise ValueError(f"{out / FILE} does not match this mesh")
    u.x.array[dx.vertex_dofs_all(V, verts)] = data["u"][pos]
    for i, pair in enumerate(pairs):
        prefix = f"pair{i}_"
        pair.load_state_dict({k[len(prefix):]: v for k, v in data.items() if k.startswith(prefix)})
    return float(data["time"]), int(data["step"]), json.loads(str(data["steps"]))
