"""A ring squeezed between two plates: a full annulus touching a lower and an upper plate."""
from __future__ import annotations

import math

import gmsh

from . import _checks, _gmsh


def build(model, *, cell: str = "quadrilateral", ring_nr: int = 4, ring_nc: int = 64,
          plate_nx: int = 24, plate_ny: int = 3, r_in: float = 0.6, r_out: float = 1.0,
          plate_width: float = 3.0, plate_thickness: float = 0.3) -> None:
    """The annulus r_in <= r <= r_out centred at the origin, and two plates of
    ``plate_width`` × ``plate_thickness`` centred on the y axis, the lower one below
    y = −r_out, the upper one above y = r_out: each touches the ring at one point, (0, ∓r_out).
    Structured grids: the ring in four quarter patches (``ring_nc`` elements around, a
    multiple of 4, ``ring_nr`` across), the plates ``plate_nx`` × ``plate_ny``.

    Physical groups (tags in brackets):
        dim 2: "ring" [1], "lower_plate" [2], "upper_plate" [3].
        dim 1: "ring_lower" [4] (outer arc, y <= 0), "ring_upper" [5] (outer arc, y >= 0),
               "lower_top" [6], "lower_bottom" [7], "upper_bottom" [8], "upper_top" [9],
               "ring_inner" [10].
    """
    cells(cell=cell, ring_nr=ring_nr, ring_nc=ring_nc, plate_nx=plate_nx, plate_ny=plate_ny,
          r_in=r_in, r_out=r_out, plate_width=plate_width, plate_thickness=plate_thickness)
    gmsh.option.setNumber("Mesh.ElementOrder", 1)
    gmsh.option.setNumber("Mesh.RecombineAll", 0)
    gmsh.option.setNumber("Mesh.SubdivisionAlgorithm", 0)
    occ, mesh = model.occ, model.mesh
    centre = occ.addPoint(0.0, 0.0, 0.0)
    angles = [0.5 * math.pi * q for q in range(4)]
    inner = [occ.addPoint(r_in * math.cos(t), r_in * math.sin(t), 0.0) for t in angles]
    outer = [occ.addPoint(r_out * math.cos(t), r_out * math.sin(t), 0.0) for t in angles]
    radial = [occ.addLine(inner[q], outer[q]) for q in range(4)]
    inner_arcs = [occ.addCircleArc(inner[q], centre, inner[(q + 1) % 4]) for q in range(4)]
    outer_arcs = [occ.addCircleArc(outer[q], centre, outer[(q + 1) % 4]) for q in range(4)]
    quarters = []
    for q in range(4):
        loop = occ.addCurveLoop([inner_arcs[q], radial[(q + 1) % 4], -outer_arcs[q],
                                 -radial[q]])
        quarters.append(occ.addPlaneSurface([loop]))
    lower, lower_edges = _plate(occ, -plate_width / 2, -r_out - plate_thickness,
                                plate_width, plate_thickness)
    upper, upper_edges = _plate(occ, -plate_width / 2, r_out, plate_width, plate_thickness)
    occ.remove([(0, centre)])
    occ.synchronize()
    for c in inner_arcs + outer_arcs:
        mesh.setTransfiniteCurve(c, ring_nc // 4 + 1)
    for c in radial:
        mesh.setTransfiniteCurve(c, ring_nr + 1)
    for q, s in enumerate(quarters):
        mesh.setTransfiniteSurface(s, "Left", [inner[q], inner[(q + 1) % 4],
                                               outer[(q + 1) % 4], outer[q]])
    for s, edges in ((lower, lower_edges), (upper, upper_edges)):
        for k, c in enumerate(edges):
            mesh.setTransfiniteCurve(c, (plate_nx if k % 2 == 0 else plate_ny) + 1)
        mesh.setTransfiniteSurface(s)
    if cell == "quadrilateral":
        for s in (*quarters, lower, upper):
            mesh.setRecombine(2, s)
    _gmsh.name_groups(model, [
        (2, quarters, "ring"), (2, [lower], "lower_plate"), (2, [upper], "upper_plate"),
        (1, outer_arcs[2:], "ring_lower"), (1, outer_arcs[:2], "ring_upper"),
        (1, [lower_edges[2]], "lower_top"), (1, [lower_edges[0]], "lower_bottom"),
        (1, [upper_edges[0]], "upper_bottom"), (1, [upper_edges[2]], "upper_top"),
        (1, inner_arcs, "ring_inner")])
    _gmsh.generate(model, cell)


def _plate(occ, x0: float, y0: float, width: float, height: float):
    """A rectangle; returns (surface, [bottom, right, top, left] edges)."""
    p = [occ.addPoint(x, y, 0.0) for x, y in
         [(x0, y0), (x0 + width, y0), (x0 + width, y0 + height), (x0, y0 + height)]]
    edges = [occ.addLine(p[k], p[(k + 1) % 4]) for k in range(4)]
    return occ.addPlaneSurface([occ.addCurveLoop(edges)]), edges


def cells(*, cell: str = "quadrilateral", ring_nr: int = 4, ring_nc: int = 64,
          plate_nx: int = 24, plate_ny: int = 3, r_in: float = 0.6, r_out: float = 1.0,
          plate_width: float = 3.0, plate_thickness: float = 0.3) -> int:
    """The number of cells ``build`` makes, after its parameter checks (ValueError)."""
    per_quad = _checks.cell(cell)
    _checks.divisions(ring_nr=ring_nr, plate_nx=plate_nx, plate_ny=plate_ny)
    _checks.divisions(4, ring_nc=ring_nc)
    if ring_nc % 4:
        raise ValueError(f"ring_nc must be a multiple of 4, got {ring_nc}")
    _checks.lengths(r_in=r_in, r_out=r_out, plate_width=plate_width,
                    plate_thickness=plate_thickness)
    if not r_in < r_out:
        raise ValueError(f"r_in must be below r_out, got {r_in} and {r_out}")
    return per_quad * (ring_nr * ring_nc + 2 * plate_nx * plate_ny)
