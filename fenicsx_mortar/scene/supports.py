"""The scene's supports on the mesh, checked before anything is solved (collective):

* one value per constrained dof: two entries that prescribe one component of one node (a
  corner shared by two support groups, a point support on a support group) must give it
  the same value at every pseudo-time of the load path, curves and rigid motions included;
  else SceneError naming both entries and the node;
* no rigid motion left free: per connected piece of the mesh, the rigid motions (the two
  translations and turning) the supports do not stop. One that no contact can stop either
  (the piece has no contact surface, or the motion slides along every one of them without
  friction: a disk held at its centre turns under a frictionless contact) is refused by
  name: a singular stiffness, whatever contact does. One that only contact stops (a block
  pressed onto a slab, free along the press) is a warning naming it.

Both work on the nodes (a P1 support holds the nodes of its facets, or the one node of a
point), so ``fenicsx-mortar check`` makes them too.
"""
from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np
from mpi4py import MPI

from .. import _dolfinx as dx
from .model import Scene, SceneError, as_list

if TYPE_CHECKING:
    from .meshing import Domain

_COMPONENTS = ("x", "y")
#: singular values of the support rows (and the contact rows) below this times the root of
#: their number leave a rigid motion free (each row is O(1): a unit vector's component of
#: a motion scaled to the piece's size)
_FREE = 1e-8


def check(scene: Scene, dom: "Domain", comm: MPI.Comm) -> list[str]:
    """Raise SceneError for conflicting values or a rigid motion nothing can hold (module
    docstring); return the warnings (motions only contact holds). Collective: rank 0
    decides on everything gathered."""
    parts = comm.gather(_local(scene, dom), root=0)
    verdict = None
    if comm.rank == 0:
        try:
            verdict = (None, _decide(scene, parts))
        except SceneError as e:
            verdict = (str(e), [])
    error, warnings = comm.bcast(verdict, root=0)
    if error is not None:
        raise SceneError(error)
    return warnings


def point_vertices(dom: "Domain", point, body: str, scene: Scene) -> np.ndarray:
    """The local vertices at ``point`` (within 1e-8 of the mesh size) that belong to a cell
    of ``body`` (collective: the mesh size)."""
    x = dx.node_coordinates(dom.mesh)
    scale = float(np.ptp(x, axis=0).max()) if len(x) else 1.0
    scale = dom.mesh.comm.allreduce(scale, op=MPI.MAX)
    tol = 1e-8 * scale
    p = np.array(point, dtype=float)
    verts = dx.locate_vertices(dom.mesh, lambda X: np.hypot(X[0] - p[0], X[1] - p[1]) < tol)
    group = next(b.group for b in scene.bodies if b.name == body)
    body_cells = dom.cells(group)
    v2c = dx.cells_of_vertices(dom.mesh)
    keep = [v for v in verts if np.isin(v2c.links(v), body_cells).any()]
    return np.array(keep, dtype=np.int32)


def _facet_node_pairs(dom: "Domain", names) -> np.ndarray:
    """(n, 2) local vertices of the facets of curve groups ``names``."""
    f = dom.facets(as_list(names))
    fv = dx.facet_vertices(dom.mesh)
    return np.array([fv.links(i)[:2] for i in f], dtype=np.int64).reshape(-1, 2)


def _local(scene: Scene, dom: "Domain") -> dict:
    """What this rank knows, by input node number: its nodes and their coordinates, its
    owned cells and their groups, each support entry's nodes, each contact's facets."""
    msh = dom.mesh
    geom = dx.vertex_to_geometry_node(msh)
    ids = dx.input_node_numbers(msh).astype(np.int64)
    x = np.array(dx.node_coordinates(msh), dtype=float)
    vid = ids[geom]                                     # vertex -> input number
    entries = []
    for d in scene.dirichlet:
        if d.boundary is not None:
            verts = np.unique(_facet_node_pairs(dom, d.boundary))
        else:
            verts = point_vertices(dom, d.point, d.body, scene)
        entries.append(vid[verts])
    contacts = [vid[_facet_node_pairs(dom, [*as_list(c.slave), *as_list(c.master)])]
                for c in scene.contacts]
    n_own = dx.num_owned_cells(msh)
    tag = np.full(dx.num_cells(msh), -1)
    tag[dom.cell_tags.indices] = dom.cell_tags.values
    return {"ids": ids, "x": x, "cells": ids[dx.cell_nodes(msh)[:n_own]],
            "tags": tag[:n_own], "entries": entries, "contacts": contacts,
            "groups": {t: n for n, t in dom.cell_groups.items()}}


def _decide(scene: Scene, parts: list[dict]) -> list[str]:
    all_ids = np.concatenate([p["ids"] for p in parts])
    uid, first = np.unique(all_ids, return_index=True)
    x = np.concatenate([p["x"] for p in parts])[first]
    size = float(np.ptp(x, axis=0).max()) if len(x) else 1.0
    entries = [np.unique(np.searchsorted(uid, np.concatenate([p["entries"][i] for p in parts])))
               for i in range(len(scene.dirichlet))]
    _check_conflicts(scene, entries, x, size)
    return _check_rigid_motions(scene, parts, uid, x, entries)


# ---------------------------------------------------------------- one value per dof


def _components(d) -> tuple[int, ...]:
    if d.motion is not None:
        return (0, 1)
    return tuple(k for k, c in enumerate(_COMPONENTS) if getattr(d, c) is not None)


def _times(scene: Scene) -> list[float]:
    """Pseudo-times where prescribed values are compared: the load steps' targets (at most
    64 of them, the last included), every curve point on the path, and 16 even steps (a
    rigid motion's turn is not linear between them)."""
    targets = scene.steps.targets()
    end = targets[-1]
    every = max(1, len(targets) // 64)
    times = set(targets[::every]) | {end} | {end * (k + 1) / 16 for k in range(16)}
    for c in scene.curves.values():
        times |= {t for t in c.t if 0 < t <= end}
    return sorted(times)


def _values(scene: Scene, d, comp: int, x: np.ndarray, t: float) -> np.ndarray:
    if d.motion is not None:
        m = d.motion
        st, sr = scene.curve(m.translation_curve)(t), scene.curve(m.rotation_curve)(t)
        return np.asarray(m.displacement((x[:, 0], x[:, 1]), st, sr)[comp], dtype=float)
    return np.full(len(x), getattr(d, _COMPONENTS[comp]) * scene.curve(d.curve)(t))


def _check_conflicts(scene: Scene, entries: list[np.ndarray], x: np.ndarray,
                     size: float) -> None:
    ds = scene.dirichlet
    times = _times(scene)
    for j in range(len(ds)):
        for i in range(j):
            for comp in set(_components(ds[i])) & set(_components(ds[j])):
                common = np.intersect1d(entries[i], entries[j])
                if not common.size:
                    continue
                xc = x[common]
                for t in times:
                    a, b = _values(scene, ds[i], comp, xc, t), _values(scene, ds[j], comp, xc, t)
                    bad = np.abs(a - b) > 1e-9 * np.maximum(np.abs(a), np.abs(b)) + 1e-12 * size
                    if bad.any():
                        k = int(np.argmax(bad))
                        c = _COMPONENTS[comp]
                        raise SceneError(
                            f"dirichlet[{j}].{c}: the node at ({xc[k, 0]:.6g}, {xc[k, 1]:.6g}) "
                            f"also has its {c} prescribed by dirichlet[{i}], with another value "
                            f"({b[k]:.6g} against {a[k]:.6g} at pseudo-time {t:.6g}): one "
                            "value per node and component; make them agree, or keep the node "
                            "out of one of the groups")


# ---------------------------------------------------------------- rigid motions


def _null(A: np.ndarray, n: int, tol: float = _FREE) -> np.ndarray:
    """An orthonormal basis (n, k) of the null space of A (m, n), whose rows are O(1)."""
    if A.size == 0:
        return np.eye(n)
    _, s, vt = np.linalg.svd(A)
    rank = int((s > tol * math.sqrt(len(A))).sum())
    return vt[rank:].T


def _rigid_rows(x: np.ndarray, comp: np.ndarray, centre: np.ndarray, L: float) -> np.ndarray:
    """Rows (m, 3): component ``comp`` of the rigid motions (x translation, y translation,
    turning scaled by L) at points x."""
    rows = np.zeros((len(x), 3))
    rows[comp == 0, 0] = 1.0
    rows[comp == 1, 1] = 1.0
    rows[:, 2] = np.where(comp == 0, -(x[:, 1] - centre[1]), x[:, 0] - centre[0]) / L
    return rows


def _check_rigid_motions(scene: Scene, parts: list[dict], uid: np.ndarray, x: np.ndarray,
                         entries: list[np.ndarray]) -> list[str]:
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components
    cells = np.searchsorted(uid, np.concatenate([p["cells"] for p in parts]))
    tags = np.concatenate([p["tags"] for p in parts])
    n = len(uid)
    rows = np.repeat(cells[:, 0], cells.shape[1] - 1)
    cols = cells[:, 1:].ravel()
    graph = coo_matrix((np.ones(len(rows)), (rows, cols)), shape=(n, n))
    n_pieces, piece = connected_components(graph, directed=False)
    names = {}
    for b in scene.bodies:
        names.setdefault(b.group, b.name)
    # (node, component) each support holds
    held_node, held_comp = [], []
    for d, nodes in zip(scene.dirichlet, entries):
        for comp in _components(d):
            held_node.append(nodes)
            held_comp.append(np.full(len(nodes), comp))
    held_node = np.concatenate(held_node) if held_node else np.zeros(0, dtype=np.int64)
    held_comp = np.concatenate(held_comp) if held_comp else np.zeros(0, dtype=np.int64)
    # contact facets: (pair index, node a, node b), without the copies of several ranks
    facets = []
    for i in range(len(scene.contacts)):
        f = np.concatenate([p["contacts"][i] for p in parts]).reshape(-1, 2)
        f = np.unique(np.sort(np.searchsorted(uid, f), axis=1), axis=0)
        facets.append(f)
    group_of_tag = parts[0]["groups"]
    warnings = []
    for k in range(n_pieces):
        mine = piece == k
        xs = x[mine]
        centre = xs.mean(axis=0)
        L = float(np.ptp(xs, axis=0).max()) or 1.0
        sel = mine[held_node]
        free = _null(_rigid_rows(x[held_node[sel]], held_comp[sel], centre, L), 3)
        if not free.shape[1]:
            continue
        bodies = sorted({names.get(group_of_tag.get(int(t), ""), "?")
                         for t in tags[mine[cells[:, 0]]]})
        who = ("body " if len(bodies) == 1 else "bodies ") + ", ".join(map(repr, bodies))
        contact_rows, pairs = [], []
        for c, f in zip(scene.contacts, facets):
            f = f[mine[f[:, 0]]]
            if not len(f):
                continue
            pairs.append(c.name)
            a, b = x[f[:, 0]], x[f[:, 1]]
            mid, t = 0.5 * (a + b), b - a
            normal = np.column_stack([-t[:, 1], t[:, 0]]) / np.hypot(t[:, 0], t[:, 1])[:, None]
            rx = _rigid_rows(mid, np.zeros(len(mid), dtype=int), centre, L)
            ry = _rigid_rows(mid, np.ones(len(mid), dtype=int), centre, L)
            if c.friction.law != "none" and c.friction.mu > 0:
                contact_rows += [rx, ry]          # friction can hold it along the surface
            else:
                contact_rows.append(normal[:, :1] * rx + normal[:, 1:] * ry)
        if contact_rows:
            M = np.concatenate(contact_rows) @ free
            unheld = free @ _null(M, free.shape[1], 1e-6)
        else:
            unheld = free
        if unheld.shape[1]:
            why = (f"and contact {', '.join(map(repr, pairs))} cannot hold it either (it slides "
                   "along the contact surface, which has no friction)") if pairs else \
                "and no contact surface is on it"
            raise SceneError(f"dirichlet: {who} can move rigidly ({_describe(unheld, centre, L)}): "
                             f"no support holds that motion, {why}: a singular stiffness; "
                             "prescribe x or y at more of its nodes")
        motion = _describe(free, centre, L)
        warnings.append(f"{who}: {motion} {'are' if ' and ' in motion else 'is'} held by no "
                        f"support, only by contact {', '.join(map(repr, pairs))}: before the "
                        "bodies touch, or where they separate, nothing holds "
                        f"{'them' if ' and ' in motion else 'it'} (a singular stiffness)")
    return warnings


def _direction(a: float, b: float) -> str:
    n = math.hypot(a, b)
    a, b = a / n, b / n
    if abs(b) < 1e-9:
        return "x"
    if abs(a) < 1e-9:
        return "y"
    return f"({a:.3g}, {b:.3g})"


def _point(x: float, y: float, L: float) -> str:
    # round-off below 1e-9 of the piece's size is 0: "(0, 1)", not "(5.6e-17, 1)"
    return "(" + ", ".join(f"{v if abs(v) > 1e-9 * L else 0.0:.6g}" for v in (x, y)) + ")"


def _describe(W: np.ndarray, centre: np.ndarray, L: float) -> str:
    """The rigid motions spanned by the columns of W (x translation, y translation,
    turning scaled by L), in words."""
    xc, yc = centre
    k = W.shape[1]
    if k == 3:
        return "translation along x and y and turning"
    if k == 1:
        a, b, c = W[:, 0]
        if abs(c) < 1e-9 * max(abs(a), abs(b)):
            return f"translation along {_direction(a, b)}"
        return f"turning about {_point(xc - b * L / c, yc + a * L / c, L)}"
    c1, c2 = W[2]
    if max(abs(c1), abs(c2)) < 1e-9:
        return "translation along x and y"
    t = c2 * W[:, 0] - c1 * W[:, 1]                  # no turning in it: a translation
    t = t / math.hypot(t[0], t[1])
    w = W[:, 0] if abs(c1) >= abs(c2) else W[:, 1]
    w = w / w[2]
    w = w - np.dot(w[:2], t[:2]) * t                 # the turn whose centre is nearest
    return (f"translation along {_direction(t[0], t[1])} and turning about "
            f"{_point(xc - w[1] * L, yc + w[0] * L, L)}")
