"""B5 frictional block on a slab: two structured rectangles with non-matching meshes."""
from __future__ import annotations

import gmsh

from . import _checks, _gmsh

_SIDES = ("bottom", "right", "top", "left")


def build(model, *, cell: str = "quadrilateral", block_nx: int = 10, block_ny: int = 5,
          slab_nx: int = 24, slab_ny: int = 8) -> None:
    """Block [0, 1] x [1, 1.5] resting on slab [-1, 2] x [0, 1] (docs/benchmarks.md B5).

    Both are structured grids. They touch along y = 1, x in [0, 1], with separate
    (duplicated) nodes: the bodies share no node and the default meshes are non-matching
    (block spacing 0.1, slab spacing 0.125).

    Parameters (keyword only, defaults in brackets):
        cell:     "quadrilateral" [default] or "triangle" (each grid quad split into 2).
        block_nx, block_ny: block elements along x and y [10, 5].
        slab_nx, slab_ny:   slab elements along x and y [24, 8].

    Physical groups (tags in brackets):
        dim 2: "block" [1], "slab" [2].
        dim 1: "block_bottom" [3] (y = 1, slave), "block_right" [4] (x = 1),
               "block_top" [5] (y = 1.5), "block_left" [6] (x = 0),
               "slab_bottom" [7] (y = 0), "slab_right" [8] (x = 2),
               "slab_top" [9] (y = 1, master), "slab_left" [10] (x = -1).
    Nodes lie at all four corners of each body.
    """
    cells(cell=cell, block_nx=block_nx, block_ny=block_ny, slab_nx=slab_nx, slab_ny=slab_ny)
    # Options are global to the gmsh session: reset those a previous build may have changed.
    gmsh.option.setNumber("Mesh.ElementOrder", 1)
    gmsh.option.setNumber("Mesh.RecombineAll", 0)
    gmsh.option.setNumber("Mesh.SubdivisionAlgorithm", 0)

    block = _rectangle(model, 0.0, 1.0, 1.0, 0.5, block_nx, block_ny, cell)
    slab = _rectangle(model, -1.0, 0.0, 3.0, 1.0, slab_nx, slab_ny, cell)
    groups = [(2, block[0], "block"), (2, slab[0], "slab")]
    for body, (_, curves) in (("block", block), ("slab", slab)):
        groups += [(1, c, f"{body}_{side}") for c, side in zip(curves, _SIDES)]
    _gmsh.name_groups(model, groups)
    _gmsh.generate(model, cell)


def cells(*, cell: str = "quadrilateral", block_nx: int = 10, block_ny: int = 5,
          slab_nx: int = 24, slab_ny: int = 8) -> int:
    """The number of cells ``build`` makes, after its parameter checks (ValueError)."""
    per_quad = _checks.cell(cell)
    _checks.divisions(block_nx=block_nx, block_ny=block_ny, slab_nx=slab_nx, slab_ny=slab_ny)
    return per_quad * (block_nx * block_ny + slab_nx * slab_ny)


def _rectangle(model, x0: float, y0: float, width: float, height: float,
               nx: int, ny: int, cell: str) -> tuple[int, list[int]]:
    """Structured rectangle with its own points; returns (surface, [bottom, right, top, left])."""
    occ = model.occ
    pts = [occ.addPoint(x, y, 0.0) for x, y in
           [(x0, y0), (x0 + width, y0), (x0 + width, y0 + height), (x0, y0 + height)]]
    curves = [occ.addLine(pts[i], pts[(i + 1) % 4]) for i in range(4)]
    surface = occ.addPlaneSurface([occ.addCurveLoop(curves)])
    occ.synchronize()
    for curve, n in zip(curves, (nx, ny, nx, ny)):
        model.mesh.setTransfiniteCurve(curve, n + 1)
    model.mesh.setTransfiniteSurface(surface, "Left", pts)
    if cell == "quadrilateral":
        model.mesh.setRecombine(2, surface)
    return surface, curves
