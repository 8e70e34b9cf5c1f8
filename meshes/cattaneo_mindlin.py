"""Cattaneo–Mindlin partial slip: two half-disks of one radius touching at (0, 0), refined
around the contact point, each with its own element size (non-matching surfaces)."""
from __future__ import annotations

import math

import gmsh

from . import _checks, _gmsh


def build(model, *, cell: str = "quadrilateral", h_contact: float = 0.0034,
          master_ratio: float = 1.37, h_far: float = 0.1, R: float = 1.0,
          refine_radius: float = 0.06, grade_to: float = 0.6) -> None:
    """Half-disk "upper" (lower half of the circle of radius R centred at (0, R), flat edge
    y = R) pressed on its mirror image "lower" (upper half of the circle centred at
    (0, −R), flat edge y = −R): two cylinders of one radius in line contact at (0, 0), the
    set-up of Johnson's Contact Mechanics §7.1 (R* = R/2). The mirror symmetry makes the
    frictional press free of tangential traction, which a cylinder on a block is not (there
    the bodies' different far fields leave a traction ∝ a/L, docs/friction.md).

    Unstructured meshes driven by size fields: element size h_contact in "upper" and
    master_ratio·h_contact in "lower" within distance refine_radius of (0, 0), growing
    linearly to h_far at distance grade_to. Quadrilaterals as in :mod:`.hertz` (Blossom
    full-quad recombination).

    Parameters (keyword only, defaults in brackets):
        cell:          "quadrilateral" [default] or "triangle".
        h_contact:     element size of "upper" near the contact point [0.0034], > 0.
        master_ratio:  the element size of "lower" there over h_contact [1.37], in
                       [0.25, 4]: not 1, so that the two arcs' nodes do not face each other.
        h_far:         element size away from it [0.1], >= the contact sizes, <= R/4.
        R:             radius [1.0], in [1e-3, 1e3].
        refine_radius: radius of the uniformly refined zone around (0, 0) [0.06], >= 0.
        grade_to:      distance from (0, 0) where the size reaches h_far [0.6],
                       > refine_radius.

    Physical groups (tags in brackets):
        dim 2: "upper" [1], "lower" [2].
        dim 1: "upper_arc" [3] (two quarter arcs cut at (0, 0)), "upper_top" [4] (y = R, cut
               at x = 0), "lower_arc" [5], "lower_bottom" [6] (y = −R, cut at x = 0).

    Mesh nodes lie exactly at (0, R), (0, 0) on both arcs (one node each) and (0, −R).
    """
    cells(cell=cell, h_contact=h_contact, master_ratio=master_ratio, h_far=h_far, R=R,
          refine_radius=refine_radius, grade_to=grade_to)
    _set_options()
    occ = model.occ
    bodies, arcs, flats = [], [], []
    for side in (1.0, -1.0):        # upper, lower
        c = side * R
        left, centre, right = (occ.addPoint(x, c, 0.0) for x in (-R, 0.0, R))
        tip = occ.addPoint(0.0, 0.0, 0.0)
        flat = [occ.addLine(left, centre), occ.addLine(centre, right)]
        arc = [occ.addCircleArc(right, centre, tip), occ.addCircleArc(tip, centre, left)]
        bodies.append(occ.addPlaneSurface([occ.addCurveLoop(flat + arc)]))
        arcs.append((arc, tip))
        flats.append(flat)
    occ.synchronize()

    field = model.mesh.field
    sizes = []
    for body, (_, tip), h in zip(bodies, arcs, (h_contact, master_ratio * h_contact)):
        distance = field.add("Distance")
        field.setNumbers(distance, "PointsList", [tip])
        threshold = field.add("Threshold")
        field.setNumber(threshold, "InField", distance)
        field.setNumber(threshold, "SizeMin", h)
        field.setNumber(threshold, "SizeMax", h_far)
        field.setNumber(threshold, "DistMin", refine_radius)
        field.setNumber(threshold, "DistMax", grade_to)
        restrict = field.add("Restrict")
        field.setNumber(restrict, "InField", threshold)
        field.setNumbers(restrict, "SurfacesList", [body])
        field.setNumbers(restrict, "CurvesList", arcs[bodies.index(body)][0]
                         + flats[bodies.index(body)])
        sizes.append(restrict)
    both = field.add("Min")
    field.setNumbers(both, "FieldsList", sizes)
    field.setAsBackgroundMesh(both)
    if cell == "quadrilateral":
        for body in bodies:
            model.mesh.setRecombine(2, body)

    groups = [(2, [bodies[0]], "upper"), (2, [bodies[1]], "lower"),
              (1, arcs[0][0], "upper_arc"), (1, flats[0], "upper_top"),
              (1, arcs[1][0], "lower_arc"), (1, flats[1], "lower_bottom")]
    _gmsh.name_groups(model, groups)
    _gmsh.generate(model, cell)


def cells(*, cell: str = "quadrilateral", h_contact: float = 0.0034,
          master_ratio: float = 1.37, h_far: float = 0.1, R: float = 1.0,
          refine_radius: float = 0.06, grade_to: float = 0.6) -> int:
    """About the number of cells ``build`` makes (an estimate from the size fields), after
    its parameter checks (ValueError)."""
    per_area = 1.15 * _checks.cell(cell)
    for name, value in (("h_contact", h_contact), ("master_ratio", master_ratio),
                        ("h_far", h_far), ("R", R), ("refine_radius", refine_radius),
                        ("grade_to", grade_to)):
        _checks.number(name, value)
    _checks.lengths(h_contact=h_contact, h_far=h_far)
    if not 0.25 <= master_ratio <= 4.0:
        raise ValueError(f"master_ratio must lie in [0.25, 4], got {master_ratio!r}")
    if not 1e-3 <= R <= 1e3:
        raise ValueError(f"R must lie in [1e-3, 1e3], got {R!r}")
    h_lower = master_ratio * h_contact
    if not h_far >= max(h_contact, h_lower):
        raise ValueError(f"h_far must be >= the contact sizes {h_contact!r} and "
                         f"{h_lower!r} (master_ratio * h_contact), got {h_far!r}")
    if not h_far <= R / 4:
        raise ValueError(f"h_far must be <= R/4 = {R / 4:g} (four elements across the "
                         f"bodies), got {h_far!r}")
    if not 0 <= refine_radius < grade_to <= 1e3:
        raise ValueError(f"need 0 <= refine_radius < grade_to <= 1e3, got "
                         f"refine_radius={refine_radius!r}, grade_to={grade_to!r}")
    area = 0.5 * math.pi * R * R            # each body
    total = 0.0
    for hc in (h_contact, h_lower):
        # half of the refined disc and of the grading ring lie in each body
        r0, r1, hf = min(refine_radius, R), min(grade_to, R), h_far
        fine = 0.5 * math.pi * r0 * r0 / hc ** 2
        if hf > hc and r1 > r0:
            k = (hf - hc) / (r1 - r0)
            ring = math.pi / k * ((r0 - hc / k) * (1.0 / hc - 1.0 / hf)
                                  + math.log(hf / hc) / k)
        else:
            ring = 0.5 * math.pi * (r1 * r1 - r0 * r0) / hc ** 2
        total += fine + ring + area / hf ** 2
    return int(per_area * total)


def _set_options() -> None:
    # global to the gmsh session: set every one the size fields and the recombination use
    opt = gmsh.option.setNumber
    opt("Mesh.ElementOrder", 1)
    opt("Mesh.RecombineAll", 0)
    opt("Mesh.SubdivisionAlgorithm", 0)
    opt("Mesh.MeshSizeExtendFromBoundary", 0)
    opt("Mesh.MeshSizeFromPoints", 0)
    opt("Mesh.MeshSizeFromCurvature", 0)
    opt("Mesh.Algorithm", 6)
    opt("Mesh.RecombinationAlgorithm", 3)
