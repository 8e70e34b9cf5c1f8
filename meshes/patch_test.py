"""B1 contact patch test: a small block resting on a larger one, non-matching meshes."""
from __future__ import annotations

import gmsh

from . import _checks, _gmsh


def build(model, *, cell: str = "quadrilateral", lower_nx: int = 16, lower_ny: int = 8,
          upper_nx: int = 20, upper_ny: int = 4) -> None:
    """Lower block [0, 4] x [0, 2] and upper block [1, 3] x [2, 3] (docs/benchmarks.md B1).

    Both blocks are structured grids; they touch along y = 2, x in [1, 3], with separate
    (duplicated) nodes there, so the meshes are non-matching and share no node.

    Parameters (keyword only, defaults in brackets):
        cell:     "quadrilateral" [default] or "triangle" (each grid quad split into 2).
        lower_nx: elements of the lower block along x [16]; a multiple of 4, so that
                  nodes fall at x = 1, 2, 3.
        lower_ny: elements of the lower block along y [8].
        upper_nx: elements of the upper block along x [20]; even, so a node falls at x = 2.
        upper_ny: elements of the upper block along y [4].

    Physical groups (tags in brackets):
        dim 2: "lower" [1], "upper" [2].
        dim 1: "lower_bottom" [3] (y = 0), "lower_right" [4] (x = 4),
               "lower_top_right" [5] (y = 2, x in [3, 4]),
               "lower_top_middle" [6] (y = 2, x in [1, 3]),
               "lower_top_left" [7] (y = 2, x in [0, 1]), "lower_left" [8] (x = 0),
               "upper_bottom" [9] (y = 2, slave), "upper_right" [10] (x = 3),
               "upper_top" [11] (y = 3), "upper_left" [12] (x = 1).
    The lower top edge is split into three NON-overlapping groups because
    dolfinx.io.gmshio (0.5.2) stores one tag per facet: a facet in two physical groups
    keeps only the first one (checked). The master surface is therefore
    lower_top_left + lower_top_middle + lower_top_right (the full top, x in [0, 4]); the
    exposed, pressure-loaded strips are lower_top_left + lower_top_right.

    Support points: mesh nodes lie exactly at (2, 0) on the lower block and (2, 3) on the
    upper block (and at (1, 2), (3, 2) on the lower top).
    """
    cells(cell=cell, lower_nx=lower_nx, lower_ny=lower_ny, upper_nx=upper_nx, upper_ny=upper_ny)
    _set_options()
    occ = model.occ

    # Lower block: six boundary curves, because the top is cut at x = 3 and x = 1.
    lower_pts = [occ.addPoint(x, y, 0.0) for x, y in
                 [(0, 0), (4, 0), (4, 2), (3, 2), (1, 2), (0, 2)]]
    lower_curves = [occ.addLine(lower_pts[i], lower_pts[(i + 1) % 6]) for i in range(6)]
    lower = occ.addPlaneSurface([occ.addCurveLoop(lower_curves)])

    upper_pts = [occ.addPoint(x, y, 0.0) for x, y in [(1, 2), (3, 2), (3, 3), (1, 3)]]
    upper_curves = [occ.addLine(upper_pts[i], upper_pts[(i + 1) % 4]) for i in range(4)]
    upper = occ.addPlaneSurface([occ.addCurveLoop(upper_curves)])
    occ.synchronize()

    mesh = model.mesh
    q = lower_nx // 4
    for curve, n in zip(lower_curves, (lower_nx, lower_ny, q, 2 * q, q, lower_ny)):
        mesh.setTransfiniteCurve(curve, n + 1)
    # Corners make the 6-curve loop a 4-sided transfinite patch (top side = 3 curves).
    mesh.setTransfiniteSurface(lower, "Left", [lower_pts[i] for i in (0, 1, 2, 5)])
    for curve, n in zip(upper_curves, (upper_nx, upper_ny, upper_nx, upper_ny)):
        mesh.setTransfiniteCurve(curve, n + 1)
    mesh.setTransfiniteSurface(upper, "Left", upper_pts)
    if cell == "quadrilateral":
        mesh.setRecombine(2, lower)
        mesh.setRecombine(2, upper)

    groups = [(2, lower, "lower"), (2, upper, "upper")]
    groups += [(1, c, n) for c, n in zip(lower_curves, (
        "lower_bottom", "lower_right", "lower_top_right", "lower_top_middle",
        "lower_top_left", "lower_left"))]
    groups += [(1, c, n) for c, n in zip(upper_curves, (
        "upper_bottom", "upper_right", "upper_top", "upper_left"))]
    _gmsh.name_groups(model, groups)
    _gmsh.generate(model, cell)


def cells(*, cell: str = "quadrilateral", lower_nx: int = 16, lower_ny: int = 8,
          upper_nx: int = 20, upper_ny: int = 4) -> int:
    """The number of cells ``build`` makes, after its parameter checks (ValueError)."""
    per_quad = _checks.cell(cell)
    _checks.divisions(lower_nx=lower_nx, lower_ny=lower_ny, upper_nx=upper_nx, upper_ny=upper_ny)
    if lower_nx % 4:
        raise ValueError(f"lower_nx must be a multiple of 4 (nodes at x = 1, 2, 3), got {lower_nx}")
    if upper_nx % 2:
        raise ValueError(f"upper_nx must be even (node at x = 2), got {upper_nx}")
    return per_quad * (lower_nx * lower_ny + upper_nx * upper_ny)


def _set_options() -> None:
    # Options are global to the gmsh session: reset those a previous build may have changed.
    gmsh.option.setNumber("Mesh.ElementOrder", 1)
    gmsh.option.setNumber("Mesh.RecombineAll", 0)
    gmsh.option.setNumber("Mesh.SubdivisionAlgorithm", 0)
