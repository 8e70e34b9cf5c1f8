"""Contact surfaces: the oriented chain(s) of the boundary facets with given meshtag values.

Surfaces are 1D and small, so every rank holds the whole surface (gathered once): reference
coordinates, global dof numbers, and segments oriented so that n = e₃ × t points out of the
body (docs/design.md §3). Current coordinates are gathered again at every Newton iterate.
"""
from __future__ import annotations

import functools
from dataclasses import dataclass, field
from typing import Sequence

import numpy as np
from mpi4py import MPI

from .. import _dolfinx as dx
from .boundary import chain_neighbours


@dataclass
class Surface:
    name: str
    X: np.ndarray          # (n, 2) reference coordinates, nodes ordered along the chains
    dofs: np.ndarray       # (n, 2) global dof numbers of (u_x, u_y)
    vertices: np.ndarray   # (n,) global vertex numbers of the mesh's topology
    seg: np.ndarray        # (n_seg, 2) node indices; e₃ × (x_b − x_a) points outward
    body_tag: int          # cell tag of the body the surface bounds (−1: no cell tags)
    _mine: np.ndarray      # surface indices of the nodes whose dofs this rank owns
    _mine_local: np.ndarray  # their local (unrolled) dof indices, (k, 2)
    comm: MPI.Comm
    owned: np.ndarray = field(init=False)  # (n,) True for the nodes whose dofs this rank owns

    def __post_init__(self):
        self.owned = np.zeros(self.n, dtype=bool)
        self.owned[self._mine] = True

    @property
    def n(self) -> int:
        return len(self.X)

    @property
    def owned_nodes(self) -> np.ndarray:
        """Surface indices of the nodes whose dofs this rank owns."""
        return self._mine

    @property
    def owned_local_dofs(self) -> np.ndarray:
        """(k, 2) this rank's local (unrolled) dofs of :attr:`owned_nodes`."""
        return self._mine_local

    def owned_sum(self, values: np.ndarray) -> np.ndarray:
        """Every rank gets each node's value from the rank that owns the node (the others'
        partial sums at a partition boundary are dropped)."""
        if self.comm.size == 1:
            return values
        return self.comm.allreduce(np.where(self.owned, values, 0.0), op=MPI.SUM)

    def displacement(self, u) -> np.ndarray:
        """(n, 2) current nodal displacement, gathered from the owning ranks."""
        vals = u.x.array[self._mine_local]
        if self.comm.size == 1:
            out = np.empty((self.n, 2))
            out[self._mine] = vals
            return out
        parts = self.comm.allgather((self._mine, vals))
        out = np.empty((self.n, 2))
        for idx, v in parts:
            out[idx] = v
        return out

    def arc_length(self, x: np.ndarray) -> np.ndarray:
        """Arc length along the chain at each node (restarting at 0 on each chain)."""
        s = np.zeros(self.n)
        for a, b in self.seg:  # nodes are ordered along the chains, so b follows a
            s[b] = s[a] + np.hypot(*(x[b] - x[a]))
        return s

    @functools.cached_property
    def neighbours(self) -> np.ndarray:
        """(n, 2) chain neighbours of every node, −1 at a chain's end
        (:func:`.boundary.chain_neighbours`)."""
        return chain_neighbours(self.seg, self.n)

    def lengths(self) -> np.ndarray:
        """Segment lengths in the reference configuration."""
        return np.linalg.norm(self.X[self.seg[:, 1]] - self.X[self.seg[:, 0]], axis=1)

    def mean_length(self) -> float:
        """Mean segment length in the reference configuration."""
        return float(np.mean(self.lengths()))


def build_surface(V, facet_tags, values: int | Sequence[int], name: str,
                  cell_tags=None) -> Surface:
    """The facets of ``facet_tags`` with the given tag value(s), gathered from all ranks and
    ordered into oriented chains; ``V`` the (P1 vector) displacement space; with
    ``cell_tags`` the surface must bound cells of one tag (one body)."""
    msh = V.mesh
    comm = msh.comm
    tdim = dx.topological_dimension(msh)
    if not dx.is_p1_vector_space(V):
        raise ValueError(f"contact surface {name}: the displacement space must be the P1 "
                         "vector space of the mesh (two dofs at every vertex); this one has "
                         f"{dx.dof_count(V)} dofs for {dx.num_vertices_global(msh)} vertices")
    for tags, dim, what in ((facet_tags, tdim - 1, "facet_tags"), (cell_tags, tdim, "cell_tags")):
        if tags is not None and getattr(tags, "dim", dim) != dim:
            raise ValueError(f"contact surface {name}: {what} are meshtags of dimension "
                             f"{tags.dim}; they must be of dimension {dim}")
    values = np.atleast_1d(np.asarray(values))
    facets = np.sort(facet_tags.indices[np.isin(facet_tags.values, values)])
    facets = facets[facets < dx.num_owned_facets(msh)]
    f2v = dx.facet_vertices(msh)
    f2c = dx.facet_cells(msh)
    v2g = dx.vertex_to_geometry_node(msh)
    x = dx.node_coordinates(msh)
    cells = dx.cell_nodes(msh)
    l2g = dx.local_to_global_dofs(V)
    n_owned_dofs = dx.owned_dof_count(V)

    cell_tag = np.full(len(cells), -1, dtype=np.int64)
    if cell_tags is not None:
        cell_tag[cell_tags.indices] = cell_tags.values
    rows, tags = [], []
    vertex_dofs = dx.vertex_dofs_all(V, np.arange(dx.num_vertices(msh)))   # once: O(cells)
    for f in facets:
        v = f2v.links(f)
        p = x[v2g[v]]
        c = f2c.links(f)[0]
        centroid = x[cells[c]].mean(axis=0)
        t = p[1] - p[0]
        if np.dot(0.5 * (p[0] + p[1]) - centroid, [-t[1], t[0]]) < 0:
            v, p = v[::-1], p[::-1]  # orient so that e₃ × t points out of the body
        d = vertex_dofs[v]
        rows.append((l2g[d], p, d, d[:, 0] < n_owned_dofs, dx.global_vertices(msh, v)))
        tags.append(int(cell_tag[c]))
    gathered = comm.allgather(rows)
    tags = [t for part in comm.allgather(tags) for t in part]
    if not tags:
        raise ValueError(f"contact surface {name}: no facets with tag(s) {values.tolist()}")
    if len(set(tags)) != 1:
        raise ValueError(f"contact surface {name} must bound exactly one body; its facets "
                         f"touch cells of {len(set(tags))} bodies")

    key_index: dict[int, int] = {}
    X, dofs, verts, seg = [], [], [], []
    for part in gathered:
        for gd, p, _, _, gv in part:
            ends = []
            for k in range(2):
                key = int(gd[k, 0])
                if key not in key_index:
                    key_index[key] = len(X)
                    X.append(p[k])
                    dofs.append(gd[k])
                    verts.append(gv[k])
                ends.append(key_index[key])
            seg.append(ends)
    X, dofs = np.array(X, dtype=float), np.array(dofs, dtype=np.int64)
    verts = np.array(verts, dtype=np.int64)
    seg = np.array(seg, dtype=np.int64).reshape(-1, 2)
    _check_chain(name, X, seg)
    order, seg_order = _chain_order(seg, len(X))
    renum = np.empty(len(X), dtype=np.int64)
    renum[order] = np.arange(len(X))
    X, dofs, verts = X[order], dofs[order], verts[order]
    seg = renum[seg[seg_order]]

    mine, mine_local = [], []
    for gd, _, d, own, _ in rows:
        for k in range(2):
            if own[k]:
                mine.append(renum[key_index[int(gd[k, 0])]])
                mine_local.append(d[k])
    mine = np.array(mine, dtype=np.int64)
    mine_local = np.array(mine_local, dtype=np.int32).reshape(-1, 2)
    mine, first = np.unique(mine, return_index=True)
    return Surface(name, X, dofs, verts, seg, tags[0], mine, mine_local[first], comm)


def _check_chain(name: str, X: np.ndarray, seg: np.ndarray) -> None:
    """A surface is one or more simple chains: no node in more than two segments (a
    branch, two facets of the body meeting at a pinched node)."""
    count = np.bincount(seg.ravel(), minlength=len(X))
    bad = np.flatnonzero(count > 2)
    if bad.size:
        p = X[bad[0]]
        raise ValueError(f"contact surface {name}: the node at ({p[0]:.6g}, {p[1]:.6g}) is in "
                         f"{count[bad[0]]} segments: not a chain (a contact surface is one or "
                         "more simple curves)")


def _chain_order(seg: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Node and segment orders that walk each chain from its start (open chains first)."""
    nxt = {int(a): i for i, (a, _) in enumerate(seg)}
    has_pred = np.zeros(n, dtype=bool)
    has_pred[seg[:, 1]] = True
    starts = [int(a) for a, _ in seg if not has_pred[a]]
    visited = np.zeros(n, dtype=bool)
    nodes, segs = [], []
    for s in starts + [int(a) for a, _ in seg]:  # closed chains start anywhere
        if visited[s]:
            continue
        node = s
        while not visited[node]:
            visited[node] = True
            nodes.append(node)
            i = nxt.get(node)
            if i is None:
                break
            segs.append(i)
            node = int(seg[i, 1])
    return np.array(nodes, dtype=np.int64), np.array(segs, dtype=np.int64)
