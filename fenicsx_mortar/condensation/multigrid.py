"""A geometric multigrid hierarchy for the condensed system (``linear_solver =
"gmres-gmg"``): the prolongations between a mesh and the meshes it was refined from.

Uniform refinement (gmsh's ``refine``: every cell split into four) puts each new node at a
coarse edge's midpoint or, for a quadrilateral, its centre, and keeps the coarse nodes; a
node new on a curved boundary is moved onto the curve. So each fine node has its parent
entity in the coarse mesh, the nearest candidate point of its own body, and the
prolongation interpolates linearly from the parent's vertices (weights 1, 1/2 or 1/4). On
Hertz at 2M dofs this hierarchy reaches about 0.6 decades a GMRES iteration where GAMG's
aggregates reach 0.2–0.3 (docs/condensation.md §6).

Every rank holds the coarse meshes whole (a few hundred thousand nodes at most); the coarse
levels are split among the ranks in contiguous node ranges.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc
from scipy.spatial import cKDTree

from .. import _dolfinx as dx


@dataclass(frozen=True, eq=False)  # (arrays: no elementwise ==, no hash)
class CoarseMesh:
    """One mesh of a refinement hierarchy, coarser than the problem's.

    Args:
        points: (n, 2) node coordinates.
        cells: (m, 3) triangles or (m, 4) quadrilaterals (node indices, gmsh's order:
            around the cell).
        cell_body: (m,) the body of each cell: the cell tag value the problem's mesh
            gives the same body.
    """
    points: np.ndarray
    cells: np.ndarray
    cell_body: np.ndarray

    def node_body(self) -> np.ndarray:
        """The body of each node (-1 for a node of no cell)."""
        body = np.full(len(self.points), -1, dtype=np.int64)
        for k in range(self.cells.shape[1]):
            body[self.cells[:, k]] = self.cell_body
        return body


def _split(n: int, comm: MPI.Comm) -> tuple[int, int]:
    """This rank's contiguous range of n coarse nodes."""
    q, r = divmod(n, comm.size)
    start = comm.rank * q + min(comm.rank, r)
    return start, start + q + (comm.rank < r)


def _candidates(coarse: CoarseMesh, body: int):
    """The points where refinement puts the nodes of ``body``: its vertices, its edges'
    midpoints and (quadrilaterals) its cells' centres, with their parents, weights and
    how far a node may lie from them (a quarter of the edge or cell's shortest edge: a
    node new on a curved boundary is moved onto the curve, by about h²/8R)."""
    cells = coarse.cells[coarse.cell_body == body]
    k = cells.shape[1]
    X = coarse.points
    length = np.linalg.norm(X[np.roll(cells, -1, axis=1)] - X[cells], axis=2)
    edges = np.unique(np.sort(np.stack([cells, np.roll(cells, -1, axis=1)], axis=2)
                              .reshape(-1, 2), axis=1), axis=0)
    verts = np.unique(cells)
    parents = [np.repeat(verts[:, None], 4, axis=1), np.repeat(edges, 2, axis=1)]
    weights = [np.tile([1.0, 0, 0, 0], (len(verts), 1)), np.tile([.5, 0, .5, 0], (len(edges), 1))]
    points = [X[verts], X[edges].mean(axis=1)]
    reach = [np.full(len(verts), 0.25 * length.min()),
             0.25 * np.linalg.norm(X[edges[:, 1]] - X[edges[:, 0]], axis=1)]
    if k == 4:
        parents.append(cells)
        weights.append(np.full(cells.shape, 0.25))
        points.append(X[cells].mean(axis=1))
        reach.append(0.25 * length.min(axis=1))
    return np.vstack(points), np.vstack(parents), np.vstack(weights), np.concatenate(reach)


#: what a hierarchy that does not fit is told to check
HINT = ("coarse_meshes are the meshes before each uniform refinement (every cell into "
        "four), coarsest first, with cell_body the values of cell_tags and a quadrilateral's "
        "nodes in order around it; without such a hierarchy use 'gmres-gamg'")


def prolongation(fine_points: np.ndarray, fine_body: np.ndarray,
                 coarse: CoarseMesh, n_fine: int, comm: MPI.Comm,
                 fixed: np.ndarray | None = None, where: str = "the fine mesh",
                 coarse_name: str = "the coarse mesh") -> PETSc.Mat:
    """The prolongation from ``coarse`` to the mesh refined from it, for 2D displacements
    (two dofs a node, node-major).

    Args:
        fine_points: (n, 2) coordinates of this rank's fine nodes (its contiguous range
            of the global numbering, in order).
        fine_body: (n,) their bodies.
        coarse: The coarse mesh (whole, on every rank).
        n_fine: The global number of fine nodes.
        comm: The communicator.
        fixed: Local fine dofs (2 node + component) whose rows stay zero: Dirichlet dofs.
        where: How the error names the fine mesh.
        coarse_name: How it names ``coarse``.

    Returns:
        The (2 n_fine, 2 n_coarse) AIJ matrix; columns split as :func:`_split`.

    Raises:
        ValueError: The fine mesh is not a uniform refinement of ``coarse``.
    """
    n = len(fine_points)
    parent = np.zeros((n, 4), dtype=np.int64)
    weight = np.zeros((n, 4))
    bodies = np.unique(coarse.cell_body)
    bad = np.setdiff1d(np.concatenate(comm.allgather(np.unique(fine_body))), bodies)
    if len(bad):
        raise ValueError(f"{where} is not a uniform refinement of {coarse_name}: it has "
                         f"bodies {bad.tolist()}, {coarse_name} has "
                         f"{bodies.tolist()}; {HINT}")
    for b in bodies:
        f = np.flatnonzero(fine_body == b)
        cand, par, w, reach = _candidates(coarse, b)
        counts = np.zeros(len(cand), dtype=np.int64)
        far, x, d = False, None, 0.0
        if len(f):
            dist, j = cKDTree(cand).query(fine_points[f])
            parent[f], weight[f] = par[j], w[j]
            counts = np.bincount(j, minlength=len(cand)).astype(np.int64)
            i = int(np.argmax(dist - reach[j]))
            far, x, d = bool(dist[i] > reach[j[i]]), fine_points[f[i]], float(dist[i])
        total = np.zeros_like(counts)
        comm.Allreduce(counts, total, op=MPI.SUM)
        where_far = comm.allgather((x, d) if far else None)
        hit = next((w_ for w_ in where_far if w_ is not None), None)
        if hit is not None:
            (x, y), d = hit
            raise ValueError(f"{where} is not a uniform refinement of {coarse_name}: its "
                             f"node at ({x:.6g}, {y:.6g}) is {d:.3g} from the nearest vertex, "
                             f"edge midpoint or cell centre of body {b}; {HINT}")
        if (total != 1).any():
            raise ValueError(f"{where} is not a uniform refinement of {coarse_name}: "
                             f"{int((total == 0).sum())} of body {b}'s refinement points "
                             f"have no node, {int((total > 1).sum())} have several; {HINT}")
    # rows node-major (x, y), each node's parents in ascending order: CSR without a sort
    order = np.argsort(parent, axis=1)
    parent = np.take_along_axis(parent, order, axis=1)
    weight = np.take_along_axis(weight, order, axis=1)
    cols = (2 * parent[:, None, :] + np.arange(2)[None, :, None]).reshape(2 * n, 4)
    vals = np.broadcast_to(weight[:, None, :], (n, 2, 4)).reshape(2 * n, 4)
    keep = vals != 0.0
    if fixed is not None and len(fixed):
        keep[fixed] = False
    indptr = np.concatenate([[0], np.cumsum(keep.sum(axis=1))])
    cols, vals = cols[keep], vals[keep]
    c0, c1 = _split(len(coarse.points), comm)
    P = PETSc.Mat().createAIJ(((2 * n, 2 * n_fine), (2 * (c1 - c0), 2 * len(coarse.points))),
                              csr=(indptr.astype(PETSc.IntType), cols.astype(PETSc.IntType),
                                   vals), comm=comm)
    P.assemble()
    return P


def prolongations(V, cell_tags, coarse_meshes, fixed_dofs: np.ndarray) -> list[PETSc.Mat]:
    """The prolongations of a hierarchy, finest first: from the last coarse mesh to V's,
    then between the coarse meshes.

    Args:
        V: The displacement space (P1 vector, on the finest mesh).
        cell_tags: Its cell tags: the body of each cell (CoarseMesh.cell_body's values).
        coarse_meshes: The meshes V's mesh was refined from, coarsest first, each a
            uniform refinement of the one before.
        fixed_dofs: Local Dirichlet dofs of V (their rows of the finest prolongation
            stay zero: the coarse correction leaves them alone).

    Returns:
        One matrix per coarse mesh.
    """
    comm = V.mesh.comm
    n_own = dx.owned_dof_count(V) // 2
    coords = dx.dof_coordinates(V)
    points = coords[:n_own, :2]
    body = np.full(len(coords), -1, dtype=np.int64)
    dofs = dx.cell_dofs(V)
    for k in range(dofs.shape[1]):
        body[dofs[cell_tags.indices, k]] = cell_tags.values
    fixed = np.asarray(fixed_dofs, dtype=np.int64)
    fixed = fixed[fixed < 2 * n_own]
    out = []
    fine = (points, body[:n_own], dx.dof_count(V) // 2, fixed, "u's mesh")
    try:
        for level in range(len(coarse_meshes) - 1, -1, -1):
            coarse = coarse_meshes[level]
            x, b, n_fine, fix, where = fine
            out.append(prolongation(x, b, coarse, n_fine, comm, fixed=fix, where=where,
                                    coarse_name=f"coarse_meshes[{level}]"))
            c0, c1 = _split(len(coarse.points), comm)
            fine = (coarse.points[c0:c1], coarse.node_body()[c0:c1], len(coarse.points),
                    None, f"coarse_meshes[{level}]")
    except ValueError:
        for P in out:
            P.destroy()
        raise
    return out


def refine_gmsh(model, times: int) -> list[CoarseMesh]:
    """Refine a gmsh model's 2D mesh ``times`` times (every cell split into four, gmsh's
    ``model.mesh.refine``), keeping the meshes before each refinement: the hierarchy of
    ``coarse_meshes``.

    Args:
        model: The gmsh model (``gmsh.model``), meshed in 2D with first-order cells in
            physical surface groups (the bodies).
        times: How many refinements.

    Returns:
        The meshes before each refinement, coarsest first: the cells of the physical
        surface groups, each tagged with its group's tag (as DOLFINx's gmsh reader tags
        them).

    Raises:
        ValueError: ``times`` not a count, or a mesh this hierarchy cannot describe (no
            physical surface group, cells of second order or of two kinds).
    """
    if isinstance(times, bool) or not isinstance(times, (int, np.integer)) or times < 0:
        raise ValueError(f"times = {times!r}: how many refinements, an integer >= 0")
    levels = []
    for _ in range(times):
        tags, xyz, _ = model.mesh.getNodes()
        index = np.zeros(int(tags.max()) + 1, dtype=np.int64)
        index[tags.astype(np.int64)] = np.arange(len(tags))
        cells, body = [], []
        for dim, tag in model.getPhysicalGroups(2):
            for entity in model.getEntitiesForPhysicalGroup(dim, tag):
                for etype, _, nodes in zip(*model.mesh.getElements(2, entity)):
                    name, _, order, k = model.mesh.getElementProperties(etype)[:4]
                    if order != 1 or k not in (3, 4):
                        raise ValueError(f"refine_gmsh: {name} cells in physical surface "
                                         f"group {tag}: first-order triangles or "
                                         "quadrilaterals only")
                    cells.append(index[np.asarray(nodes, dtype=np.int64)].reshape(-1, k))
                    body.append(np.full(len(cells[-1]), tag, dtype=np.int32))
        if not cells or len({c.shape[1] for c in cells}) > 1:
            raise ValueError("refine_gmsh: the model needs its 2D cells in physical surface "
                             "groups (the bodies), all triangles or all quadrilaterals"
                             + (", not both" if cells else ""))
        used, inverse = np.unique(np.vstack(cells), return_inverse=True)
        levels.append(CoarseMesh(xyz.reshape(-1, 3)[used, :2].copy(),
                                 inverse.reshape(-1, cells[0].shape[1]).astype(np.int64),
                                 np.concatenate(body)))
        model.mesh.refine()
    return levels
