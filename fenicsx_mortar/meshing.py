"""gmsh model (a generator from :mod:`fenicsx_mortar.meshes` or a ``.msh`` file) → DOLFINx
mesh + named tags."""
from __future__ import annotations

import importlib
from dataclasses import dataclass

import numpy as np
from mpi4py import MPI

from . import _dolfinx as dx
from .scene import Scene, SceneError


@dataclass
class Domain:
    """The distributed mesh with its physical groups by name."""
    mesh: dx.Mesh
    cell_tags: object
    facet_tags: object
    cell_groups: dict[str, int]
    facet_groups: dict[str, int]

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
    """Fill gmsh.model on this rank; return {dim: {name: tag}}. Raises SceneError."""
    import gmsh
    ms = scene.mesh
    if ms.generator is not None:
        gmsh.model.add(ms.generator)
        try:
            load_generator(ms.generator).build(gmsh.model, cell=ms.cell, **ms.params)
        except (TypeError, ValueError) as e:
            raise SceneError(f"mesh.params for generator {ms.generator!r}: {e}") from None
    else:
        path = scene.mesh_file()
        if not path.is_file():
            raise SceneError(f"mesh.file: {path} does not exist")
        try:
            gmsh.open(str(path))
        except Exception as e:  # gmsh raises bare Exception on unreadable files
            raise SceneError(f"mesh.file: {path} is not a readable gmsh mesh ({e})") from None
        if gmsh.model.getDimension() != 2:
            raise SceneError(f"mesh.file: {path} is a {gmsh.model.getDimension()}D mesh; "
                             "fenicsx_mortar is 2D (plane strain)")
        _, xyz, _ = gmsh.model.mesh.getNodes()
        if xyz.size and np.abs(xyz.reshape(-1, 3)[:, 2]).max() > 0:
            raise SceneError(f"mesh.file: {path} has nodes off the plane z = 0")
    groups: dict[int, dict[str, int]] = {1: {}, 2: {}}
    for dim, tag in gmsh.model.getPhysicalGroups():
        if dim in groups:
            groups[dim][gmsh.model.getPhysicalName(dim, tag) or str(tag)] = tag
    if not groups[2]:
        raise SceneError("mesh: no physical surface groups (bodies need named 2D groups)")
    return groups


def build_domain(scene: Scene, comm: MPI.Comm = MPI.COMM_WORLD) -> Domain:
    """Mesh the scene on rank 0, distribute it, and check every group the scene names."""
    import gmsh
    groups, error = None, None
    if comm.rank == 0:
        gmsh.initialize()
        gmsh.option.setNumber("General.Terminal", 0)
        try:
            groups = _build_model(scene)
        except SceneError as e:
            error = str(e)
    error = comm.bcast(error, root=0)
    if error is not None:
        if comm.rank == 0:
            gmsh.finalize()
        raise SceneError(error)
    groups = comm.bcast(groups, root=0)
    msh, ct, ft = dx.model_to_mesh(gmsh.model, comm, 0)
    if comm.rank == 0:
        gmsh.finalize()
    dom = Domain(msh, ct, ft, groups[2], groups[1])
    _check_groups(scene, dom, comm)
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
