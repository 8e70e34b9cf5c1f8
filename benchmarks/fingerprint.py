r"""Behaviour fingerprints: solve scenes, store every converged step's numbers, compare runs.

A refactor that promises "behaviour unchanged" is checked by fingerprinting the scenes before
and after it and comparing the two files::

    python benchmarks/fingerprint.py run OUT.json SCENE.toml [SCENE.toml ...] [--steps N]
    python benchmarks/fingerprint.py compare A.json B.json [--rtol 1e-12]

``run`` solves each scene with the public API (``solve(scene, out=None, on_step=...)``) and
stores, per scene and per converged step, the step record (Newton iterations, augmentations,
cuts, residuals, reactions, the "contact" sub-dict) and, per contact pair, every nodal array
of ``pair.interface()`` (pressure, gap, x, y, s, active; with friction t_tangential, slip,
status), plus the final ``converged`` flag and message (or the exception, if the run raised).
Floats are written by ``repr`` (exact for float64); NaN (the gap of a node without support)
becomes null. ``--steps N`` keeps the first N load steps of every scene (the cut floor stays
the full scene's). Under mpirun every rank solves, rank 0 writes; the interface arrays are
checked to be identical on every rank, and a hash of each rank's dofs records the mesh
partition. OUT.json is rewritten after each scene.

``compare`` matches scenes by file stem and prints, per scene, the largest relative
difference of the reactions, the contact records, the nodal pressures and the other interface
arrays (each quantity relative to its largest magnitude in the scene, over all steps and both
runs), and whether the step counts, converged flags, Newton iterations, augmentations, cuts
and statuses (active / stick / slip per node, active / stick / slip node counts) are
identical. It exits 1 if any of these differs (floats: beyond ``--rtol``). Residual histories
and the KKT residual are printed for information only: near convergence they are round-off
noise, so they are not part of the verdict; nor is a changed message when the flags agree.
Interface arrays are compared node by node in the pair's own node order. Scales: all
reactions of a scene share one (a component zero up to round-off has no accuracy of its
own); a pair's forces share one, so do its pressure and tangential traction, and its
positions, arc lengths, gaps and slips (gaps and slips are differences of positions).

The baseline of commit 5d83ce5 was recorded in a worktree, whose code the baseline imports
(check: the first line ``run`` prints names the package it solves with), on the scene files
frozen there; /tmp/fm_scenes holds the variants the tests run (VARIANTS below)::

    git -C /work/main worktree add --detach /tmp/fm_base 5d83ce5
    cd /tmp/fm_base
    FP="/work/main/.venv/bin/python /work/main/benchmarks/fingerprint.py"
    MPI2="env OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 mpirun -n 2 --oversubscribe"
    S="demos/scenes/patch_test.toml demos/scenes/hertz.toml demos/scenes/block_on_slab.toml
       demos/scenes/half_rings.toml demos/scenes/ironing.toml demos/scenes/clamped_block.toml
       demos/scenes/block_compression.toml demos/scenes/hard/*.toml /tmp/fm_scenes/*.toml"
    PYTHONPATH=/tmp/fm_base $FP variants /tmp/fm_scenes
    PYTHONPATH=/tmp/fm_base $FP run /tmp/fm_baseline_serial.json $S             # 3.5 min
    $MPI2 env PYTHONPATH=/tmp/fm_base $FP run /tmp/fm_baseline_mpi2.json $S     # 19-23 min (busy)

Reproducibility of the baseline itself (same code, run again): serial runs are bitwise
equal (/tmp/fm_baseline_serial_b.json, scenes in reverse order: 38 of 38). Under mpirun -n 2
they are not (three runs: /tmp/fm_baseline_mpi2{,_a,_b}.json): the mesh partition changes
from run to run, and MUMPS in parallel varies even on the same partition (with linear_solver
= "superlu_dist" the same partition gave bitwise equal runs). Between two such runs the
pressures differ by up to 7e-10 relative, contact records by 5e-10, reactions by 8e-12, and
Newton iterations differ in ~20 of 96 ironing steps (by up to 11) and 8 of 9
c03_half_rings_bspline steps (up to 8); 6 of 38 scenes were bitwise equal in all three. So
under MPI ``compare`` shows this noise floor, and only the serial comparison can check
"bitwise or <= 1e-12".

After the refactor: the same scene files (still from /tmp/fm_base, so that only the code
differs), the refactored package by PYTHONPATH=/work/main (FP, MPI2, S as above; this
compares against 5d83ce5 whatever /work/main holds, commits made since included)::

    cd /tmp/fm_base
    PYTHONPATH=/work/main $FP run /tmp/fm_new_serial.json $S
    $FP compare /tmp/fm_baseline_serial.json /tmp/fm_new_serial.json
    $MPI2 env PYTHONPATH=/work/main $FP run /tmp/fm_new_mpi2.json $S
    $FP compare /tmp/fm_baseline_mpi2.json /tmp/fm_new_mpi2.json
"""
from __future__ import annotations

import argparse
import hashlib
import json
import math
import os
import sys
import time
from pathlib import Path

import numpy as np

# the variants of the demo scenes that the tests run (tests/test_mpi.py, tests/stability):
# name -> (scene file under demos/scenes, [(old text, new text), ...])
SMOOTH = 'method = "mortar"', 'method = "mortar"\nsmoothing = "{}"'
HALF_RINGS_TIMES = ("times = [0.25, 0.5, 0.75, 1.0, 1.05, 1.1, 1.15, 1.2, 1.25, 1.3, 1.35, 1.4, "
                    "1.45, 1.5, 1.55, 1.6, 1.65, 1.7, 1.75, 1.8, 1.85, 1.9, 1.95, 2.0]")
VARIANTS = {
    "patch_test_nts": ("patch_test", [('method = "mortar"', 'method = "nts"')]),
    "patch_test_hermite": ("patch_test", [(SMOOTH[0], SMOOTH[1].format("hermite"))]),
    "patch_test_bspline": ("patch_test", [(SMOOTH[0], SMOOTH[1].format("bspline"))]),
    "hertz_hermite": ("hertz", [(SMOOTH[0], SMOOTH[1].format("hermite"))]),
    "hertz_coarse": ("hertz", [("h_contact = 0.0048", "h_contact = 0.012")]),
    "block_on_slab_short": ("block_on_slab", [
        ("times = [0.5, 1.0, 1.1, 1.2, 1.3, 1.4, 1.5, 1.6, 1.7, 1.8, 1.9, 2.0]",
         "times = [1.0, 1.1, 1.2]")]),
    "half_rings_friction": ("half_rings", [
        ('enforcement = { type = "alm" }\n',
         'enforcement = { type = "alm" }\nfriction = { law = "coulomb", mu = 0.3 }\n'),
        (HALF_RINGS_TIMES, "times = [0.5, 1.0, 1.05, 1.1]")]),
    "c09b_frictionless": ("hard/c09b_vanishing_friction", [
        ('friction = { law = "coulomb", mu = 1.0e-6 }\n', "")]),
    "c11_max_iterations_2": ("hard/c11_touching_huge_residual", [
        ("[solver]\n", "[solver]\nmax_iterations = 2\n")]),
    "c11_rtol_1": ("hard/c11_touching_huge_residual", [("rtol = 1e-9", "rtol = 1.0")]),
}


def plain(v):
    """JSON-ready copy: numpy → Python, NaN → None (floats stay exact: json writes repr)."""
    if isinstance(v, np.ndarray):
        v = v.tolist()
    if isinstance(v, dict):
        return {str(k): plain(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [plain(x) for x in v]
    if isinstance(v, (bool, np.bool_)):
        return bool(v)
    if isinstance(v, (int, np.integer)):
        return int(v)
    if isinstance(v, (float, np.floating)):
        return None if math.isnan(v) else float(v)
    return str(v) if isinstance(v, np.str_) else v


def partition(V, comm) -> list[str]:
    """Per rank, hashes of the coordinates of the dofs it owns (as a set: the mesh partition)
    and of all its dofs in their local order, ghosts included (the numbering). Under mpirun
    both can change from run to run, and with them the round-off of every sum."""
    def sha(a):
        return hashlib.sha1(np.ascontiguousarray(a).tobytes()).hexdigest()[:12]
    X = V.tabulate_dof_coordinates()
    own = X[: V.dofmap.index_map.size_local]
    return comm.allgather(f"{sha(own[np.lexsort(own.T[::-1])])}/{sha(X)}")


def fingerprint(path: str, steps: int | None, comm) -> dict:
    from fenicsx_mortar import load_scene, solve
    scene = load_scene(path)
    if steps is not None and steps < len(scene.steps.targets()):
        scene.steps.min_increment = scene.steps.floor()  # the floor depends on the final time
        scene.steps.times, scene.steps.count = scene.steps.targets()[:steps], None
    fp = {"path": str(path), "title": scene.title, "steps_limit": steps, "steps": []}

    def on_step(record, state):
        # before the library refactor the pairs were ``state.hooks`` with ``.pair.name``
        pairs = state.pairs if hasattr(state, "pairs") else state.hooks
        # (the vertex numbers are labels, not results)
        nodal = plain({getattr(p, "pair", p).name: {k: v for k, v in p.interface().items()
                                                     if k != "vertex"} for p in pairs})
        if comm.size > 1 and len(set(comm.allgather(json.dumps(nodal)))) > 1:
            raise RuntimeError(f"{path}: interface arrays differ between ranks")
        fp["steps"].append({"record": plain(record), "nodal": nodal})
        if "partition" not in fp:
            fp["partition"] = partition(state.u.function_space, comm)

    t0 = time.perf_counter()
    try:
        res = solve(scene, out=None, log=lambda s: None, on_step=on_step)
        fp.update(converged=bool(res.converged), message=res.message, dofs=res.summary.get("dofs"))
    except Exception as e:  # noqa: BLE001 - a crash is part of the behaviour
        fp.update(converged=False, message=None, error=f"{type(e).__name__}: {e}")
    fp["seconds"] = time.perf_counter() - t0
    return fp


def run(out: Path, scenes: list[str], steps: int | None) -> None:
    from mpi4py import MPI
    import fenicsx_mortar
    comm = MPI.COMM_WORLD
    data = {"meta": {"ranks": comm.size, "package": fenicsx_mortar.__file__,
                     "argv": sys.argv, "date": time.strftime("%Y-%m-%d %H:%M:%S")},
            "scenes": {}}
    if comm.rank == 0:
        print(f"fenicsx_mortar from {fenicsx_mortar.__file__}, {comm.size} ranks", flush=True)
    for path in scenes:
        name = Path(path).stem
        if name in data["scenes"]:
            raise SystemExit(f"two scenes named {name}")
        fp = fingerprint(path, steps, comm)
        data["scenes"][name] = fp
        if comm.rank == 0:
            tmp = out.with_suffix(".tmp")
            tmp.write_text(json.dumps(data, indent=0) + "\n")
            os.replace(tmp, out)
            print(f"{name:40s} {fp['seconds']:8.1f} s  {len(fp['steps']):3d} steps  "
                  f"converged {fp['converged']}  {fp.get('error') or fp['message']}", flush=True)


# ------------------------------------------------------------------------------ compare
def flat(obj, prefix: str = "") -> dict:
    """Nested dicts as one level: {"record/reactions/bottom/y": 4.0, "nodal/hertz/gap": [...]}"""
    if isinstance(obj, dict):
        out = {}
        for k, v in obj.items():
            out.update(flat(v, f"{prefix}{k}/"))
        return out
    return {prefix[:-1]: obj}


def is_float(v) -> bool:
    vals = v if isinstance(v, list) else [v]
    return any(x is None or isinstance(x, float) for x in vals)


FLOAT_GROUPS = ("reactions", "contact", "pressure", "interface", "residuals (info)", "kkt (info)")
EXACT_GROUPS = ("newton_iterations", "augmentations", "cuts", "statuses", "steps")
FORCES = ("normal_force", "force_on_slave", "tangential_force", "tangential_force_on_slave")


def classify(name: str) -> tuple[str, str]:
    """(report group, scale) of a float quantity such as "reactions/top/y" or "nodal/hertz/gap".
    Quantities sharing a scale are measured against their common largest magnitude: all
    reactions together (a component that is zero up to round-off has no accuracy of its own);
    a pair's forces together; its pressure and tangential traction together; its positions,
    arc lengths, gaps and slips against the largest coordinate (gaps and slips are
    differences of positions)."""
    parts = name.split("/")
    head, last = parts[0], parts[-1]
    if name in ("time", "load_factor"):
        return "steps", name
    if head == "residuals":
        return "residuals (info)", name
    if last == "kkt_residual":
        return "kkt (info)", name
    if head == "reactions":
        return "reactions", "reactions"
    if head == "contact":
        return "contact", f"contact/{parts[1]}/forces" if last in FORCES else name
    if last in ("pressure", "t_tangential"):
        return ("pressure" if last == "pressure" else "interface"), f"nodal/{parts[1]}/tractions"
    if last in ("x", "y", "s", "gap", "slip"):
        return "interface", f"nodal/{parts[1]}/geometry"
    return "interface", name


def exact_group(name: str) -> str:
    last = name.split("/")[-1]
    if last in ("newton_iterations", "augmentations", "cuts"):
        return last
    return "steps" if last == "step" else "statuses"


def compare_scene(a: dict, b: dict, rtol: float) -> bool:
    """Print the comparison of one scene; True when equal within rtol."""
    problems = []
    for k in ("converged", "error", "steps_limit"):
        if a.get(k) != b.get(k):
            problems.append(f"{k}: {a.get(k)!r} vs {b.get(k)!r}")
    if a.get("partition") and b.get("partition") and a["partition"] != b["partition"]:
        print("  note: the mesh partitions differ: round-off differences are expected")
    same = {g: True for g in EXACT_GROUPS}
    if len(a["steps"]) != len(b["steps"]):
        problems.append(f"step count {len(a['steps'])} vs {len(b['steps'])}")
        same["steps"] = False
    diff, scale, bitwise = {}, {}, True
    for k, (sa, sb) in enumerate(zip(a["steps"], b["steps"])):
        fa, fb = flat(sa), flat(sb)
        for key in fa.keys() ^ fb.keys():
            problems.append(f"step {k + 1}: {key} only in {'A' if key in fa else 'B'}")
        for key in fa.keys() & fb.keys():
            va, vb, name = fa[key], fb[key], key.removeprefix("record/")
            bitwise &= va == vb
            if not (is_float(va) or is_float(vb)):
                if va != vb:
                    same[exact_group(name)] = False
                    problems.append(f"step {k + 1}: {name} {va} vs {vb}"[:200])
                continue
            x, y = np.array(va, dtype=float).ravel(), np.array(vb, dtype=float).ravel()
            if x.shape != y.shape or not np.array_equal(np.isnan(x), np.isnan(y)):
                d = math.inf
            else:
                d = float(np.nanmax(np.abs(x - y), initial=0.0))
            diff[name] = max(diff.get(name, 0.0), d)
            sid = classify(name)[1]
            top = float(np.nanmax(np.abs(np.r_[x, y]), initial=0.0))
            scale[sid] = max(scale.get(sid, 0.0), top)
    worst = {g: (0.0, "") for g in FLOAT_GROUPS}
    for name, d in diff.items():
        g, sid = classify(name)
        rel = d / scale[sid] if scale[sid] > 0 else (0.0 if d == 0 else math.inf)
        if g == "steps":  # time, load_factor: must be exact
            if d != 0:
                same["steps"] = False
                problems.append(f"{name} differs by {d:.3g}")
        elif rel > worst[g][0]:
            worst[g] = (rel, name)
    for g in FLOAT_GROUPS[:4]:
        if worst[g][0] > rtol:
            problems.append(f"{g}: {worst[g][1]} differs by {worst[g][0]:.3g} relative")
    floats = ", ".join(f"{g} {w:.2g}" + (f" ({n})" if w else "") for g, (w, n) in worst.items())
    exact = ", ".join(f"{g} {'same' if ok else 'DIFFER'}" for g, ok in same.items())
    print(f"  {len(a['steps'])}/{len(b['steps'])} steps, "
          f"converged {a['converged']}/{b['converged']}, "
          f"{'bitwise equal' if bitwise and not problems else 'not bitwise equal'}")
    if a.get("message") != b.get("message"):
        print(f"  message differs (not judged): {str(a.get('message'))[:150]!r} vs "
              f"{str(b.get('message'))[:150]!r}")
    print(f"  max relative difference: {floats}")
    print(f"  identical: {exact}")
    for p in problems[:12]:
        print(f"  ! {p}")
    if len(problems) > 12:
        print(f"  ! ... {len(problems) - 12} more")
    return not problems


def compare(file_a: Path, file_b: Path, rtol: float) -> int:
    (ma, A), (mb, B) = ((d["meta"], d["scenes"]) for d in (json.loads(Path(f).read_text())
                                                       for f in (file_a, file_b)))
    for tag, f, m in (("A", file_a, ma), ("B", file_b, mb)):
        print(f"{tag}: {f} ({m['ranks']} ranks, {m['package']}, {m['date']})")
    if ma["ranks"] != mb["ranks"]:
        print("  note: different rank counts, not expected to be bitwise equal")
    failed = []
    for name in list(A) + [n for n in B if n not in A]:
        print(name)
        if name not in A or name not in B:
            print(f"  ! only in {'A' if name in A else 'B'}")
            failed.append(name)
        elif not compare_scene(A[name], B[name], rtol):
            failed.append(name)
    print(f"{len(failed)} of {len(set(A) | set(B))} scenes differ (rtol {rtol:g})"
          + (": " + ", ".join(failed) if failed else ""))
    return 1 if failed else 0


def variants(folder: Path) -> None:
    """Write VARIANTS as TOML files (from this checkout's demos/scenes, by the cwd)."""
    folder.mkdir(parents=True, exist_ok=True)
    for name, (stem, edits) in VARIANTS.items():
        text = Path(f"demos/scenes/{stem}.toml").read_text()
        for old, new in edits:
            assert text.count(old) == 1, f"{stem}: {old!r} not found once"
            text = text.replace(old, new)
        (folder / f"{name}.toml").write_text(text)
        print(folder / f"{name}.toml")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    r = sub.add_parser("run", help="solve scenes, write their fingerprints")
    r.add_argument("out", type=Path)
    r.add_argument("scenes", nargs="+")
    r.add_argument("--steps", type=int, default=None, help="only the first N load steps")
    c = sub.add_parser("compare", help="compare two fingerprint files")
    c.add_argument("a", type=Path)
    c.add_argument("b", type=Path)
    c.add_argument("--rtol", type=float, default=1e-12)
    v = sub.add_parser("variants", help="write the test variants of the demo scenes")
    v.add_argument("folder", type=Path)
    args = ap.parse_args()
    if args.cmd == "run":
        run(args.out, args.scenes, args.steps)
    elif args.cmd == "variants":
        variants(args.folder)
    else:
        return compare(args.a, args.b, args.rtol)
    return 0


if __name__ == "__main__":
    sys.exit(main())
