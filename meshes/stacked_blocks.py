"""Two stacked rectangles with independent meshes and an adjustable gap (stability suite).

Used by the hard cases of ``tests/stability`` (docs/stability.md): slave nodes tied to master
nodes, a slave surface overhanging the master's ends, initial penetration, density ratios.
"""
from __future__ import annotations

import gmsh

from . import _checks, _gmsh

_SIDES = ("bottom", "right", "top", "left")


def build(model, *, cell: str = "quadrilateral",
          lower_x0: float = 0.0, lower_width: float = 2.0, lower_height: float = 1.0,
          lower_nx: int = 8, lower_ny: int = 4,
          upper_x0: float = 0.5, upper_width: float = 1.0, upper_height: float = 0.5,
          upper_nx: int = 8, upper_ny: int = 4, gap: float = 0.0) -> None:
    """Lower block [lower_x0, lower_x0 + lower_width] x [0, lower_height] and upper block
    [upper_x0, upper_x0 + upper_width] x [lower_height + gap, lower_height + gap + upper_height].

    Both are structured grids with their own (duplicated) nodes. ``gap`` > 0 leaves an open
    gap, ``gap`` = 0 makes them exactly touch, ``gap`` < 0 overlaps them (initial
    penetration |gap|). The horizontal extents are free, so the upper block may overhang the
    lower one (a slave surface extending beyond the master's ends) or sit inside it.

    Parameters (keyword only, defaults in brackets):
        cell: "quadrilateral" [default] or "triangle" (each grid quad split into 2).
        lower_x0 [0.0], lower_width [2.0] > 0, lower_height [1.0] > 0,
        lower_nx [8], lower_ny [4] >= 1,
        upper_x0 [0.5], upper_width [1.0] > 0, upper_height [0.5] > 0,
        upper_nx [8], upper_ny [4] >= 1, gap [0.0] with gap > -upper_height.

    Physical groups (tags in brackets):
        dim 2: "lower" [1], "upper" [2].
        dim 1: "lower_bottom" [3], "lower_right" [4], "lower_top" [5] (master),
               "lower_left" [6], "upper_bottom" [7] (slave), "upper_right" [8],
               "upper_top" [9], "upper_left" [10].
    Nodes lie at every grid point (corners included); a node falls on the vertical centre
    line of a block when its nx is even.
    """
    cells(cell=cell, lower_x0=lower_x0, lower_width=lower_width, lower_height=lower_height,
          lower_nx=lower_nx, lower_ny=lower_ny, upper_x0=upper_x0, upper_width=upper_width,
          upper_height=upper_height, upper_nx=upper_nx, upper_ny=upper_ny, gap=gap)
    gmsh.option.setNumber("Mesh.ElementOrder", 1)
    gmsh.option.setNumber("Mesh.RecombineAll", 0)
    gmsh.option.setNumber("Mesh.SubdivisionAlgorithm", 0)

    lower = _rectangle(model, lower_x0, 0.0, lower_width, lower_height, lower_nx, lower_ny, cell)
    upper = _rectangle(model, upper_x0, lower_height + gap, upper_width, upper_height,
                       upper_nx, upper_ny, cell)
    groups = [(2, lower[0], "lower"), (2, upper[0], "upper")]
    for body, (_, curves) in (("lower", lower), ("upper", upper)):
        groups += [(1, c, f"{body}_{side}") for c, side in zip(curves, _SIDES)]
    _gmsh.name_groups(model, groups)
    _gmsh.generate(model, cell)


def cells(*, cell: str = "quadrilateral",
          lower_x0: float = 0.0, lower_width: float = 2.0, lower_height: float = 1.0,
          lower_nx: int = 8, lower_ny: int = 4,
          upper_x0: float = 0.5, upper_width: float = 1.0, upper_height: float = 0.5,
          upper_nx: int = 8, upper_ny: int = 4, gap: float = 0.0) -> int:
    """The number of cells ``build`` makes, after its parameter checks (ValueError)."""
    per_quad = _checks.cell(cell)
    _checks.divisions(lower_nx=lower_nx, lower_ny=lower_ny, upper_nx=upper_nx, upper_ny=upper_ny)
    _checks.lengths(lower_width=lower_width, lower_height=lower_height,
                    upper_width=upper_width, upper_height=upper_height)
    _checks.coordinates(lower_x0=lower_x0, upper_x0=upper_x0, gap=gap)
    if not gap > -upper_height:
        raise ValueError(f"gap must be > -upper_height, got {gap!r}")
    return per_quad * (lower_nx * lower_ny + upper_nx * upper_ny)


def _rectangle(model, x0, y0, width, height, nx, ny, cell):
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
