"""Shrink fit: two coaxial quarter rings with a radial interference (curved benchmark)."""
from __future__ import annotations


import gmsh

from . import _checks, _gmsh


def build(model, *, cell: str = "quadrilateral", a: float = 0.5, b: float = 1.0,
          c: float = 1.5, delta: float = 0.01, inner_nr: int = 4, inner_nc: int = 8,
          outer_nr: int = 4, outer_nc: int = 13) -> None:
    """Quarter model (θ ∈ [0, π/2]) of a hub shrunk into a ring, both centred at the origin
    (docs/curved_interface.md, ``benchmarks/curved_interface.py``).

    "inner_ring": a ≤ r ≤ b + delta.   "outer_ring": b ≤ r ≤ c.
    In the reference configuration the two overlap radially by ``delta`` (the interference:
    an initial penetration, resolved by the contact, which pushes them apart); delta < 0 is
    a radial clearance. The bodies share no node. Both are structured (transfinite) polar
    grids: uniform angle steps (π/2)/nc on every arc, so all arc nodes lie exactly on the
    circles (interior nodes too: the transfinite interpolation of a polar sector is the polar
    grid), and uniform radial steps. With inner_nc ≠ outer_nc the contact arcs are
    non-matching; the defaults (8 and 13) share only the end nodes' angles 0 and π/2.

    Parameters (keyword only, defaults in brackets):
        cell:     "quadrilateral" [default] or "triangle" (each grid quad split into 2).
        a:        inner radius of the inner ring [0.5], > 0.
        b:        inner radius of the outer ring, the nominal contact radius [1.0], > a.
        c:        outer radius of the outer ring [1.5], > b.
        delta:    radial interference [0.01]; the inner ring's outer radius is b + delta,
                  with a < b + delta < c.
        inner_nr: radial elements of the inner ring [4], >= 1.
        inner_nc: circumferential elements of the inner ring [8], >= 2.
        outer_nr: radial elements of the outer ring [4], >= 1.
        outer_nc: circumferential elements of the outer ring [13], >= 2.

    Physical groups (tags in brackets):
        dim 2: "inner_ring" [1], "outer_ring" [2].
        dim 1: "inner_contact" [3] (r = b + delta, the inner ring's outer arc: slave),
               "outer_contact" [4] (r = b, the outer ring's inner arc: master),
               "inner_x0" [5] (x = 0, y in [a, b + delta]), "inner_y0" [6] (y = 0),
               "outer_x0" [7] (x = 0, y in [b, c]), "outer_y0" [8] (y = 0),
               "outer_surface" [9] (r = c), "inner_bore" [10] (r = a).
    Nodes at the corners of both sectors: (r, 0) and (0, r) for r = a, b + delta (inner
    ring) and r = b, c (outer ring).
    """
    cells(cell=cell, a=a, b=b, c=c, delta=delta, inner_nr=inner_nr, inner_nc=inner_nc,
          outer_nr=outer_nr, outer_nc=outer_nc)
    # Options are global to the gmsh session: reset those a previous build may have changed.
    gmsh.option.setNumber("Mesh.ElementOrder", 1)
    gmsh.option.setNumber("Mesh.RecombineAll", 0)
    gmsh.option.setNumber("Mesh.SubdivisionAlgorithm", 0)

    inner, i_bore, i_contact, i_y0, i_x0 = _sector(model, a, b + delta, inner_nr, inner_nc, cell)
    outer, o_contact, o_surface, o_y0, o_x0 = _sector(model, b, c, outer_nr, outer_nc, cell)
    groups = [(2, inner, "inner_ring"), (2, outer, "outer_ring"),
              (1, i_contact, "inner_contact"), (1, o_contact, "outer_contact"),
              (1, i_x0, "inner_x0"), (1, i_y0, "inner_y0"),
              (1, o_x0, "outer_x0"), (1, o_y0, "outer_y0"),
              (1, o_surface, "outer_surface"), (1, i_bore, "inner_bore")]
    _gmsh.name_groups(model, groups)
    _gmsh.generate(model, cell)


def cells(*, cell: str = "quadrilateral", a: float = 0.5, b: float = 1.0, c: float = 1.5,
          delta: float = 0.01, inner_nr: int = 4, inner_nc: int = 8, outer_nr: int = 4,
          outer_nc: int = 13) -> int:
    """The number of cells ``build`` makes, after its parameter checks (ValueError)."""
    per_quad = _checks.cell(cell)
    _checks.divisions(inner_nr=inner_nr, outer_nr=outer_nr)
    _checks.divisions(2, inner_nc=inner_nc, outer_nc=outer_nc)
    _checks.lengths(a=a, b=b, c=c)
    _checks.number("delta", delta)
    if not 0 < a < b < c:
        raise ValueError(f"radii must satisfy 0 < a < b < c, got a={a!r}, b={b!r}, c={c!r}")
    if not a < b + delta < c:
        raise ValueError(f"delta must satisfy a < b + delta < c, got delta={delta!r} "
                         f"(a={a!r}, b={b!r}, c={c!r})")
    return per_quad * (inner_nr * inner_nc + outer_nr * outer_nc)


def _sector(model, r_in: float, r_out: float, nr: int, nc: int, cell: str
            ) -> tuple[int, int, int, int, int]:
    """Structured quarter annulus r_in ≤ r ≤ r_out, θ ∈ [0, π/2]; returns (surface, inner
    arc, outer arc, edge y = 0, edge x = 0)."""
    occ = model.occ
    centre = occ.addPoint(0.0, 0.0, 0.0)
    p_in = [occ.addPoint(r_in, 0.0, 0.0), occ.addPoint(0.0, r_in, 0.0)]
    p_out = [occ.addPoint(r_out, 0.0, 0.0), occ.addPoint(0.0, r_out, 0.0)]
    arc_in = occ.addCircleArc(p_in[0], centre, p_in[1])
    arc_out = occ.addCircleArc(p_out[0], centre, p_out[1])
    y0 = occ.addLine(p_in[0], p_out[0])
    x0 = occ.addLine(p_out[1], p_in[1])
    loop = occ.addCurveLoop([y0, arc_out, x0, arc_in])
    surface = occ.addPlaneSurface([loop])
    # The centre only defines the arcs; left in the model it would become an orphan node.
    occ.remove([(0, centre)])
    occ.synchronize()

    mesh = model.mesh
    for curve, n in ((arc_in, nc), (arc_out, nc), (y0, nr), (x0, nr)):
        mesh.setTransfiniteCurve(curve, n + 1)
    mesh.setTransfiniteSurface(surface, "Left", [p_in[0], p_out[0], p_out[1], p_in[1]])
    if cell == "quadrilateral":
        mesh.setRecombine(2, surface)
    return surface, arc_in, arc_out, y0, x0
