"""Command line: ``fenicsx-mortar run SCENE.toml --out DIR``, ``fenicsx-mortar check
SCENE.toml``, and in a source checkout ``fenicsx-mortar study [--quick] [--out DIR]``
(``python -m benchmarks.study``, docs/accuracy-vs-time.md).

Exit codes: 0 converged, 1 the run stopped early (outputs up to the last converged step are
kept), 2 bad input (one message naming the problem, no traceback).
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    if argv[:1] == ["study"]:
        return _study(argv[1:])
    parser = argparse.ArgumentParser(prog="fenicsx-mortar",
                                     description="2D finite-deformation mortar contact on FEniCSx")
    sub = parser.add_subparsers(dest="command", required=True)
    run = sub.add_parser("run", help="run a scene file")
    run.add_argument("scene", type=Path, nargs="?", help="scene file (TOML, see docs/scenes.md)")
    run.add_argument("--out", type=Path, default=None,
                     help="output directory (default: results/<scene name>)")
    run.add_argument("--restart", type=Path, default=None, metavar="DIR",
                     help="continue the run in DIR from its last converged step")
    check = sub.add_parser("check", help="validate a scene file (and its mesh) without solving")
    check.add_argument("scene", type=Path)
    # listed for --help only: main() hands "study" to the study's own parser first
    sub.add_parser("study", add_help=False, help="accuracy against compute time: method x "
                   "smoothing x enforcement x mesh size on B1-B3 (source checkout only; "
                   "docs/accuracy-vs-time.md)")
    args = parser.parse_args(argv)

    from mpi4py import MPI

    from .scene import SceneError, load_scene
    comm = MPI.COMM_WORLD
    try:
        if args.command == "run" and args.restart is not None:
            from .scene import load_scene_json
            scene = load_scene_json(args.restart / "scene.json")
            args.scene, args.out = args.restart / "scene.json", args.restart
        elif args.scene is None:
            parser.error("give a scene file (or --restart DIR)")
        else:
            scene = load_scene(args.scene)
        if args.command == "check":
            from .meshing import build_domain
            build_domain(scene, comm)
            if comm.rank == 0:
                print(f"{args.scene}: OK")
            return 0
        from .run import solve
        out = args.out or Path("results") / args.scene.stem
        result = solve(scene, out, comm, restart=args.restart is not None)
    except SceneError as e:
        if comm.rank == 0:
            print(f"fenicsx-mortar: error: {e}", file=sys.stderr)
        return 2
    if comm.rank == 0:
        t = result.timings
        print(f"summary: {'converged' if result.converged else 'NOT converged'}, "
              f"{len(result.steps)} steps, "
              f"{sum(s['newton_iterations'] for s in result.steps)} Newton iterations, "
              f"{t.get('total', 0):.2f} s total; outputs in {out}")
        if result.steps:
            for name, c in result.steps[-1].get("contact", {}).items():
                print(f"contact {name}: normal force {c['normal_force']:.6g}, max pressure "
                      f"{c['max_pressure']:.6g}, {c['active_nodes']} active nodes, "
                      f"KKT residual {c['kkt_residual']:.1e}")
    return 0 if result.converged else 1


def _study(argv: list[str]) -> int:
    """The study lives in the repository (benchmarks/study), not in the package: found next
    to the package's directory, i.e. in a source checkout (editable install)."""
    root = Path(__file__).resolve().parents[1]
    if not (root / "benchmarks" / "study" / "__main__.py").is_file():
        print("fenicsx-mortar: the study runs from a source checkout: "
              "python -m benchmarks.study [--quick] [--out DIR] (in the repository root)",
              file=sys.stderr)
        return 2
    sys.path.insert(0, str(root))
    from benchmarks.study.__main__ import main as study
    return study(argv, prog="fenicsx-mortar study")


if __name__ == "__main__":
    sys.exit(main())
