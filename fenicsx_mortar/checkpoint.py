"""Checkpoints of the last converged step, for ``fenicsx-mortar run --restart DIR``.

The displacement is stored per ORIGINAL mesh node (gmsh input numbering), so a restart may
use another number of MPI ranks; each contact pair adds its history (ALM multipliers, NTS
segment choices, friction reference points) through ``state_dict``/``load_state_dict``.
Written atomically (a failed write leaves the previous checkpoint and no temporary file).

A checkpoint carries the fingerprints of the scene it was written for (SHA-256 of the
scene as saved in scene.json) and of the mesh (SHA-256 of every node's number and
coordinates and every cell's nodes): a restart refuses, before anything is written, a
checkpoint that is corrupt or comes from another scene or mesh.
"""
from __future__ import annotations

import hashlib
import io
import json
from pathlib import Path

import numpy as np
from mpi4py import MPI

from . import _dolfinx as dx
from .output import write_file
from .parallel import agree, on_rank0
from .scene import SceneError

FILE = "checkpoint.npz"
#: the arrays every checkpoint has (the pairs add "pair<i>_<key>")
ARRAYS = ("node", "u", "time", "step", "steps", "fingerprint_scene", "fingerprint_mesh")


def scene_fingerprint(scene_json: str) -> str:
    """Of the scene as scene.json holds it (run.scene_to_json, a canonical text)."""
    return hashlib.sha256(scene_json.encode()).hexdigest()


def mesh_fingerprint(dom, comm: MPI.Comm) -> str:
    """Of the mesh whatever its distribution: nodes (input number, x, y), cells (their
    nodes' input numbers, sorted, and their group's name) and the tagged facets (midpoint
    and group name), gathered and sorted on rank 0 (collective). The groups count: a mesh
    file with the same cells but a boundary moved to another group is another problem."""
    msh = dom.mesh
    idx = dx.input_node_numbers(msh).astype(np.int64)
    x = np.ascontiguousarray(dx.node_coordinates(msh), dtype=np.float64)
    n_own = dx.num_owned_cells(msh)
    cells = np.sort(idx[dx.cell_nodes(msh)[:n_own]], axis=1)
    cell_names = {t: n for n, t in dom.cell_groups.items()}
    tag = np.full(dx.num_cells(msh), -1)
    tag[dom.cell_tags.indices] = dom.cell_tags.values
    body = [cell_names.get(int(t), "") for t in tag[:n_own]]
    facet_names = {t: n for n, t in dom.facet_groups.items()}
    ft = dom.facet_tags
    mid = dx.midpoints(msh, 1, ft.indices)[:, :2] if len(ft.indices) else np.zeros((0, 2))
    facets = [(float(m[0]), float(m[1]), facet_names.get(int(t), ""))
              for m, t in zip(mid, ft.values)]
    parts = comm.gather((idx, x, cells, body, facets), root=0)
    digest = None
    if comm.rank == 0:
        idx = np.concatenate([p[0] for p in parts])
        x = np.concatenate([p[1] for p in parts])
        idx, first = np.unique(idx, return_index=True)
        cells = np.concatenate([p[2] for p in parts])
        body = [b for p in parts for b in p[3]]
        order = np.lexsort(cells.T[::-1])
        h = hashlib.sha256()
        for a in (idx, x[first], cells[order]):
            h.update(np.ascontiguousarray(a).tobytes())
        h.update("\n".join(body[i] for i in order).encode())
        h.update(repr(sorted({f for p in parts for f in p[4]})).encode())
        digest = h.hexdigest()
    return comm.bcast(digest, root=0)


def _owned_nodes(V):
    """(input node index, local dofs (n, 2)) of the vertices this rank owns."""
    msh = V.mesh
    verts = np.arange(dx.num_vertices(msh, ghosts=False), dtype=np.int32)
    geom = dx.vertex_to_geometry_node(msh)[verts]
    return dx.input_node_numbers(msh)[geom], dx.vertex_dofs_all(V, verts)


def save(out: Path, comm: MPI.Comm, u, pairs, t: float, k: int, steps: list[dict],
         fingerprints: tuple[str, str]) -> None:
    """Collective; rank 0 writes. A failed write raises OSError on every rank."""
    idx, dofs = _owned_nodes(u.function_space)
    parts = comm.gather((idx, u.x.array[dofs]), root=0)
    # state_dict is collective (it gathers per-node history from the owning ranks)
    states = [p.state_dict() for p in pairs]

    def write() -> None:
        idx = np.concatenate([p[0] for p in parts])
        vals = np.concatenate([p[1] for p in parts])
        order = np.argsort(idx)
        arrays = {"node": idx[order], "u": vals[order], "time": np.array(t),
                  "step": np.array(k), "steps": np.array(json.dumps(steps, default=float)),
                  "fingerprint_scene": np.array(fingerprints[0]),
                  "fingerprint_mesh": np.array(fingerprints[1])}
        for i, state in enumerate(states):
            for key, value in state.items():
                arrays[f"pair{i}_{key}"] = value
        buf = io.BytesIO()
        np.savez(buf, **arrays)
        write_file(out, FILE, buf.getvalue())
    on_rank0(comm, write)


def read(out: Path, comm: MPI.Comm, scene_json: str) -> dict:
    """The checkpoint's arrays (on every rank), checked: a readable file with every array,
    finite values of consistent shapes, written for this scene. Raises SceneError naming
    the file (exit 2) before anything is written."""
    return on_rank0(comm, lambda: _read(out / FILE, scene_json), share=True)


def _read(path: Path, scene_json: str) -> dict:
    try:
        with np.load(path, allow_pickle=False) as f:
            data = {key: f[key] for key in f.files}
    except Exception as e:  # BadZipFile, EOFError, ValueError, IsADirectoryError, ...
        raise SceneError(f"{path}: not a readable checkpoint ({type(e).__name__}: {e})") \
            from None
    missing = [a for a in ARRAYS if a not in data]
    if missing:
        old = " (written before checkpoints had fingerprints)" if "fingerprint_scene" in \
            missing and "u" in data else ""
        raise SceneError(f"{path}: not a checkpoint of this version: no {', '.join(missing)}"
                         f"{old}")
    if str(data["fingerprint_scene"]) != scene_fingerprint(scene_json):
        raise SceneError(f"{path}: written for another scene than {path.parent / 'scene.json'}"
                         " (its scene fingerprint differs); refusing to continue it")
    node, u = data["node"], data["u"]
    if (node.ndim != 1 or u.shape != (len(node), 2) or not np.issubdtype(node.dtype, np.integer)
            or not np.issubdtype(u.dtype, np.floating)):
        raise SceneError(f"{path}: arrays 'node' {node.shape} and 'u' {u.shape} do not fit "
                         "(one displacement [ux, uy] per node)")
    if not (np.isfinite(u).all() and np.isfinite(data["time"]).all()):
        raise SceneError(f"{path}: holds values that are not finite")
    try:
        steps = json.loads(str(data["steps"]))
    except ValueError:
        steps = None
    if not isinstance(steps, list) or not all(isinstance(s, dict) for s in steps):
        raise SceneError(f"{path}: its step records are not a JSON list of records")
    data["steps"] = steps
    return data


def load(out: Path, comm: MPI.Comm, u, pairs, data: dict, mesh_fp: str
         ) -> tuple[float, int, list[dict]]:
    """Set ``u`` and the pairs' history from the checked ``data`` (:func:`read`) after
    checking it belongs to this mesh; return (time, step, records)."""
    path = out / FILE
    if str(data["fingerprint_mesh"]) != mesh_fp:
        raise SceneError(f"{path}: written for another mesh (its mesh fingerprint differs: "
                         "the mesh file changed?); refusing to continue it")

    def apply() -> None:
        V = u.function_space
        msh = V.mesh
        verts = np.arange(dx.num_vertices(msh), dtype=np.int32)
        idx = dx.input_node_numbers(msh)[dx.vertex_to_geometry_node(msh)[verts]]
        node = data["node"]
        pos = np.searchsorted(node, idx)
        if np.any(pos >= len(node)) or np.any(node[np.minimum(pos, len(node) - 1)] != idx):
            raise SceneError(f"{path} does not match this mesh")
        u.x.array[dx.vertex_dofs_all(V, verts)] = data["u"][pos]
        for i, pair in enumerate(pairs):
            prefix = f"pair{i}_"
            try:
                pair.load_state_dict({k[len(prefix):]: v for k, v in data.items()
                                      if k.startswith(prefix)})
            except (KeyError, ValueError, IndexError) as e:
                raise SceneError(f"{path}: the history of contact {pair.name} does not fit "
                                 f"({type(e).__name__}: {e})") from None
    agree(comm, apply)
    return float(data["time"]), int(data["step"]), data["steps"]
