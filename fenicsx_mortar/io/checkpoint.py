"""Checkpoints of the last converged step, for ``fenicsx-mortar run --restart DIR``.

The displacement is stored per ORIGINAL mesh node (gmsh input numbering), so a restart may
use another number of MPI ranks; each contact pair adds its history (ALM multipliers, NTS
segment choices, friction reference points) through ``state_dict``/``load_state_dict``.
Written atomically (a failed write leaves the previous checkpoint and no temporary file).

A checkpoint carries the fingerprints of the scene it was written for (SHA-256 of the
scene as saved in scene.json) and of the mesh (SHA-256 of every node's number and
coordinates and every cell's nodes), and a checksum (SHA-256) over all its arrays. A
restart takes it as a whole or not at all: the checksum, the fingerprints, every array's
type and shape (the pairs' history against what the pairs hold), finite values, and the
time, the step and the step records agreeing with each other and with the scene's load
path; anything else is refused (SceneError naming checkpoint.npz, exit 2) before anything
is written.
"""
from __future__ import annotations

import hashlib
import io
import json
import math
import zipfile
from pathlib import Path

import numpy as np
from mpi4py import MPI

from .. import _dolfinx as dx
from .output import write_file
from ..scene.parallel import agree, on_rank0
from ..scene import SceneError, Steps, from_dict, json_loads

FILE = "checkpoint.npz"
#: the arrays every checkpoint has (the pairs add "pair<i>_<key>")
ARRAYS = ("node", "u", "time", "step", "steps", "fingerprint_scene", "fingerprint_mesh",
          "checksum")
#: the most a checkpoint may hold, unpacked (a mesh at the cell limit needs ~50 MB) and in
#: arrays: a zip that unpacks to more is not one of ours
MAX_BYTES, MAX_ARRAYS = 1 << 30, 10_000


def checksum(arrays: dict[str, np.ndarray]) -> str:
    """SHA-256 over every array but "checksum": its name, type, shape and bytes."""
    h = hashlib.sha256()
    for name in sorted(k for k in arrays if k != "checksum"):
        a = np.ascontiguousarray(arrays[name])
        h.update(f"{name}\0{a.dtype.str}\0{a.shape}\0".encode())
        h.update(a.tobytes())
    return h.hexdigest()


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
        arrays["checksum"] = np.array(checksum(arrays))
        buf = io.BytesIO()
        np.savez(buf, **arrays)
        write_file(out, FILE, buf.getvalue())
    on_rank0(comm, write)


def read(out: Path, comm: MPI.Comm, scene_json: str) -> dict:
    """The checkpoint's arrays (on every rank), checked as a whole (module docstring) except
    what needs the mesh and the pairs (:func:`load`). Raises SceneError naming the file
    (exit 2) before anything is written."""
    return on_rank0(comm, lambda: _read(out / FILE, scene_json), share=True)


def _read(path: Path, scene_json: str) -> dict:
    data = _arrays(path)
    missing = [a for a in ARRAYS if a not in data]
    if missing:
        old = " (written by an older version: before checkpoints had a checksum)" \
            if "u" in data and "node" in data else ""
        raise SceneError(f"{path}: not a checkpoint of this version: no {', '.join(missing)}"
                         f"{old}")
    if not _is_text(data["checksum"]) or str(data["checksum"]) != checksum(data):
        raise SceneError(f"{path}: its content does not match its checksum (edited or "
                         "damaged); refusing to continue from it")
    for key in ("fingerprint_scene", "fingerprint_mesh", "steps"):
        if not _is_text(data[key]):
            raise SceneError(f"{path}: array {key!r} is not a text")
    if str(data["fingerprint_scene"]) != scene_fingerprint(scene_json):
        raise SceneError(f"{path}: written for another scene than {path.parent / 'scene.json'}"
                         " (its scene fingerprint differs); refusing to continue it")
    node, u = data["node"], data["u"]
    if (node.ndim != 1 or u.shape != (len(node), 2) or not np.issubdtype(node.dtype, np.integer)
            or not np.issubdtype(u.dtype, np.floating) or not len(node)):
        raise SceneError(f"{path}: arrays 'node' {node.shape} and 'u' {u.shape} do not fit "
                         "(one displacement [ux, uy] per node)")
    if np.any(np.diff(node) <= 0):
        raise SceneError(f"{path}: array 'node' is not strictly increasing (each node once)")
    for key in ("time", "step"):
        kind = np.floating if key == "time" else np.integer
        if data[key].shape != () or not np.issubdtype(data[key].dtype, kind):
            raise SceneError(f"{path}: array {key!r} is not one "
                             f"{'number' if key == 'time' else 'integer'}")
    if not (np.isfinite(u).all() and np.isfinite(data["time"]).all()):
        raise SceneError(f"{path}: holds values that are not finite")
    for key, a in data.items():
        if key.startswith("pair") and np.issubdtype(a.dtype, np.floating) \
                and not np.isfinite(a).all():
            raise SceneError(f"{path}: holds values that are not finite (array {key!r})")
    data["steps"] = _records(path, str(data["steps"]))
    _check_path(path, float(data["time"]), int(data["step"]), data["steps"], scene_json)
    return data


def _arrays(path: Path) -> dict:
    """Every array of the .npz (no pickles), after a look at the zip's directory: at most
    MAX_ARRAYS arrays and MAX_BYTES unpacked."""
    try:
        with zipfile.ZipFile(path) as z:
            infos = z.infolist()
        if len(infos) > MAX_ARRAYS or sum(i.file_size for i in infos) > MAX_BYTES:
            raise SceneError(f"{path}: {len(infos)} arrays of {sum(i.file_size for i in infos):,}"
                             f" bytes unpacked: more than a checkpoint holds "
                             f"({MAX_BYTES:,} bytes at most)")
        with np.load(path, allow_pickle=False) as f:
            return {key: f[key] for key in f.files}
    except SceneError:
        raise
    except Exception as e:  # BadZipFile, EOFError, ValueError, IsADirectoryError, ...
        raise SceneError(f"{path}: not a readable checkpoint ({type(e).__name__}: {e})") \
            from None


def _is_text(a: np.ndarray) -> bool:
    return a.shape == () and a.dtype.kind == "U"


def _records(path: Path, text: str) -> list[dict]:
    try:
        steps = json_loads(text)
    except ValueError:
        steps = None
    if not isinstance(steps, list) or not all(isinstance(s, dict) for s in steps):
        raise SceneError(f"{path}: its step records are not a JSON list of records")
    return steps


def _check_path(path: Path, t: float, k: int, steps: list[dict], scene_json: str) -> None:
    """The time, the step and the records agree: step k is the k-th record, the records
    are steps 1..k at increasing times, the last at ``t``, and ``t`` lies on the scene's
    load path (0, last target]."""
    try:
        st = from_dict(Steps, json.loads(scene_json).get("steps", {}), "steps")
        end = st.targets()[-1]
    except (SceneError, ValueError, AttributeError, IndexError):
        return          # the saved scene itself was checked (load_scene_json)
    if not 0 < t <= end * (1 + 1e-12):
        raise SceneError(f"{path}: time = {t:g} is not on the scene's load path (0, {end:g}]")
    if not 1 <= k == len(steps):
        raise SceneError(f"{path}: step = {k} but it holds {len(steps)} step records (one per "
                         "converged step, the last one the checkpoint's)")
    times = []
    for i, r in enumerate(steps):
        ti = r.get("time")
        if r.get("step") != i + 1 or isinstance(ti, bool) or not isinstance(ti, (int, float)) \
                or not math.isfinite(ti):
            raise SceneError(f"{path}: step record {i} is not step {i + 1} with a time")
        times.append(float(ti))
    if any(b <= a for a, b in zip([0.0, *times], times)) or times[-1] != t:
        raise SceneError(f"{path}: time = {t:g} and the step records' times "
                         f"({', '.join(f'{x:g}' for x in times[-3:])}) disagree (they must "
                         "increase to the checkpoint's time)")


def load(out: Path, comm: MPI.Comm, u, pairs, data: dict, mesh_fp: str
         ) -> tuple[float, int, list[dict]]:
    """Set ``u`` and the pairs' history from the checked ``data`` (:func:`read`) after
    checking it belongs to this mesh and these pairs (collective); return (time, step,
    records)."""
    path = out / FILE
    if str(data["fingerprint_mesh"]) != mesh_fp:
        raise SceneError(f"{path}: written for another mesh (its mesh fingerprint differs: "
                         "the mesh file changed?); refusing to continue it")
    msh = u.function_space.mesh
    if len(data["node"]) != dx.num_vertices_global(msh):
        raise SceneError(f"{path}: holds {len(data['node'])} nodes, the mesh has "
                         f"{dx.num_vertices_global(msh)}")
    _check_history(path, data, pairs, [p.state_dict() for p in pairs])

    def apply() -> None:
        V = u.function_space
        verts = np.arange(dx.num_vertices(msh), dtype=np.int32)
        idx = dx.input_node_numbers(msh)[dx.vertex_to_geometry_node(msh)[verts]]
        node = data["node"]
        pos = np.searchsorted(node, idx)
        if np.any(pos >= len(node)) or np.any(node[np.minimum(pos, len(node) - 1)] != idx):
            raise SceneError(f"{path} does not match this mesh")
        u.x.array[dx.vertex_dofs_all(V, verts)] = data["u"][pos]
        for i, pair in enumerate(pairs):
            prefix = f"pair{i}_"
            pair.load_state_dict({k[len(prefix):]: v for k, v in data.items()
                                  if k.startswith(prefix)})
    agree(comm, apply)
    return float(data["time"]), int(data["step"]), data["steps"]


def _check_history(path: Path, data: dict, pairs: list, expected: list[dict]) -> None:
    """Each pair's arrays: the names, shapes and kinds (float, integer) of what the pair
    holds (``expected``: its state_dict, the same on every rank), and segment numbers
    (integer arrays) that name a master segment or none (-1)."""
    stored = {k for k in data if k.startswith("pair")}
    for i, (pair, want) in enumerate(zip(pairs, expected)):
        prefix = f"pair{i}_"
        have = {k[len(prefix):] for k in stored if k.startswith(prefix)}
        stored -= {prefix + k for k in have}
        if have != set(want):
            raise SceneError(f"{path}: the history of contact {pair.name} has arrays "
                             f"{sorted(have)}, the pair holds {sorted(want)}")
        for key, ref in want.items():
            a = data[prefix + key]
            if a.shape != np.shape(ref) or a.dtype.kind != np.asarray(ref).dtype.kind:
                raise SceneError(f"{path}: the history of contact {pair.name}: {key!r} is "
                                 f"{a.dtype.kind}{a.shape}, the pair holds "
                                 f"{np.asarray(ref).dtype.kind}{np.shape(ref)}")
            n_seg = len(pair.master.seg)
            if a.dtype.kind in "iu" and a.size and not (a.min() >= -1 and a.max() < n_seg):
                raise SceneError(f"{path}: the history of contact {pair.name}: {key!r} names "
                                 f"segments outside the master's 0..{n_seg - 1}")
    if stored:
        raise SceneError(f"{path}: arrays {sorted(stored)[:3]} belong to no contact pair of "
                         "the scene")
