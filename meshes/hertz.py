"""B2 Hertz: half-disk resting on a block, refined around the contact point (0, 0)."""
from __future__ import annotations

import math

import gmsh

from . import _checks, _gmsh


def build(model, *, cell: str = "quadrilateral", h_contact: float = 0.05, h_far: float = 0.1,
          R: float = 1.0, refine_radius: float = 0.15, grade_to: float | None = None,
          refine: int = 0) -> list:
    """Half-disk "disk" (lower half of the circle of radius R centred at (0, R), flat edge
    y = R) on the block "block" [-1, 1] x [-1, 0] (docs/benchmarks.md B2). They touch at (0, 0)
    only; each body has its own node there (no shared node).

    Unstructured meshes driven by a size field: element size h_contact within distance
    refine_radius of (0, 0) (so on both bodies for |x| <= refine_radius along the contact
    surfaces), growing linearly to h_far at distance grade_to (default: refine_radius +
    5 (h_far - h_contact)). ``refine_radius = 0.08, grade_to = 0.6`` is the grading of
    docs/benchmarks.md B2's reference meshes (about 4.4k dofs at h_contact = a/10).
    Quadrilaterals: gmsh's "Blossom full-quad" recombination of a frontal-Delaunay
    triangulation (all quads by construction; checked: RuntimeError if any triangle is left).
    Cost: about 1 s for h_contact = 0.0024 (a/20), ~17k cells. Sets the global gmsh options
    Mesh.Algorithm, Mesh.RecombinationAlgorithm and Mesh.MeshSizeExtendFromBoundary /
    FromPoints / FromCurvature (see _set_options).

    Parameters (keyword only, defaults in brackets):
        cell:          "quadrilateral" [default] or "triangle".
        h_contact:     element size near the contact point [0.05], > 0.
        h_far:         element size away from it [0.1], >= h_contact, <= min(R, 1)/4.
        R:             half-disk radius [1.0], in [1e-3, 1e3].
        refine_radius: radius of the uniformly refined zone around (0, 0) [0.15], in [0, 1e3].
        grade_to:      distance from (0, 0) where the size reaches h_far [None: see above],
                       > refine_radius.
        refine:        uniform refinements of the generated mesh [0], in [0, 4]: each splits
                       every cell into four (gmsh's refine; new boundary nodes on the arc),
                       so the sizes above are those before refining. For large meshes:
                       at about 2M dofs, h = 0.0082 refined twice takes ~15 s where
                       meshing at h/4 directly takes many minutes (h/2: 131 s against
                       5.5 + 1.4 s; docs/performance.md).

    Returns the meshes before each refinement, coarsest first (the hierarchy of
    ``linear_solver = "gmres-gmg"``; empty without refinement).

    Physical groups (tags in brackets):
        dim 2: "disk" [1], "block" [2].
        dim 1: "disk_arc" [3] (the half circle, two quarter arcs cut at (0, 0)),
               "disk_top" [4] (flat edge y = R, cut at (0, R)),
               "block_top" [5] (y = 0, cut at x = 0), "block_bottom" [6] (y = -1, cut at
               x = 0), "block_left" [7] (x = -1), "block_right" [8] (x = 1).

    Mesh nodes lie exactly at: (0, R) (disk top), (0, R/2) (disk interior, embedded point;
    (0, 0.5) for R = 1), (0, 0) on the disk arc AND on the block top (one node each), and
    (0, -1) (block bottom).
    """
    cells(cell=cell, h_contact=h_contact, h_far=h_far, R=R, refine_radius=refine_radius,
          grade_to=grade_to, refine=refine)
    if grade_to is None:
        grade_to = refine_radius + 5.0 * (h_far - h_contact)
    _set_options(cell)
    occ = model.occ

    # Disk: flat edge cut at the centre, arc cut at the contact point (0, 0).
    left, centre, right = (occ.addPoint(x, R, 0.0) for x in (-R, 0.0, R))
    bottom = occ.addPoint(0.0, 0.0, 0.0)
    inner = occ.addPoint(0.0, 0.5 * R, 0.0)
    disk_top = [occ.addLine(left, centre), occ.addLine(centre, right)]
    disk_arc = [occ.addCircleArc(right, centre, bottom), occ.addCircleArc(bottom, centre, left)]
    disk = occ.addPlaneSurface([occ.addCurveLoop(disk_top + disk_arc)])

    # Block: bottom and top cut at x = 0.
    pts = [occ.addPoint(x, y, 0.0) for x, y in
           [(-1, -1), (0, -1), (1, -1), (1, 0), (0, 0), (-1, 0)]]
    b_curves = [occ.addLine(pts[i], pts[(i + 1) % 6]) for i in range(6)]
    block = occ.addPlaneSurface([occ.addCurveLoop(b_curves)])
    occ.synchronize()
    model.mesh.embed(0, [inner], 2, disk)

    field = model.mesh.field
    distance = field.add("Distance")
    field.setNumbers(distance, "PointsList", [bottom, pts[4]])
    threshold = field.add("Threshold")
    field.setNumber(threshold, "InField", distance)
    field.setNumber(threshold, "SizeMin", h_contact)
    field.setNumber(threshold, "SizeMax", h_far)
    field.setNumber(threshold, "DistMin", refine_radius)
    field.setNumber(threshold, "DistMax", grade_to)
    field.setAsBackgroundMesh(threshold)
    if cell == "quadrilateral":
        model.mesh.setRecombine(2, disk)
        model.mesh.setRecombine(2, block)

    groups = [(2, [disk], "disk"), (2, [block], "block"), (1, disk_arc, "disk_arc"),
              (1, disk_top, "disk_top"), (1, b_curves[3:5], "block_top"),
              (1, b_curves[0:2], "block_bottom"), (1, [b_curves[5]], "block_left"),
              (1, [b_curves[2]], "block_right")]
    _gmsh.name_groups(model, groups)
    # gmsh 4.8's full-quad recombination leaves a triangle for a few sizes (seen: h_contact
    # = a/10 for a soft disk on a 4x stiffer block): mesh again with the field's sizes
    # 0.1 % smaller, which moves every node slightly and recombines cleanly
    for attempt in range(4):
        model.mesh.generate(2)
        if _gmsh.is_all(model, cell):
            from ..condensation.multigrid import refine_gmsh   # (petsc4py: when meshing)
            return refine_gmsh(model, refine)
        model.mesh.clear()
        shrink = 1.0 - 1e-3 * (attempt + 1)
        field.setNumber(threshold, "SizeMin", h_contact * shrink)
        field.setNumber(threshold, "SizeMax", h_far * shrink)
    raise RuntimeError(f"mesh is not all {cell}: {model.mesh.getElementTypes(2)}")


def cells(*, cell: str = "quadrilateral", h_contact: float = 0.05, h_far: float = 0.1,
          R: float = 1.0, refine_radius: float = 0.15, grade_to: float | None = None,
          refine: int = 0) -> int:
    """About the number of cells ``build`` makes (an estimate from the size field: the
    mesh is unstructured), after its parameter checks (ValueError). The elements must fit
    the bodies (h_far <= min(R, 1)/4): larger ones make gmsh abort the process."""
    if isinstance(refine, bool) or not isinstance(refine, int) or not 0 <= refine <= 4:
        raise ValueError(f"refine must be an integer in [0, 4], got {refine!r}")
    per_area = 1.15 * _checks.cell(cell)
    for name, value in (("h_contact", h_contact), ("h_far", h_far), ("R", R),
                        ("refine_radius", refine_radius)):
        _checks.number(name, value)
    _checks.lengths(h_contact=h_contact, h_far=h_far)
    if not 1e-3 <= R <= 1e3:
        raise ValueError(f"R must lie in [1e-3, 1e3], got {R!r}")
    if not h_far >= h_contact:
        raise ValueError(f"h_far must be >= h_contact, got h_far={h_far!r}, "
                         f"h_contact={h_contact!r}")
    if not h_far <= min(R, 1.0) / 4:
        raise ValueError(f"h_far must be <= min(R, 1)/4 = {min(R, 1.0) / 4:g} (four elements "
                         f"across the thinner body), got {h_far!r}")
    if not 0 <= refine_radius <= 1e3:
        raise ValueError(f"refine_radius must lie in [0, 1e3], got {refine_radius!r}")
    if grade_to is None:
        grade_to = refine_radius + 5.0 * (h_far - h_contact)
    else:
        _checks.number("grade_to", grade_to)
        if not refine_radius < grade_to <= 1e3:
            raise ValueError(f"grade_to must be > refine_radius and <= 1e3, got "
                             f"grade_to={grade_to!r}, refine_radius={refine_radius!r}")
    # cells per area 1.15/h^2 (quadrilaterals; triangles 2.3/h^2): h_contact within
    # refine_radius of the contact point, growing linearly to h_far at grade_to (the
    # Threshold field); the integral of 2 pi r / h(r)^2 over that ring is closed
    area = 2.0 + 0.5 * math.pi * R * R
    r0, r1, hc, hf = refine_radius, grade_to, h_contact, h_far
    fine = min(math.pi * r0 * r0, area) / hc ** 2
    if hf > hc:
        k = (hf - hc) / (r1 - r0)
        ring = 2.0 * math.pi / k * ((r0 - hc / k) * (1.0 / hc - 1.0 / hf)
                                    + math.log(hf / hc) / k)
    else:
        ring = math.pi * (r1 * r1 - r0 * r0) / hc ** 2
    return int(per_area * (fine + ring + area / hf ** 2)) * 4 ** refine


def _set_options(cell: str) -> None:
    # Options are global to the gmsh session: set every one the size field and the
    # recombination depend on, whatever a previous build left.
    opt = gmsh.option.setNumber
    opt("Mesh.ElementOrder", 1)
    opt("Mesh.RecombineAll", 0)
    opt("Mesh.SubdivisionAlgorithm", 0)
    opt("Mesh.MeshSizeExtendFromBoundary", 0)   # the field alone sets the size
    opt("Mesh.MeshSizeFromPoints", 0)
    opt("Mesh.MeshSizeFromCurvature", 0)
    # Frontal-Delaunay. (gmsh 4.8's "frontal-Delaunay for quads", 8, crashes on this
    # geometry; plain Blossom, 1, leaves stray triangles for some sizes.)
    opt("Mesh.Algorithm", 6)
    # Blossom full-quad: triangulate at twice the size, recombine, split every cell into
    # quads, so no triangle can be left and the final size is about the field's.
    opt("Mesh.RecombinationAlgorithm", 3)
