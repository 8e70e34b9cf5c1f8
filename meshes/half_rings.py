"""B3 two half-rings: two concentric lower half annuli touching along r = 10."""
from __future__ import annotations

import math

import gmsh

from . import _checks, _gmsh


def build(model, *, cell: str = "quadrilateral", fixed_nr: int = 4, fixed_nc: int = 32,
          moving_nr: int = 4, moving_nc: int = 60) -> None:
    """Lower half annuli (theta in [pi, 2*pi]) centred at the origin (docs/benchmarks.md B3).

    "fixed_ring":  R_i = 10, R_e = 12.   "moving_ring": R_i = 8, R_e = 10.
    They touch along r = 10 with separate (duplicated) nodes: the bodies share no node.
    Both are structured (transfinite) polar grids: nodes at uniform angle steps pi/nc on
    every arc (so all arc nodes lie exactly on the circles) and uniform radial steps.

    Parameters (keyword only, defaults in brackets):
        cell:      "quadrilateral" [default] or "triangle" (each grid quad split into 2).
        fixed_nr:  radial elements of the fixed ring [4].
        fixed_nc:  circumferential elements of the fixed ring [32], >= 2.
        moving_nr: radial elements of the moving ring [4].
        moving_nc: circumferential elements of the moving ring [60], >= 2.

    Physical groups (tags in brackets):
        dim 2: "fixed_ring" [1], "moving_ring" [2].
        dim 1: "fixed_inner" [3] (r = 10, master), "fixed_outer" [4] (r = 12),
               "fixed_ends" [5] (both cut ends, y = 0, |x| in [10, 12]),
               "moving_outer" [6] (r = 10, slave), "moving_inner" [7] (r = 8, the hub),
               "moving_ends" [8] (y = 0, |x| in [8, 10]).
    Each arc is made of two gmsh curves (a circle arc must be shorter than pi), cut at the
    grid angle pi + pi*(nc//2)/nc, i.e. at the lowest point (0, -r) when nc is even.
    """
    cells(cell=cell, fixed_nr=fixed_nr, fixed_nc=fixed_nc, moving_nr=moving_nr,
          moving_nc=moving_nc)
    # Options are global to the gmsh session: reset those a previous build may have changed.
    gmsh.option.setNumber("Mesh.ElementOrder", 1)
    gmsh.option.setNumber("Mesh.RecombineAll", 0)
    gmsh.option.setNumber("Mesh.SubdivisionAlgorithm", 0)

    fixed, f_inner, f_outer, f_ends = _half_annulus(model, 10.0, 12.0, fixed_nr, fixed_nc, cell)
    moving, m_inner, m_outer, m_ends = _half_annulus(model, 8.0, 10.0, moving_nr, moving_nc, cell)
    groups = [(2, [fixed], "fixed_ring"), (2, [moving], "moving_ring"),
              (1, f_inner, "fixed_inner"), (1, f_outer, "fixed_outer"), (1, f_ends, "fixed_ends"),
              (1, m_outer, "moving_outer"), (1, m_inner, "moving_inner"),
              (1, m_ends, "moving_ends")]
    _gmsh.name_groups(model, groups)
    _gmsh.generate(model, cell)


def cells(*, cell: str = "quadrilateral", fixed_nr: int = 4, fixed_nc: int = 32,
          moving_nr: int = 4, moving_nc: int = 60) -> int:
    """The number of cells ``build`` makes, after its parameter checks (ValueError)."""
    per_quad = _checks.cell(cell)
    _checks.divisions(fixed_nr=fixed_nr, moving_nr=moving_nr)
    _checks.divisions(2, fixed_nc=fixed_nc, moving_nc=moving_nc)
    return per_quad * (fixed_nr * fixed_nc + moving_nr * moving_nc)


def _half_annulus(model, r_in: float, r_out: float, nr: int, nc: int, cell: str
                  ) -> tuple[int, list[int], list[int], list[int]]:
    """Structured lower half annulus; returns (surface, inner arcs, outer arcs, end lines)."""
    occ = model.occ
    k = nc // 2
    angles = (math.pi, math.pi + math.pi * k / nc, 2.0 * math.pi)
    centre = occ.addPoint(0.0, 0.0, 0.0)
    inner = [occ.addPoint(r_in * math.cos(t), r_in * math.sin(t), 0.0) for t in angles]
    outer = [occ.addPoint(r_out * math.cos(t), r_out * math.sin(t), 0.0) for t in angles]
    inner_arcs = [occ.addCircleArc(inner[0], centre, inner[1]),
                  occ.addCircleArc(inner[1], centre, inner[2])]
    outer_arcs = [occ.addCircleArc(outer[2], centre, outer[1]),
                  occ.addCircleArc(outer[1], centre, outer[0])]
    ends = [occ.addLine(inner[2], outer[2]), occ.addLine(outer[0], inner[0])]
    loop = occ.addCurveLoop([inner_arcs[0], inner_arcs[1], ends[0],
                             outer_arcs[0], outer_arcs[1], ends[1]])
    surface = occ.addPlaneSurface([loop])
    # The centre only defines the arcs; left in the model it would become an orphan node.
    occ.remove([(0, centre)])
    occ.synchronize()

    mesh = model.mesh
    for curve, n in zip(inner_arcs + outer_arcs[::-1] + ends, (k, nc - k, k, nc - k, nr, nr)):
        mesh.setTransfiniteCurve(curve, n + 1)
    mesh.setTransfiniteSurface(surface, "Left", [inner[0], inner[2], outer[2], outer[0]])
    if cell == "quadrilateral":
        mesh.setRecombine(2, surface)
    return surface, inner_arcs, outer_arcs, ends
