r"""The same numbers on DOLFINx 0.5.2 (Debian 12), 0.9 (Debian 13) and 0.11 (PyPI).

The contact patch test (B1), Hertz at h_c = a/10 (B2), the frictional block on the slab
(B5, μ = 0.3) and the half-rings with Coulomb friction μ = 0.3 (B3, the full path) are
solved on every version and every converged step compared with the first's: nodal
pressures, reactions,
contact forces, the other interface arrays to ``--rtol`` (1e-8), Newton iterations, cuts and
stick/slip statuses exactly (benchmarks/fingerprint.py ``compare``).

All versions read the same mesh files, written once by ``scenes``: the generators' meshes
are not the same on all systems. gmsh 4.8 (Debian 12) and 4.13 (Debian 13) mesh the Hertz
disk's far field differently (176 of 5708 nodes moved, by up to 1.2e-4; the contact zone is
the same), which alone makes the Hertz pressures differ by 1.8e-8 relative; the structured
meshes of B1, B3, B5 agree to 5e-15. .ci/run does::

    python benchmarks/cross_version.py scenes DIR             # four scenes and their meshes
    python benchmarks/cross_version.py run A.json DIR/*.toml  # on the host (0.5.2)
    scripts/debian_root.sh -- .venv/bin/python benchmarks/cross_version.py run B.json ...
    scripts/debian_root.sh --venv pip -- .venv/bin/python benchmarks/cross_version.py run C.json ...
    python benchmarks/cross_version.py compare A.json B.json C.json

``run`` is fingerprint's ``run`` with the DOLFINx, PETSc and MPI versions added to the file.
``compare`` runs fingerprint's comparison of the first file with each other one (exit 1 if
anything differs) and then prints, per scene and version, the largest relative difference
of the nodal pressures and of the reactions to the first file's.
"""
from __future__ import annotations

import argparse
import json
import re
import sys
from pathlib import Path

import numpy as np

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from benchmarks import fingerprint  # noqa: E402

SCENES_DIR = Path(__file__).resolve().parents[1] / "demos" / "scenes"
# file stem -> (demo scene, [(old text, new text)]): the demo scenes are B1, B2 at a/10 and
# B5 with mu = 0.3 already; B3 is made frictional as its own docstring says
SCENES = {
    "patch_test": ("patch_test", []),
    "hertz": ("hertz", []),
    "block_on_slab": ("block_on_slab", []),
    "half_rings_mu03": ("half_rings", [(
        'enforcement = { type = "lagrange" }\n',
        'enforcement = { type = "lagrange" }\nfriction = { law = "coulomb", mu = 0.3 }\n')]),
}


def write_scenes(folder: Path) -> list[Path]:
    """The four scene files in ``folder``, each reading its mesh from a file written here
    by its generator; an edit that no longer applies stops here (the demo scene changed)
    instead of comparing some other problem."""
    folder.mkdir(parents=True, exist_ok=True)
    paths = []
    for name, (stem, edits) in SCENES.items():
        text = (SCENES_DIR / f"{stem}.toml").read_text()
        for old, new in edits:
            if text.count(old) != 1:
                raise SystemExit(f"cross_version: {stem}.toml changed: {old!r} is not in it once")
            text = text.replace(old, new)
        text = mesh_to_file(text, folder / f"{name}.msh")
        path = folder / f"{name}.toml"
        path.write_text(text)
        paths.append(path)
    return paths


def mesh_to_file(text: str, msh: Path) -> str:
    """Write the scene's generated mesh to ``msh`` (binary: coordinates bit for bit) and
    return the scene text with ``[mesh]`` reading that file instead."""
    import tomllib

    import gmsh
    from fenicsx_mortar.scene.meshing import load_generator
    mesh = tomllib.loads(text)["mesh"]
    gmsh.initialize()
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.model.add(mesh["generator"])
        load_generator(mesh["generator"]).build(
            gmsh.model, cell=mesh.get("cell", "quadrilateral"), **mesh.get("params", {}))
        gmsh.option.setNumber("Mesh.MshFileVersion", 4.1)
        gmsh.option.setNumber("Mesh.Binary", 1)
        gmsh.write(str(msh))
    finally:
        gmsh.finalize()
    head, sep, rest = text.partition("[mesh]\n")
    body, nxt, tail = rest.partition("\n[")
    keep = [line for line in body.splitlines()
            if not re.match(r"\s*(generator|cell|params)\s*=", line)]
    return head + sep + "\n".join([f'file = "{msh.name}"', *keep]) + "\n" + nxt + tail


def largest(a: dict, b: dict, group: str) -> tuple[float, str]:
    """Largest relative difference of one group ("pressure", "reactions") between two
    fingerprints of a scene, with fingerprint's scales (the pair's largest traction, the
    scene's largest reaction), and where it is."""
    diff, scale = {}, {}
    for sa, sb in zip(a["steps"], b["steps"]):
        fa, fb = fingerprint.flat(sa), fingerprint.flat(sb)
        for key in fa.keys() & fb.keys():
            name = key.removeprefix("record/")
            g, sid = fingerprint.classify(name)
            if g != group:
                continue
            x = np.array(fa[key], dtype=float).ravel()
            y = np.array(fb[key], dtype=float).ravel()
            if x.shape != y.shape:
                return float("inf"), name
            diff[name] = max(diff.get(name, 0.0), float(np.nanmax(np.abs(x - y), initial=0.0)))
            top = float(np.nanmax(np.abs(np.r_[x, y]), initial=0.0))
            scale[sid] = max(scale.get(sid, 0.0), top)
    worst = (0.0, "")
    for name, d in diff.items():
        s = scale[fingerprint.classify(name)[1]]
        rel = d / s if s > 0 else (0.0 if d == 0 else float("inf"))
        worst = max(worst, (rel, name))
    return worst


def run(out: Path, scenes: list[str]) -> None:
    """fingerprint's ``run``, then the versions it ran on into the file's meta."""
    from mpi4py import MPI
    from fenicsx_mortar import _dolfinx as dx
    fingerprint.run(out, scenes, None)
    if MPI.COMM_WORLD.rank == 0:
        from petsc4py import PETSc
        data = json.loads(out.read_text())
        data["meta"].update(dolfinx=dx.VERSION, petsc=".".join(map(str, PETSc.Sys.getVersion())),
                            mpi=MPI.Get_library_version().splitlines()[0].strip())
        out.write_text(json.dumps(data, indent=0) + "\n")


def _label(meta: dict, path: Path) -> str:
    return f"DOLFINx {meta['dolfinx']}" if "dolfinx" in meta else path.name


def compare(files: list[Path], rtol: float) -> int:
    """Each file after the first against the first (fingerprint's verdict), then a table of
    the largest relative differences; exit status 1 if any comparison failed."""
    data = [json.loads(Path(f).read_text()) for f in files]
    ref, ref_label = data[0]["scenes"], _label(data[0]["meta"], files[0])
    status = 0
    for f in files[1:]:
        status |= fingerprint.compare(files[0], f, rtol)
    labels = [_label(d["meta"], f) for d, f in zip(data[1:], files[1:])]
    print(f"\nlargest relative difference to {ref_label} (nodal pressures / reactions):")
    print("| scene | " + " | ".join(labels) + " |")
    print("|---|" + "---|" * len(labels))
    overall = [{"pressure": (0.0, ""), "reactions": (0.0, "")} for _ in labels]
    for name in ref:
        cells = []
        for d, worst in zip(data[1:], overall):
            other = d["scenes"].get(name)
            if other is None:
                cells.append("missing")
                continue
            rel = {}
            for group in worst:
                rel[group], where = largest(ref[name], other, group)
                worst[group] = max(worst[group], (rel[group], f"{name}: {where}"))
            cells.append(f"{rel['pressure']:.1e} / {rel['reactions']:.1e}")
        print(f"| {name} | " + " | ".join(cells) + " |")
    for label, worst in zip(labels, overall):
        print(f"{label} against {ref_label}: largest relative difference over the scenes: "
              + "; ".join(f"{g} {rel:.2g} ({where})" for g, (rel, where) in worst.items()))
    return status


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    s = sub.add_parser("scenes", help="write the scene files, print their paths")
    s.add_argument("folder", type=Path)
    r = sub.add_parser("run", help="fingerprint the scenes on this version")
    r.add_argument("out", type=Path)
    r.add_argument("scenes", nargs="+")
    c = sub.add_parser("compare", help="compare the fingerprints of versions with the first's")
    c.add_argument("files", type=Path, nargs="+")
    c.add_argument("--rtol", type=float, default=1e-8)
    args = ap.parse_args()
    if args.cmd == "scenes":
        print(" ".join(str(p) for p in write_scenes(args.folder)))
        return 0
    if args.cmd == "run":
        run(args.out, args.scenes)
        return 0
    if len(args.files) < 2:
        ap.error("compare: give two fingerprint files or more")
    return compare(args.files, args.rtol)


if __name__ == "__main__":
    sys.exit(main())
