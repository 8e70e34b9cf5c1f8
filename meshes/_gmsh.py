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
