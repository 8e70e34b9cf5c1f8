"""The gmsh steps every generator ends with: named physical groups, then first-order cells
of one type."""
from __future__ import annotations

from numbers import Integral
from typing import Iterable, Sequence

#: gmsh element types: 3 = 4-node quadrilateral, 2 = 3-node triangle
ELEMENT_TYPE = {"quadrilateral": 3, "triangle": 2}


def name_groups(model, groups: Iterable[tuple[int, int | Sequence[int], str]],
                start: int = 1) -> None:
    """One physical group per (dim, entity or entities, name), tagged start, start + 1, …"""
    for tag, (dim, entities, name) in enumerate(groups, start=start):
        ids = [int(entities)] if isinstance(entities, Integral) else [int(e) for e in entities]
        model.addPhysicalGroup(dim, ids, tag)
        model.setPhysicalName(dim, tag, name)


def is_all(model, cell: str) -> bool:
    """The 2D mesh is made of ``cell``s only."""
    return list(model.mesh.getElementTypes(2)) == [ELEMENT_TYPE[cell]]


def generate(model, cell: str) -> None:
    """Mesh in 2D and check that every cell is a ``cell`` (RuntimeError otherwise)."""
    model.mesh.generate(2)
    if not is_all(model, cell):
        raise RuntimeError(f"mesh is not all {cell}: {model.mesh.getElementTypes(2)}")


def refine(model, times: int) -> list:
    """Refine the 2D mesh ``times`` times (every cell split into four); return the meshes
    before each refinement, coarsest first, as a geometric multigrid's hierarchy
    (:class:`~fenicsx_mortar.condensation.multigrid.CoarseMesh`: the cells of the
    physical surface groups, tagged with their group's tag, as DOLFINx tags them)."""
    import numpy as np

    from ..condensation.multigrid import CoarseMesh
    levels = []
    for _ in range(times):
        tags, xyz, _ = model.mesh.getNodes()
        index = np.zeros(int(tags.max()) + 1, dtype=np.int64)
        index[tags.astype(np.int64)] = np.arange(len(tags))
        cells, body = [], []
        for dim, tag in model.getPhysicalGroups(2):
            for entity in model.getEntitiesForPhysicalGroup(dim, tag):
                for etype, _, nodes in zip(*model.mesh.getElements(2, entity)):
                    k = model.mesh.getElementProperties(etype)[3]
                    c = index[np.asarray(nodes, dtype=np.int64)].reshape(-1, k)
                    cells.append(c)
                    body.append(np.full(len(c), tag, dtype=np.int32))
        cells = np.vstack(cells)
        used, cells = np.unique(cells, return_inverse=True)
        levels.append(CoarseMesh(xyz.reshape(-1, 3)[used, :2].copy(),
                                 cells.reshape(-1, k).astype(np.int64), np.concatenate(body)))
        model.mesh.refine()
    return levels
