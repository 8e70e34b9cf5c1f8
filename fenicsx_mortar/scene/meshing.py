"""gmsh model (a generator from :mod:`fenicsx_mortar.meshes` or a ``.msh`` file) → DOLFINx
mesh + named tags."""
from __future__ import annotations

import importlib
from dataclasses import dataclass, field

import numpy as np
from mpi4py import MPI

from .. import _dolfinx as dx
from ..io import mshfile
from . import supports
from .parallel import wait_for_all
from .model import LIMITS, Scene, SceneError, as_list


@dataclass
class Domain:
    """The distributed mesh with its physical groups by name; ``warnings``: what the checks
    of the scene on it noticed (e.g. a body that only contact holds), for the run's log."""
    mesh: dx.Mesh
    cell_tags: object
    facet_tags: object
    cell_groups: dict[str, int]
    facet_groups: dict[str, int]
    warnings: list[str] = field(default_factory=list)
    #: the meshes this one was refined from, coarsest first (a generator's ``refine``)
    coarse_meshes: list = field(default_factory=list)

    def facets(self, names: str | list[str]) -> np.ndarray:
        """Local facet indices of one or more named curve groups."""
        names = [names] if isinstance(names, str) else names
        ids = [self.facet_groups[n] for n in names]
        return np.sort(self.facet_tags.indices[np.isin(self.facet_tags.values, ids)])

    def cells(self, name: str) -> np.ndarray:
        return self.cell_tags.indices[self.cell_tags.values == self.cell_groups[name]]


def load_generator(name: str):
    """The generator module ``fenicsx_mortar.meshes.<name>``."""
    return importlib.import_module(f"fenicsx_mortar.meshes.{name}")


def _build_model(scene: Scene):
    """Fill gmsh.model on this rank; return {dim: {name: tag}} and the coarse meshes of a
    refined generator's mesh. Raises SceneError."""
    import gmsh
    ms = scene.mesh
    coarse: list = []
    if ms.generator is not None:
        gmsh.model.add(ms.generator)
        try:
            coarse = load_generator(ms.generator).build(
                gmsh.model, cell=ms.cell or "quadrilateral", **ms.params) or []
        except (TypeError, ValueError) as e:
            raise SceneError(f"mesh.params for generator {ms.generator!r}: {e}") from None
        except Exception as e:  # gmsh raises bare Exception ("Could not create line")
            raise SceneError(f"mesh.params for generator {ms.generator!r}: gmsh failed: "
                             f"{e}") from None
    else:
        path = scene.mesh_file()
        try:
            data = mshfile.read(path)
        except mshfile.MeshFileError as e:
            raise SceneError(str(e)) from None
        _check_names(data, path)
        with mshfile.open_for_gmsh(data) as name:
            try:
                gmsh.open(name)
            except Exception as e:  # gmsh raises bare Exception on unreadable files
                raise SceneError(f"mesh.file: {path} is not a readable gmsh mesh "
                                 f"({str(e).replace(name, path.name)})") from None
        del data
        _renumber_nodes(gmsh.model)
        if gmsh.model.getDimension() == 3:
            raise SceneError(f"mesh.file: {path} is a {gmsh.model.getDimension()}D mesh; "
                             "fenicsx_mortar is 2D (plane strain)")
        _, xyz, _ = gmsh.model.mesh.getNodes()
        if xyz.size and np.abs(xyz.reshape(-1, 3)[:, 2]).max() > 0:
            raise SceneError(f"mesh.file: {path} has nodes off the plane z = 0")
        _check_cells(gmsh.model, f"mesh.file: {path}")
    groups: dict[int, dict[str, int]] = {1: {}, 2: {}}
    for dim, tag in gmsh.model.getPhysicalGroups():
        if dim in groups:
            groups[dim][gmsh.model.getPhysicalName(dim, tag) or str(tag)] = tag
    if not groups[2]:
        raise SceneError("mesh: no physical surface groups (bodies need named 2D groups)")
    if ms.generator is None:
        _warn_nameless(scene, groups)
    return groups, coarse


def _warn_nameless(scene: Scene, groups: dict[int, dict[str, int]]) -> None:
    """A physical group without a name among named ones that the scene does not use: gmsh
    drops a name given to two groups (setPhysicalName), and the group left nameless may be
    a part of the boundary the scene means by that name."""
    import warnings

    import gmsh
    used = set().union(*scene.groups_used())
    for dim, kind in ((1, "curve"), (2, "surface")):
        has_name = {n: bool(gmsh.model.getPhysicalName(dim, t)) for n, t in groups[dim].items()}
        nameless = [n for n, named in has_name.items() if not named and n not in used]
        if nameless and any(has_name.values()):
            warnings.warn(f"mesh.file: physical {kind} group(s) {', '.join(nameless)} have no "
                          "name while the others have one (gmsh keeps a name given to two "
                          "groups on one of them only); the scene does not use them",
                          stacklevel=2)


def _check_names(data: bytes, path) -> None:
    """No physical name on two curve or two surface groups: gmsh keeps it on one and leaves
    the others nameless, so a scene naming it would get part of the group (a support on half
    its boundary, exit 0). Reads the $PhysicalNames section, which is text in every format
    and comes before the nodes (the scan stops at the first other section)."""
    import re
    header = {b"$MeshFormat", b"$EndMeshFormat", b"$PhysicalNames", b"$Comments",
              b"$EndComments"}
    seen: dict[tuple[int, bytes], int] = {}
    inside = False
    start = 0
    while start < len(data):
        end = data.find(b"\n", start, start + 4096)
        end = min(len(data), start + 4096) if end < 0 else end + 1
        line, start = data[start:end].strip(), end
        if line == b"$EndPhysicalNames":
            return
        if line.startswith(b"$") and line not in header:
            return
        if line == b"$PhysicalNames":
            inside = True
            continue
        m = re.fullmatch(rb'(\d+)\s+(\d+)\s+"(.*)"', line) if inside else None
        if m is None or int(m[1]) not in (1, 2):
            continue
        key, tag = (int(m[1]), m[3]), int(m[2])
        if seen.setdefault(key, tag) != tag:
            name = key[1].decode("utf-8", "replace")
            kind = "curve" if key[0] == 1 else "surface"
            raise SceneError(
                f"mesh.file: {path}: the physical name {name!r} is on two {kind} "
                f"groups (tags {seen[key]} and {tag}): gmsh keeps it on one only, "
                "and a scene naming it would get part of what it means; merge "
                "them into one group or rename one")


#: gmsh element types of the linear cells DOLFINx 0.5 reads here: triangle 3, quadrangle 4
_LINEAR = {2: "triangle", 3: "quadrilateral"}


def _check_cells(model, where: str) -> None:
    """What ``model_to_mesh`` cannot take, found in the gmsh model first (DOLFINx would
    segfault on mixed cell types, read higher-order cells as another element, or count a
    cell twice if it is in two physical groups): one linear cell type, some 2D cells and
    at most LIMITS["cells"] of them, every surface in at most one physical group, no cell
    of zero area."""
    types = [int(t) for t in model.mesh.getElementTypes(2)]
    if not types:
        raise SceneError(f"{where} has no 2D cells")
    names = [model.mesh.getElementProperties(t)[0] for t in types]
    if len(types) > 1:
        raise SceneError(f"{where} mixes cell types ({', '.join(names)}); one type only, "
                         "linear triangles or quadrilaterals")
    if types[0] not in _LINEAR:
        raise SceneError(f"{where} has {names[0]} cells; fenicsx_mortar takes linear "
                         "triangles or quadrilaterals (3 or 4 nodes)")
    _, cells = model.mesh.getElementsByType(types[0])
    n_nodes = 3 if types[0] == 2 else 4
    if len(cells) // n_nodes > LIMITS["cells"]:
        raise SceneError(f"{where} has {len(cells) // n_nodes:,} cells, more than the limit "
                         f"of {LIMITS['cells']:,}")
    owner: dict[int, str] = {}
    for dim, tag in model.getPhysicalGroups(2):
        name = model.getPhysicalName(dim, tag) or str(tag)
        for entity in model.getEntitiesForPhysicalGroup(dim, tag):
            if entity in owner:
                raise SceneError(f"{where}: surface {entity} is in two physical surface groups "
                                 f"({owner[entity]!r} and {name!r}): its cells would count "
                                 "twice")
            owner[entity] = name
    loose = [e for _, e in model.getEntities(2) if e not in owner]
    n_loose = sum(len(t) for e in loose for t in model.mesh.getElements(2, e)[1])
    if n_loose:
        first = next(e for e in loose if any(len(t) for t in model.mesh.getElements(2, e)[1]))
        nodes = model.mesh.getElements(2, first)[2][0][:3]
        c = np.mean([model.mesh.getNode(int(n))[0][:2] for n in nodes], axis=0)
        raise SceneError(f"{where}: {n_loose} cell(s) in no physical surface group (the first "
                         f"near ({c[0]:.6g}, {c[1]:.6g}), surface {first}): every cell must "
                         "belong to a body's group; add them to one, or remove them (gmsh's "
                         "Mesh.SaveAll writes cells outside the groups)")
    cells = cells.reshape(-1, n_nodes).astype(np.int64)
    x = _node_coordinates(model)
    _check_areas(x, cells, where)
    _check_duplicates(x, cells, where)
    _check_curves(model, x, cells, where)


def _renumber_nodes(model) -> None:
    """Node tags 1..N, as DOLFINx's gmsh reader takes them (it asserts so, and the checks
    here index by tag): a valid file may number its nodes from anywhere (1e9 gave "Unable
    to allocate 14.9 GiB"). Meshes numbered 1..N already are left as they are."""
    tags = model.mesh.getNodes()[0]
    if len(tags) and not (int(tags.min()) == 1 and int(tags.max()) == len(tags)):
        model.mesh.renumberNodes()


def _node_coordinates(model) -> np.ndarray:
    """(max node tag + 1, 2): the nodes' x, y by gmsh node tag (NaN where no node)."""
    tags, xyz, _ = model.mesh.getNodes()
    x = np.full((int(tags.max()) + 1, 2), np.nan)
    x[tags.astype(np.int64)] = xyz.reshape(-1, 3)[:, :2]
    return x


def _check_duplicates(x: np.ndarray, cells: np.ndarray, where: str) -> None:
    """No two cells on the same nodes: DOLFINx 0.5 builds a topology with a facet shared
    by four cells and PETSc then segfaults in the assembly (and the process hangs)."""
    key = np.sort(cells, axis=1)
    _, first, count = np.unique(key, axis=0, return_index=True, return_counts=True)
    twice = first[count > 1]
    if twice.size:
        c = x[cells[twice[0]]].mean(axis=0)
        raise SceneError(f"{where}: {twice.size} cell(s) listed more than once, on the same "
                         f"nodes (the first at ({c[0]:.6g}, {c[1]:.6g}))")


def _check_curves(model, x: np.ndarray, cells: np.ndarray, where: str) -> None:
    """Every segment of a physical curve group is an edge of a 2D cell (DOLFINx 0.5
    crashes, free(): invalid pointer in distribute_entity_data, on a curve off the cells),
    and in one physical curve group only (DOLFINx keeps one tag per facet: the other group
    would silently lose it, a contact surface or a support shrunk)."""
    a, b = cells, np.roll(cells, -1, axis=1)
    lo, hi = np.minimum(a, b).ravel(), np.maximum(a, b).ravel()
    n = len(x)
    edges = np.unique(lo * n + hi)
    names, keys, groups = [], [], []
    for dim, tag in model.getPhysicalGroups(1):
        name = model.getPhysicalName(dim, tag) or str(tag)
        names.append(name)
        for entity in model.getEntitiesForPhysicalGroup(dim, tag):
            for etype, _, nodes in zip(*model.mesh.getElements(1, entity)):
                if etype != 1:   # DOLFINx drops other line types: the group came out empty
                    raise SceneError(
                        f"{where}: physical curve {name!r} has "
                        f"{model.mesh.getElementProperties(etype)[0]} segments; boundary "
                        "groups must be linear 2-node lines, like the cells")
                k = model.mesh.getElementProperties(etype)[3]
                seg = np.asarray(nodes, dtype=np.int64).reshape(-1, k)[:, :2]
                key = seg.min(axis=1) * n + seg.max(axis=1)
                off = ~np.isin(key, edges)
                if off.any():
                    p0, p1 = x[seg[np.flatnonzero(off)[0]]]
                    raise SceneError(
                        f"{where}: physical curve {name!r} has {int(off.sum())} segment(s) "
                        f"that are no cell's edge (the first from ({p0[0]:.6g}, "
                        f"{p0[1]:.6g}) to ({p1[0]:.6g}, {p1[1]:.6g})): a boundary group "
                        "must lie on the cells of the bodies")
                keys.append(key)
                groups.append(np.full(len(key), len(names) - 1))
    if not keys:
        return
    # (segment, group) pairs without repeats: a segment listed twice by one group is fine
    pairs = np.unique(np.column_stack([np.concatenate(keys), np.concatenate(groups)]), axis=0)
    shared = np.flatnonzero(pairs[1:, 0] == pairs[:-1, 0])
    if shared.size:
        key, (g0, g1) = int(pairs[shared[0], 0]), pairs[shared[0]:shared[0] + 2, 1]
        p0, p1 = x[key // n], x[key % n]
        raise SceneError(
            f"{where}: the segment from ({p0[0]:.6g}, {p0[1]:.6g}) to ({p1[0]:.6g}, "
            f"{p1[1]:.6g}) is in two physical curve groups, {names[g0]!r} and {names[g1]!r}: "
            "a facet keeps one tag, so one group would silently lose it; make the "
            "groups disjoint and list several in a scene key instead")


def _check_areas(x: np.ndarray, cells: np.ndarray, where: str) -> None:
    """No cell of zero area, and no folded quadrilateral: its bilinear map is one-to-one only
    if the corners turn the same way (J is affine in each reference coordinate, so its sign
    at the corners is the test); a reentrant corner gives J < 0 there while the area is
    still positive (the step guard would refuse every state, the first one included)."""
    p = x[cells]                                         # (n, k, 2) corners in order
    q = np.roll(p, -1, axis=1)
    signed = 0.5 * np.sum(p[..., 0] * q[..., 1] - q[..., 0] * p[..., 1], axis=1)
    scale = float(np.ptp(p.reshape(-1, 2), axis=0).max()) ** 2
    bad = np.flatnonzero(np.abs(signed) <= 1e-14 * scale)
    if bad.size:
        c = p[bad[0]].mean(axis=0)
        raise SceneError(f"{where}: {bad.size} cell(s) of zero area (the first at "
                         f"({c[0]:.6g}, {c[1]:.6g}))")
    e_next, e_prev = q - p, np.roll(p, 1, axis=1) - p
    turn = np.sign(signed)[:, None] * (e_next[..., 0] * e_prev[..., 1]
                                       - e_next[..., 1] * e_prev[..., 0])
    # a straight corner (180°, J = 0 there only) is accepted: some generators make them
    folded = np.flatnonzero((turn < -1e-12 * scale).any(axis=1))
    if folded.size:
        cell = folded[0]
        corner = p[cell, int(np.argmin(turn[cell]))]
        raise SceneError(f"{where}: {folded.size} folded cell(s): a quadrilateral whose corner "
                         f"at ({corner[0]:.6g}, {corner[1]:.6g}) turns the other way (not "
                         "convex): its map to the reference square is not one-to-one")


def _gmsh_initialize(gmsh) -> None:
    """gmsh.initialize keeping our SIGINT, SIGTERM and SIGPIPE handlers: gmsh >= 4.11 resets
    SIGINT to the default unless ``interruptible=False``, gmsh 4.15 resets SIGTERM and SIGPIPE
    regardless (a signal while meshing would kill the process without a word; a closed
    stdout, ``| head``, killed the run at its next log line)."""
    import inspect
    import signal
    import threading
    kept = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM, signal.SIGPIPE)}
    # no ~/.gmshrc or ~/.gmsh-options: they are scripts too, and not the scene's
    if "interruptible" in inspect.signature(gmsh.initialize).parameters:
        gmsh.initialize(readConfigFiles=False, interruptible=False)
    else:
        gmsh.initialize(readConfigFiles=False)
    if threading.current_thread() is threading.main_thread():
        # Python still lists its handler after a C-level reset: install it again
        for s, handler in kept.items():
            if handler is not None:
                signal.signal(s, handler)


def build_domain(scene: Scene, comm: MPI.Comm = MPI.COMM_WORLD) -> Domain:
    """Mesh the scene on rank 0, distribute it, and check every group the scene names."""
    import gmsh
    groups, coarse, error = None, None, None
    if comm.rank == 0:
        _gmsh_initialize(gmsh)
        gmsh.option.setNumber("General.Terminal", 0)
        try:
            groups, coarse = _build_model(scene)
        except SceneError as e:
            error = str(e)
        except Exception as e:  # whatever gmsh raises: every rank must hear of it
            error = f"mesh: gmsh failed: {e}"
    wait_for_all(comm)   # the other ranks wait for gmsh here, still answering signals
    error = comm.bcast(error, root=0)
    if error is not None:
        if comm.rank == 0:
            gmsh.finalize()
        raise SceneError(error)
    groups, coarse = comm.bcast((groups, coarse), root=0)
    msh, ct, ft = dx.model_to_mesh(gmsh.model, comm, 0)
    if comm.rank == 0:
        gmsh.finalize()
    dom = Domain(msh, ct, ft, groups[2], groups[1], coarse_meshes=coarse)
    _check_groups(scene, dom, comm)
    dom.warnings = supports.check(scene, dom, comm)
    return dom


def _check_groups(scene: Scene, dom: Domain, comm: MPI.Comm) -> None:
    cells, facets = scene.groups_used()
    for name in sorted(cells):
        if name not in dom.cell_groups:
            raise SceneError(f"bodies: physical surface group {name!r} is not in the mesh "
                             f"(it has: {', '.join(sorted(dom.cell_groups))})")
        if comm.allreduce(len(dom.cells(name)), op=MPI.SUM) == 0:
            raise SceneError(f"bodies: physical surface group {name!r} has no cells")
    for name in sorted(facets):
        if name not in dom.facet_groups:
            raise SceneError(f"physical curve group {name!r} is not in the mesh "
                             f"(it has: {', '.join(sorted(dom.facet_groups)) or 'none'})")
        if comm.allreduce(len(dom.facets(name)), op=MPI.SUM) == 0:
            raise SceneError(f"physical curve group {name!r} has no facets in the mesh")
    _check_loads_on_boundary(scene, dom, comm)
    for name in sorted(set(dom.cell_groups) - cells):
        raise SceneError(f"mesh: physical surface group {name!r} is no body's region (its "
                         "cells would have no material: a singular stiffness); add a body "
                         "on it or remove it from the mesh")


def _check_loads_on_boundary(scene: Scene, dom: Domain, comm: MPI.Comm) -> None:
    """Pressures and tractions act on exterior facets (``ds``): on a curve group inside a
    body they would be dropped without a word. Contact surfaces too: a master inside a
    body lets the other body overlap it with zero contact force."""
    keys: dict[str, str] = {}
    for kind, items in (("pressures", scene.pressures), ("tractions", scene.tractions)):
        for i, item in enumerate(items):
            for name in as_list(item.boundary):
                keys.setdefault(name, f"{kind}[{i}].boundary")
    for i, c in enumerate(scene.contacts):
        for side in ("slave", "master"):
            for name in as_list(getattr(c, side)):
                keys.setdefault(name, f"contacts[{i}].{side}")
    if not keys:
        return
    outer = dx.exterior_facets(dom.mesh)
    owned = dx.num_owned_facets(dom.mesh)
    for name, key in keys.items():
        f = dom.facets(name)
        inner = f[(f < owned) & ~np.isin(f, outer)]
        first = dx.midpoints(dom.mesh, 1, inner[:1])[0, :2].tolist() if inner.size else None
        counts = comm.allgather((inner.size, first))
        n = sum(c for c, _ in counts)
        if n:
            x, y = next(p for c, p in counts if c)
            what = ("a contact surface must be on a body's boundary (the other body would "
                    "pass through these unopposed)") if key.startswith("contacts") else \
                "a load acts on a body's boundary only, and these would be ignored"
            raise SceneError(f"{key}: {n} facet(s) of physical curve group {name!r} lie inside "
                             f"the mesh, between two cells (the first at ({x:.6g}, {y:.6g})); "
                             f"{what}")
