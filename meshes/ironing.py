"""B4 ironing: a "bullet" tool (rectangle on a half-disk) above a substrate block."""
from __future__ import annotations

import math

import gmsh

from . import _checks, _gmsh

_CX, _CY, _R = 1.2, 5.02, 1.0   # half-disk centre and radius: lowest tool point y = 4.02
_H = 1.0                        # height of the tool's rectangle [0.2, 2.2] x [5.02, 6.02]


def build(model, *, cell: str = "quadrilateral", nx: int = 70, ny: int = 10,
          n_arc: int = 18) -> None:
    """Substrate [0, 12] x [0, 4] and tool = rectangle [0.2, 2.2] x [5.02, 6.02] on top of
    the lower half-disk of radius 1 centred at (1.2, 5.02) (docs/benchmarks.md B4; initial gap
    0.02 between the tool's lowest point (1.2, 4.02) and the substrate top y = 4).

    Both bodies are all-quadrilateral structured (transfinite) meshes, or each quad split
    into 2 triangles. The tool is one body made of five conforming four-sided patches: an
    inner rectangle below the centre, three patches between it and the arc (left, bottom,
    right, the arc cut at angles pi + pi*n1/n_arc and 2*pi - pi*n1/n_arc, n1 = n_arc // 4),
    and the upper rectangle. Arc nodes are at uniform angle steps pi/n_arc, exactly on the
    circle. The upper rectangle has n_arc elements across and n_arc // 2 high.

    Parameters (keyword only, defaults in brackets):
        cell:  "quadrilateral" [default] or "triangle".
        nx, ny: substrate elements along x and y [70, 10].
        n_arc: segments on the tool's half-circle [18], >= 4.

    Physical groups (tags in brackets):
        dim 2: "substrate" [1], "tool" [2].
        dim 1: "substrate_bottom" [3] (y = 0), "substrate_right" [4] (x = 12),
               "substrate_top" [5] (y = 4, master), "substrate_left" [6] (x = 0),
               "tool_arc" [7] (the half-circle, slave), "tool_sides" [8]
               (x = 0.2 and x = 2.2, y in [5.02, 6.02]), "tool_top" [9] (y = 6.02).
    The half-disk's flat edge y = 5.02 is interior to the tool (not a boundary).
    """
    cells(cell=cell, nx=nx, ny=ny, n_arc=n_arc)
    # Options are global to the gmsh session: reset those a previous build may have changed.
    gmsh.option.setNumber("Mesh.ElementOrder", 1)
    gmsh.option.setNumber("Mesh.RecombineAll", 0)
    gmsh.option.setNumber("Mesh.SubdivisionAlgorithm", 0)

    occ = model.occ
    divisions: dict[int, int] = {}   # curve -> number of elements, set after synchronize
    patches: list[tuple[int, list[int]]] = []   # (surface, its 4 corner points)

    def line(a: int, b: int, n: int) -> int:
        curve = occ.addLine(a, b)
        divisions[curve] = n
        return curve

    def patch(curves: list[int], corners: list[int]) -> int:
        surface = occ.addPlaneSurface([occ.addCurveLoop(curves)])
        patches.append((surface, corners))
        return surface

    # Substrate.
    s_pts = [occ.addPoint(x, y, 0.0) for x, y in [(0, 0), (12, 0), (12, 4), (0, 4)]]
    s_curves = [line(s_pts[i], s_pts[(i + 1) % 4], n) for i, n in enumerate((nx, ny, nx, ny))]
    substrate = patch(s_curves, s_pts)

    # Tool: angles of the arc cuts; the inner rectangle's corners sit on the same rays at
    # half the radius, so the arc patches have near-right corners and radial sides.
    n1 = n_arc // 4
    n2 = n_arc - 2 * n1
    m = n1                       # radial elements between inner rectangle and arc
    n_up = n_arc // 2
    t1 = math.pi + math.pi * n1 / n_arc
    t2 = 2.0 * math.pi - math.pi * n1 / n_arc
    rho = 0.5 * _R

    def polar(r: float, t: float) -> int:
        return occ.addPoint(_CX + r * math.cos(t), _CY + r * math.sin(t), 0.0)

    centre = occ.addPoint(_CX, _CY, 0.0)
    a0, a1, a2, a3 = (polar(_R, t) for t in (math.pi, t1, t2, 2.0 * math.pi))
    i1, i2 = polar(rho, t1), polar(rho, t2)
    u1 = occ.addPoint(_CX + rho * math.cos(t1), _CY, 0.0)   # on the flat edge above i1
    u2 = occ.addPoint(_CX + rho * math.cos(t2), _CY, 0.0)
    b0 = occ.addPoint(_CX - _R, _CY + _H, 0.0)
    b3 = occ.addPoint(_CX + _R, _CY + _H, 0.0)
    arcs = []
    for a, b, n in ((a0, a1, n1), (a1, a2, n2), (a2, a3, n1)):
        arcs.append(occ.addCircleArc(a, centre, b))
        divisions[arcs[-1]] = n
    a1_i1, a2_i2 = line(a1, i1, m), line(a2, i2, m)
    i1_u1, i2_u2 = line(i1, u1, n1), line(i2, u2, n1)
    i1_i2, u1_u2 = line(i1, i2, n2), line(u1, u2, n2)
    a0_u1, u2_a3 = line(a0, u1, m), line(u2, a3, m)
    sides = [line(a3, b3, n_up), line(b0, a0, n_up)]
    top = line(b3, b0, n_arc)
    tool = [patch([arcs[0], a1_i1, i1_u1, a0_u1], [a0, a1, i1, u1]),
            patch([arcs[1], a2_i2, i1_i2, a1_i1], [a1, a2, i2, i1]),
            patch([arcs[2], u2_a3, i2_u2, a2_i2], [a2, a3, u2, i2]),
            patch([i1_i2, i2_u2, u1_u2, i1_u1], [i1, i2, u2, u1]),
            patch([a0_u1, u1_u2, u2_a3, sides[0], top, sides[1]], [a0, a3, b3, b0])]
    # The centre only defines the arcs; left in the model it would become an orphan node.
    occ.remove([(0, centre)])
    occ.synchronize()

    mesh = model.mesh
    for curve, n in divisions.items():
        mesh.setTransfiniteCurve(curve, n + 1)
    for surface, corners in patches:
        mesh.setTransfiniteSurface(surface, "Left", corners)
        if cell == "quadrilateral":
            mesh.setRecombine(2, surface)

    groups = [(2, [substrate], "substrate"), (2, tool, "tool")]
    groups += [(1, [c], f"substrate_{side}")
               for c, side in zip(s_curves, ("bottom", "right", "top", "left"))]
    groups += [(1, arcs, "tool_arc"), (1, sides, "tool_sides"), (1, [top], "tool_top")]
    _gmsh.name_groups(model, groups)
    _gmsh.generate(model, cell)


def cells(*, cell: str = "quadrilateral", nx: int = 70, ny: int = 10, n_arc: int = 18) -> int:
    """The number of cells ``build`` makes, after its parameter checks (ValueError)."""
    per_quad = _checks.cell(cell)
    _checks.divisions(nx=nx, ny=ny)
    _checks.divisions(4, n_arc=n_arc)
    n1 = n_arc // 4
    n2 = n_arc - 2 * n1
    tool = n1 * (2 * n1 + n2) + n2 * n1 + n_arc * (n_arc // 2)
    return per_quad * (nx * ny + tool)
