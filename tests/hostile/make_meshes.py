"""Writes the hostile mesh files of tests/hostile/meshes/ (committed; run again only to change
them): ``python tests/hostile/make_meshes.py``. Every file but ``square.msh`` is one that
fenicsx_mortar must refuse by name."""
from __future__ import annotations

from pathlib import Path

import gmsh

HERE = Path(__file__).parent / "meshes"
SIDES = ("bottom", "right", "top", "left")


def _square(x0: float, width: float, n: int, recombine: bool) -> tuple[int, list[int]]:
    occ = gmsh.model.occ
    pts = [occ.addPoint(x, y, 0.0) for x, y in
           [(x0, 0.0), (x0 + width, 0.0), (x0 + width, 1.0), (x0, 1.0)]]
    curves = [occ.addLine(pts[i], pts[(i + 1) % 4]) for i in range(4)]
    surface = occ.addPlaneSurface([occ.addCurveLoop(curves)])
    occ.synchronize()
    for c in curves:
        gmsh.model.mesh.setTransfiniteCurve(c, n + 1)
    gmsh.model.mesh.setTransfiniteSurface(surface, "Left", pts)
    if recombine:
        gmsh.model.mesh.setRecombine(2, surface)
    return surface, curves


def _groups(surfaces: dict[str, list[int]], curves: dict[str, list[int]]) -> None:
    tag = 1
    for dim, groups in ((2, surfaces), (1, curves)):
        for name, entities in groups.items():
            gmsh.model.addPhysicalGroup(dim, entities, tag)
            gmsh.model.setPhysicalName(dim, tag, name)
            tag += 1


def _write(name: str, build, order: int = 1, incomplete: int = 0, dim: int = 2) -> None:
    gmsh.initialize()
    gmsh.option.setNumber("General.Terminal", 0)
    gmsh.option.setNumber("Mesh.MshFileVersion", 4.1)
    gmsh.model.add(name)
    build()
    gmsh.option.setNumber("Mesh.SecondOrderIncomplete", incomplete)
    gmsh.model.mesh.generate(dim)
    if order > 1:
        gmsh.model.mesh.setOrder(order)
    gmsh.write(str(HERE / name))
    gmsh.finalize()


def unit_square(n: int = 2, recombine: bool = True):
    def build():
        s, c = _square(0.0, 1.0, n, recombine)
        _groups({"block": [s]}, dict(zip(SIDES, ([x] for x in c))))
    return build


def mixed():
    """Left half quadrilaterals, right half triangles (two surfaces sharing x = 0.5), one body."""
    geo = gmsh.model.geo
    p = [geo.addPoint(x, y, 0.0) for x, y in
         [(0, 0), (0.5, 0), (1, 0), (1, 1), (0.5, 1), (0, 1)]]
    bottom = [geo.addLine(p[0], p[1]), geo.addLine(p[1], p[2])]
    right = geo.addLine(p[2], p[3])
    top = [geo.addLine(p[3], p[4]), geo.addLine(p[4], p[5])]
    left = geo.addLine(p[5], p[0])
    middle = geo.addLine(p[1], p[4])
    quads = geo.addPlaneSurface([geo.addCurveLoop([bottom[0], middle, top[1], left])])
    tris = geo.addPlaneSurface([geo.addCurveLoop([bottom[1], right, top[0], -middle])])
    geo.synchronize()
    for c in (*bottom, right, *top, left, middle):
        gmsh.model.mesh.setTransfiniteCurve(c, 3)
    for s in (quads, tris):
        gmsh.model.mesh.setTransfiniteSurface(s)
    gmsh.model.mesh.setRecombine(2, quads)
    _groups({"block": [quads, tris]},
            {"bottom": bottom, "right": [right], "top": top, "left": [left]})


def overlap():
    """The one surface is in two physical surface groups: its cells would come twice."""
    s, c = _square(0.0, 1.0, 2, True)
    _groups({"block": [s], "copy": [s]}, dict(zip(SIDES, ([x] for x in c))))


def lines_only():
    """A physical surface group whose surface is not meshed: only 1D cells."""
    s, c = _square(0.0, 1.0, 2, True)
    _groups({"block": [s]}, dict(zip(SIDES, ([x] for x in c))))


def floating():
    """The unit square and a meshed line above it (y = 2) in a physical curve group
    "floating": a boundary whose segments are no cell's edges (DOLFINx 0.5 crashed on it)."""
    s, c = _square(0.0, 1.0, 2, True)
    occ = gmsh.model.occ
    line = occ.addLine(occ.addPoint(1.0, 2.0, 0.0), occ.addPoint(0.0, 2.0, 0.0))
    occ.synchronize()
    gmsh.model.mesh.setTransfiniteCurve(line, 3)
    _groups({"block": [s]}, {**dict(zip(SIDES, ([x] for x in c))), "floating": [line]})


def shared_curve():
    """The unit square with its bottom in two physical curve groups, "bottom" and "base":
    a facet keeps one tag (DOLFINx), so one group would silently lose its facets."""
    s, c = _square(0.0, 1.0, 2, True)
    _groups({"block": [s]}, {**dict(zip(SIDES, ([x] for x in c))), "base": [c[0]]})


def save_all():
    """The unit square (group "block") and a second meshed square beside it in no physical
    group, written with Mesh.SaveAll (DOLFINx aborted, SIGABRT)."""
    s, c = _square(0.0, 1.0, 2, True)
    _square(2.0, 1.0, 2, True)
    _groups({"block": [s]}, dict(zip(SIDES, ([x] for x in c))))
    gmsh.option.setNumber("Mesh.SaveAll", 1)


def _offset_numbers(text: str, offset: int) -> str:
    """An MSH 2.2 text with every node number shifted by ``offset``."""
    out, section = [], None
    for line in text.split("\n"):
        parts = line.split()
        if line.startswith("$"):
            section = line
        elif section == "$Nodes" and len(parts) == 4:
            parts[0] = str(int(parts[0]) + offset)
        elif section == "$Elements" and len(parts) > 3:
            k = 3 + int(parts[2])
            parts = parts[:k] + [str(int(q) + offset) for q in parts[k:]]
        out.append(" ".join(parts) if parts and not line.startswith("$") else line)
    return "\n".join(out)


def main() -> None:
    HERE.mkdir(exist_ok=True)
    _write("square.msh", unit_square())
    _write("mixed.msh", mixed)
    _write("tri6.msh", unit_square(recombine=False), order=2)
    _write("quad9.msh", unit_square(), order=2)
    _write("quad8.msh", unit_square(), order=2, incomplete=1)
    _write("overlap.msh", overlap)
    _write("lines_only.msh", lines_only, dim=1)
    _write("floating.msh", floating)
    _write("shared_curve.msh", shared_curve)
    # a unit square and, beside it, a quadrilateral whose four corners lie on one line
    # (zero area), written by hand (gmsh 2.2)
    (HERE / "zero_area.msh").write_text(
        "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$PhysicalNames\n3\n1 2 \"bottom\"\n"
        "1 3 \"top\"\n2 1 \"block\"\n$EndPhysicalNames\n$Nodes\n7\n1 0 0 0\n2 1 0 0\n"
        "3 2 0 0\n4 0 1 0\n5 1 1 0\n6 3 0 0\n7 4 0 0\n$EndNodes\n$Elements\n4\n"
        "1 1 2 2 1 1 2\n2 1 2 3 3 4 5\n3 3 2 1 1 1 2 5 4\n4 3 2 1 1 3 6 7 2\n"
        "$EndElements\n")
    # the unit square as one quadrilateral, listed twice (DOLFINx 0.5: a PETSc SEGV and a
    # process that hangs)
    (HERE / "duplicate_cell.msh").write_text(
        "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$PhysicalNames\n3\n1 2 \"bottom\"\n"
        "1 3 \"top\"\n2 1 \"block\"\n$EndPhysicalNames\n$Nodes\n4\n1 0 0 0\n2 1 0 0\n"
        "3 1 1 0\n4 0 1 0\n$EndNodes\n$Elements\n4\n1 1 2 2 1 1 2\n2 1 2 3 3 3 4\n"
        "3 3 2 1 1 1 2 3 4\n4 3 2 1 1 1 2 3 4\n$EndElements\n")
    (HERE / "points_only.msh").write_text(
        "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n3\n1 0 0 0\n2 1 0 0\n3 0 1 0\n"
        "$EndNodes\n$Elements\n0\n$EndElements\n")
    (HERE / "empty.msh").write_bytes(b"")
    (HERE / "garbage.msh").write_bytes(bytes(range(256)) * 8)
    text = (HERE / "square.msh").read_text()
    (HERE / "truncated.msh").write_text(text[: text.index("$Elements") + 40])
    _write("save_all.msh", save_all)
    # the unit square with its nodes numbered from 1e9 (a valid file: "Unable to allocate
    # 14.9 GiB" before the renumbering)
    gmsh.initialize()
    gmsh.option.setNumber("General.Terminal", 0)
    gmsh.option.setNumber("Mesh.MshFileVersion", 2.2)
    gmsh.model.add("square22")
    unit_square()()
    gmsh.model.mesh.generate(2)
    gmsh.write(str(HERE / "numbered_from_1e9.msh"))
    gmsh.finalize()
    path = HERE / "numbered_from_1e9.msh"
    path.write_text(_offset_numbers(path.read_text(), 10**9))


if __name__ == "__main__":
    main()
