"""Build the B2 Hertz mesh with fenicsx_mortar's own generator and dump it as JSON.

Run with the PROJECT's interpreter (gmsh 4.8, the exact mesh our code solves on):

    .venv/bin/python benchmarks/peers/export_hertz_mesh.py LEVEL OUT.json

h_contact = a/LEVEL, h_far = 0.1, refine_radius = 0.08, grade_to = 0.6, quadrilaterals:
the parameters of benchmarks/newton_cost.py ``hertz_scene``. Output: nodes {tag: [x, y]},
quads per body (gmsh node tags, as gmsh gives them) and the 2-node segments of every named
physical curve group.
"""
import json
import sys
from pathlib import Path

import gmsh

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))
from benchmarks.analytics import HERTZ_A  # noqa: E402  (exact a, as hertz_scene uses)
from fenicsx_mortar.meshes import hertz  # noqa: E402


def main(level: float, out: str) -> None:
    gmsh.initialize()
    gmsh.option.setNumber("General.Terminal", 0)
    gmsh.model.add("hertz")
    hertz.build(gmsh.model, cell="quadrilateral", h_contact=HERTZ_A / level, h_far=0.1,
                refine_radius=0.08, grade_to=0.6)
    tags, xyz, _ = gmsh.model.mesh.getNodes()
    nodes = {int(t): [float(xyz[3 * i]), float(xyz[3 * i + 1])] for i, t in enumerate(tags)}
    bodies, curves = {}, {}
    for dim, ptag in gmsh.model.getPhysicalGroups():
        name = gmsh.model.getPhysicalName(dim, ptag)
        cells = []
        for ent in gmsh.model.getEntitiesForPhysicalGroup(dim, ptag):
            types, _, conn = gmsh.model.mesh.getElements(dim, ent)
            for et, c in zip(types, conn):
                k = {3: 4, 1: 2}[int(et)]          # 4-node quad / 2-node line only
                c = [int(v) for v in c]
                cells += [c[i:i + k] for i in range(0, len(c), k)]
        (bodies if dim == 2 else curves)[name] = cells
    gmsh.finalize()
    with open(out, "w") as f:
        json.dump({"level": level, "h_contact": HERTZ_A / level, "nodes": nodes,
                   "bodies": bodies, "curves": curves}, f)


if __name__ == "__main__":
    main(float(sys.argv[1]), sys.argv[2])
