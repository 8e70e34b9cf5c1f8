"""The hostile inputs (issue 18): scenes, files, paths, checkpoints, signals and faults a
hostile user can hand to ``fenicsx-mortar``, each with the outcome it must get.

A :class:`Case` says how to lay its inputs out in a fresh directory D (``D/scene.toml``,
extra files, a donor run to restart from), the command line (``{scene}``, ``{out}`` =
``D/out`` and ``{dir}`` = D are filled in; the working directory is ``D/work``), and what
must come out: the exit code, a word of the message (the key or file at fault), and for some
cases more (summary.json untouched, a warning recorded). Every case also must print no
traceback and write nothing outside ``D/out``. ``stage = "scene"`` cases must be refused
before meshing starts.

Used by tests/test_hostile.py (the assertions, run by ``make test``) and by
tests/hostile/outcomes.py (the table of outcomes by kind, on any version of the code).
"""
from __future__ import annotations

import copy
import json
import math
import os
import re
import shutil
import signal
import subprocess
import sys
import time
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np

from ._toml import dumps

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]
MESHES = HERE / "meshes"
NAN, INF = math.nan, math.inf
DELETE = object()
#: the block on a slab of tests/bad_input/_base.toml: 2 steps, ~1 s
BASE = tomllib.loads((ROOT / "tests/bad_input/_base.toml").read_text())
#: a unit square from a mesh file (tests/hostile/meshes/square.msh, 4 quadrilaterals)
SQUARE = {
    "title": "square from a file",
    "mesh": {"file": "square.msh"},
    "bodies": [{"name": "block", "material": {"model": "neo-hooke", "E": 1000.0, "nu": 0.3}}],
    "dirichlet": [{"boundary": "bottom", "x": 0.0, "y": 0.0}],
    "pressures": [{"boundary": "top", "value": 10.0}],
    "steps": {"count": 1},
    "output": {"xdmf": False, "plots": False},
}
#: a generator-made block (meshes/block.py), for its parameters
BLOCK = {**copy.deepcopy(SQUARE), "mesh": {"generator": "block", "params": {"nx": 2, "ny": 2}}}


def edit(doc: dict, *changes) -> dict:
    """A deep copy of ``doc`` with ``(path, value)`` changes: ``"bodies[0].material.E"``;
    value DELETE removes the key; a path ending in ``[+]`` appends to a list."""
    doc = copy.deepcopy(doc)
    for path, value in changes:
        value = value if value is DELETE else copy.deepcopy(value)
        parts = re.findall(r"[^.\[\]]+|\[\d+\]|\[\+\]", path)
        node = doc
        for p in parts[:-1]:
            node = node[int(p[1:-1])] if p.startswith("[") else node.setdefault(p, {})
        last = parts[-1]
        if last == "[+]":
            node.append(value)
        elif last.startswith("["):
            if not isinstance(node, list):   # an index into a table made on the way
                raise TypeError(f"{path}: not a list")
            node[int(last[1:-1])] = value
        elif value is DELETE:
            del node[last]
        else:
            node[last] = value
    return doc


def base(*changes) -> dict:
    return edit(BASE, *changes)


@dataclass
class Case:
    id: str
    expect: int                           # exit code
    key: str                              # must be in the message (stderr; stdout too for 0/1)
    scene: dict | str | bytes | None = None
    argv: tuple[str, ...] = ("run", "{scene}", "--out", "{out}")
    files: dict = field(default_factory=dict)     # name in D -> Path (copied), str or bytes
    prepare: Callable | None = None       # prepare(D, donors) lays out more inputs
    check: Callable | None = None         # check(D, stdout, stderr) -> what is wrong, or ""
    stage: str = "scene"                  # "scene": refused before meshing; "mesh"; "run"
    hazard: str = "wrong"                 # an exit 0 would be: a "wrong" answer, the value
    #                                       "ignored", or a value "unchecked" (unbounded in
    #                                       memory or time, an unsafe name, an unverified file)
    mode: str = "inproc"                  # "inproc" (main(argv)), "process", "mpi"
    ranks: int = 1
    sender: Callable | None = None        # process mode: sender(proc, D) while it runs
    fault: bool = False                   # run through tests/hostile/_faults.py (full disk)
    env: dict = field(default_factory=dict)  # process mode: more environment ({dir} = D;
    #                                           a value None unsets the variable)
    timeout: float = 60.0
    stdout: str | None = None             # process mode: stdout to this file (/dev/full)

    def write_inputs(self, d: Path, donors) -> None:
        (d / "work").mkdir(parents=True, exist_ok=True)
        if isinstance(self.scene, dict):
            (d / "scene.toml").write_text(dumps(self.scene))
        elif isinstance(self.scene, str):
            (d / "scene.toml").write_text(self.scene)
        elif isinstance(self.scene, bytes):
            (d / "scene.toml").write_bytes(self.scene)
        for name, content in self.files.items():
            target = d / name
            if isinstance(content, Path):
                shutil.copyfile(content, target)
            elif isinstance(content, bytes):
                target.write_bytes(content)
            else:
                target.write_text(content)
        if self.prepare is not None:
            self.prepare(d, donors)

    def args(self, d: Path) -> list[str]:
        return [a.format(scene=d / "scene.toml", out=d / "out", dir=d) for a in self.argv]


# ----------------------------------------------------------------------------- helpers


def square(*changes, mesh: str = "square.msh") -> tuple[dict, dict]:
    """(scene, files) of SQUARE on the mesh file ``mesh`` (from tests/hostile/meshes)."""
    scene = edit(SQUARE, ("mesh.file", mesh), *changes)
    return scene, {mesh: MESHES / mesh}


def square_case(id: str, expect: int, key: str, *changes, mesh: str = "square.msh",
                **kw) -> Case:
    """A case of SQUARE on the mesh file ``mesh`` with ``changes``."""
    scene, files = square(*changes, mesh=mesh)
    return Case(id, expect, key, scene, files=files, **kw)


def mesh_case(id: str, key: str, mesh: str, **kw) -> Case:
    return square_case(id, 2, key, mesh=mesh, stage="mesh", **kw)


def copy_donor(name: str = "base"):
    """prepare: D/out is a copy of the donor run ``name`` (a finished run's directory)."""
    def prepare(d: Path, donors) -> None:
        shutil.copytree(donors.get(name), d / "out")
    return prepare


def then(*steps):
    def prepare(d: Path, donors) -> None:
        for s in steps:
            s(d, donors)
    return prepare


def rewrite_checkpoint(change: Callable[[dict], dict]):
    """prepare step: D/out/checkpoint.npz rewritten with ``change(arrays)``."""
    def step(d: Path, donors) -> None:
        path = d / "out/checkpoint.npz"
        with np.load(path) as f:
            arrays = {k: f[k] for k in f.files}
        np.savez(path, **change(arrays))
    return step


def write(rel: str, content: bytes):
    def step(d: Path, donors) -> None:
        (d / rel).write_bytes(content)
    return step


def summary_unchanged(d: Path, out: str, err: str) -> str:
    """check: the restart refused must leave the donor's summary.json as it was."""
    now = (d / "out/summary.json").read_bytes()
    was = (d / "summary.before").read_bytes()
    return "" if now == was else "summary.json was overwritten"


def keep_summary(step):
    """prepare: ``step``, then remember summary.json (for :func:`summary_unchanged`)."""
    def prepare(d: Path, donors) -> None:
        step(d, donors)
        shutil.copyfile(d / "out/summary.json", d / "summary.before")
    return prepare


def checkpoint_case(id: str, *steps, key: str = "checkpoint.npz", donor: str = "base",
                    **kw) -> Case:
    prep = keep_summary(then(copy_donor(donor), *steps))
    return Case(id, 2, key, None, argv=("run", "--restart", "{out}"), prepare=prep,
                check=summary_unchanged, stage="mesh", **kw)


def readonly_dir(d: Path, donors) -> None:
    """prepare: D/ro a directory this process cannot write into: mode 0555, or for root (who
    writes anyway) a read-only tmpfs; skipped where neither works."""
    ro = d / "ro"
    ro.mkdir()
    if os.geteuid() != 0:
        ro.chmod(0o555)
        return
    proc = subprocess.run(["mount", "-t", "tmpfs", "-o", "ro,size=64k", "tmpfs", str(ro)],
                          capture_output=True)
    if proc.returncode != 0:
        raise Skip("no read-only directory: not root-free and cannot mount")


def small_disk(d: Path, donors, size: str = "64k") -> None:
    """prepare: D/out a 64 KiB (``size``) tmpfs, which the run's writes fill up for real
    (root only)."""
    (d / "out").mkdir()
    proc = subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={size}", "tmpfs", str(d / "out")],
                          capture_output=True) if os.geteuid() == 0 else None
    if proc is None or proc.returncode != 0:
        raise Skip("cannot mount a small file system here (needs root)")


def unmount(d: Path) -> None:
    """Undo what a case's preparation left running or mounted: a lock it holds, a run it
    started in the background (ended), the read-only and small file systems."""
    fd = _HELD.pop(d, None)
    if fd is not None:
        os.close(fd)
    proc = _BACKGROUND.pop(d, None)
    if proc is not None and proc.poll() is None:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()
    for place in (d / "ro", d / "out"):
        if os.path.ismount(place):
            subprocess.run(["umount", str(place)], check=False)


#: locks and background runs a case's preparation holds, by case directory
_HELD: dict[Path, int] = {}
_BACKGROUND: dict[Path, subprocess.Popen] = {}


def hdf5_fails_first() -> None:
    """prepare: skip where the HDF5 write cannot fail first. With PyPI's DOLFINx 0.11 wheel
    the XDMF writes went through on every disk size from 9 to 48 KiB and the checkpoint
    failed first (one line naming it: as with XDMF off); on 8 KiB and less its HDF5, built
    with assertions, aborts inside the file creation."""
    import importlib.metadata
    try:
        importlib.metadata.version("dolfinx-solver-real")
    except importlib.metadata.PackageNotFoundError:
        return
    raise Skip("PyPI's DOLFINx wheel: no disk size on which its HDF5 write fails first "
               "(hdf5_fails_first)")


class Skip(Exception):
    """This machine cannot lay the case out (e.g. no way to make a read-only directory)."""


def fifo(rel: str):
    def step(d: Path, donors) -> None:
        os.mkfifo(d / rel)
    return step


def mkdir(rel: str):
    def step(d: Path, donors) -> None:
        (d / rel).mkdir(parents=True)
    return step


def in_summary(word: str):
    def check(d: Path, out: str, err: str) -> str:
        s = json.loads((d / "out/summary.json").read_text())
        text = json.dumps(s.get("warnings", []))
        if word in text and word in out:
            return ""
        return f"no {word!r} warning in the log and summary.json"
    return check


def full_disk_kept(d: Path, out: str, err: str) -> str:
    """check: after the disk filled up, no temporary file is left and summary.json and the
    checkpoint still hold the last good (first) step."""
    o = d / "out"
    left = [p.name for p in o.iterdir() if p.name.startswith(".")]
    if left:
        return f"temporary files left: {left}"
    s = json.loads((o / "summary.json").read_text())
    with np.load(o / "checkpoint.npz") as f:
        step = int(f["step"])
    if len(s["steps"]) != 1 or step != 1:
        return f"summary.json has {len(s['steps'])} steps, the checkpoint step {step} (want 1, 1)"
    return ""


def scene_json_whole(d: Path, out: str, err: str) -> str:
    """check: scene.json, written before the disk filled up, is whole (or absent)."""
    f = d / "out" / "scene.json"
    if f.exists():
        json.loads(f.read_text())
    left = [p.name for p in (d / "out").rglob(".*")]
    return f"temporary files left: {left}" if left else ""


def full_disk_consistent(d: Path, out: str, err: str) -> str:
    """check: on a disk that filled up no temporary file is left, and summary.json and the
    checkpoint are whole and hold the same step, or the checkpoint one more (summary.json
    is written last in a step)."""
    o = d / "out"
    left = [p.name for p in o.rglob(".*")]
    if left:
        return f"temporary files left: {left}"
    steps = len(json.loads((o / "summary.json").read_text())["steps"])
    with np.load(o / "checkpoint.npz") as f:
        step = int(f["step"])
    if steps < 1 or step - steps not in (0, 1):
        return f"summary.json has {steps} steps, the checkpoint step {step}"
    return ""


def signal_after(sig: signal.Signals, seconds: float, marker: str = "effect:"):
    """sender: ``sig`` once ``marker`` was printed (start-up is under way) plus ``seconds``."""
    def send(proc: subprocess.Popen, d: Path) -> None:
        deadline = time.time() + 60
        seen = ""
        while marker not in seen and time.time() < deadline and proc.poll() is None:
            line = proc.stdout.readline()
            seen += line
            if not line:
                time.sleep(0.02)
        time.sleep(seconds)
        if proc.poll() is None:
            proc.send_signal(sig)
        proc.seen = seen
    return send


# --------------------------------------------------------------------------- the cases

CONTACT = "contacts[0]"
COULOMB_LAW = (f"{CONTACT}.friction.law", "coulomb")
CURVE = ("curves", {"c": {"t": [0.0, 1.0, 2.0], "value": [0.0, 1.0, 1.0]}})
PENALTY = (f"{CONTACT}.enforcement", {"type": "penalty"})

CASES: list[Case] = []


def add(*cases: Case) -> None:
    CASES.extend(cases)


def value(id: str, key: str, *changes, hazard: str = "wrong", stage: str = "scene",
          expect: int = 2) -> Case:
    """A scene of BASE with ``changes`` whose message must name ``key``."""
    return Case(id, expect, key, base(*changes), hazard=hazard, stage=stage)


# -- floats that are not finite (TOML has nan and inf) ------------------------------------
add(
    value("E_nan", "bodies[0].material.E", ("bodies[0].material.E", NAN)),
    value("E_inf", "bodies[0].material.E", ("bodies[0].material.E", INF)),
    value("E_minus_inf", "bodies[1].material.E", ("bodies[1].material.E", -INF)),
    value("nu_nan", "bodies[0].material.nu", ("bodies[0].material.nu", NAN)),
    value("nu_minus_inf", "bodies[0].material.nu", ("bodies[0].material.nu", -INF)),
    value("pressure_nan", "pressures[0].value", ("pressures[0].value", NAN)),
    value("pressure_inf", "pressures[0].value", ("pressures[0].value", INF)),
    value("pressure_minus_inf", "pressures[0].value", ("pressures[0].value", -INF)),
    value("traction_nan", "tractions[0].value[0]",
          ("tractions", [{"boundary": "block_right", "value": [NAN, 0.0]}])),
    value("traction_inf", "tractions[0].value[1]",
          ("tractions", [{"boundary": "block_right", "value": [0.0, INF]}])),
    value("dirichlet_x_nan", "dirichlet[0].x", ("dirichlet[0].x", NAN)),
    value("dirichlet_y_inf", "dirichlet[0].y", ("dirichlet[0].y", INF)),
    value("point_nan", "dirichlet[2].point[0]",
          ("dirichlet[+]", {"point": [NAN, 0.0], "body": "slab", "x": 0.0})),
    value("motion_center_inf", "dirichlet[1].motion.center[0]",
          ("dirichlet[1]", {"boundary": "block_left", "motion": {"center": [INF, 0.0]}})),
    value("motion_translation_nan", "dirichlet[1].motion.translation[1]",
          ("dirichlet[1]", {"boundary": "block_left", "motion": {"translation": [0.0, NAN]}})),
    value("motion_rotation_inf", "dirichlet[1].motion.rotation",
          ("dirichlet[1]", {"boundary": "block_left", "motion": {"rotation": INF}})),
    value("curve_t_nan", "curves.c.t[1]", CURVE, ("curves.c.t", [0.0, NAN, 2.0]),
          ("pressures[0].curve", "c")),
    value("curve_t_inf", "curves.c.t[2]", CURVE, ("curves.c.t", [0.0, 1.0, INF]),
          ("pressures[0].curve", "c")),
    value("curve_value_inf", "curves.c.value[1]", CURVE, ("curves.c.value", [0.0, INF, 1.0]),
          ("pressures[0].curve", "c")),
    # the same pair twice: redundant multipliers, a singular system (it said "a body or a
    # direction left free?")
    value("pair_twice", "contacts[1]", ("contacts", [
        {"name": "c", "slave": "block_bottom", "master": "slab_top"},
        {"name": "c2", "slave": "block_bottom", "master": "slab_top"}])),
    # no update allowed: every penalty step failed after 6 cuts ("KKT not reached in 0")
    value("max_augmentations_zero", f"{CONTACT}.enforcement.max_augmentations",
          (f"{CONTACT}.enforcement", {"type": "penalty", "epsilon": 1e7,
                                      "max_augmentations": 0})),
    # the same pair with the roles swapped: cut 6 times, then the active-set cycling guard
    value("pair_twice_swapped", "contacts[1]", ("contacts", [
        {"name": "c", "slave": "block_bottom", "master": "slab_top"},
        {"name": "c2", "slave": "slab_top", "master": "block_bottom"}])),
    # two surfaces of one body: DIVERGED_FNORM_NAN after 6 cuts, the cause not named
    value("self_contact", "same body", (f"{CONTACT}.master", "block_top"), stage="mesh"),
    # SuperLU_dist and hypre cannot take the multipliers' zero pivots (DIVERGED_PCSETUP_FAILED
    # without a word on the solver)
    value("superlu_dist_with_multipliers", "solver.linear_solver",
          ("solver.linear_solver", "superlu_dist")),
    # (with the dual basis, the mortar default, "gmres-hypre" condenses the multipliers:
    # docs/condensation.md; the standard basis keeps the saddle point)
    value("gmres_hypre_with_multipliers", "solver.linear_solver",
          ("solver.linear_solver", "gmres-hypre"), (f"{CONTACT}.basis", "standard")),
    # t − t_prev overflows: the curve would be 0 inside the interval, silently
    value("curve_t_span_overflows", "curves.c.t", CURVE,
          ("curves.c.t", [-1.7e308, 1.7e308]), ("curves.c.value", [0.0, 1.0]),
          ("pressures[0].curve", "c")),
    value("E_integer_beyond_float", "bodies[0].material.E", ("bodies[0].material.E", 10**400)),
    value("curve_value_nan_unused", "curves.c.value[2]", CURVE,
          ("curves.c.value", [0.0, 1.0, NAN]), hazard="ignored"),
    value("epsilon_inf", f"{CONTACT}.enforcement.epsilon",
          (f"{CONTACT}.enforcement", {"type": "penalty", "epsilon": INF})),
    value("epsilon_nan", f"{CONTACT}.enforcement.epsilon",
          (f"{CONTACT}.enforcement", {"epsilon": NAN})),
    value("tolerance_inf", f"{CONTACT}.enforcement.tolerance",
          (f"{CONTACT}.enforcement", {"tolerance": INF})),
    value("tolerance_nan", f"{CONTACT}.enforcement.tolerance",
          (f"{CONTACT}.enforcement", {"tolerance": NAN})),
    value("mu_inf", f"{CONTACT}.friction.mu", (f"{CONTACT}.friction.mu", INF), COULOMB_LAW),
    value("mu_nan", f"{CONTACT}.friction.mu", (f"{CONTACT}.friction.mu", NAN), COULOMB_LAW),
    value("search_radius_nan", f"{CONTACT}.search_radius", (f"{CONTACT}.search_radius", NAN)),
    value("search_radius_inf", f"{CONTACT}.search_radius", (f"{CONTACT}.search_radius", INF),
          hazard="unchecked"),
    value("steps_end_nan", "steps.end", ("steps.end", NAN)),
    value("steps_end_inf", "steps.end", ("steps.end", INF)),
    value("steps_times_nan", "steps.times[0]", ("steps", {"times": [NAN]})),
    value("steps_times_inf", "steps.times[1]", ("steps", {"times": [0.5, INF]})),
    value("min_increment_nan", "steps.min_increment", ("steps.min_increment", NAN)),
    value("min_increment_inf", "steps.min_increment", ("steps.min_increment", INF),
          hazard="ignored"),
    value("atol_inf", "solver.atol", ("solver", {"atol": INF})),
    value("atol_nan", "solver.atol", ("solver", {"atol": NAN})),
    value("rtol_inf", "solver.rtol", ("solver", {"rtol": INF}), hazard="ignored"),
    value("rtol_nan", "solver.rtol", ("solver", {"rtol": NAN})),
    value("petsc_value_nan", "-snes_linesearch_damping",
          ("solver", {"petsc": {"-snes_linesearch_damping": NAN}})),
    value("mesh_param_nan", "mesh.params.slab_nx", ("mesh.params.slab_nx", NAN)),
)

# -- numbers out of range; upper bounds where a value drives memory or time --------------
add(
    value("tolerance_one", f"{CONTACT}.enforcement.tolerance",
          (f"{CONTACT}.enforcement", {"tolerance": 1.0})),
    value("tolerance_below_roundoff", f"{CONTACT}.enforcement.tolerance",
          (f"{CONTACT}.enforcement", {"tolerance": 1e-300}), hazard="unchecked"),
    value("search_radius_zero", f"{CONTACT}.search_radius", (f"{CONTACT}.search_radius", 0.0),
          hazard="ignored"),
    value("search_radius_negative", f"{CONTACT}.search_radius",
          (f"{CONTACT}.search_radius", -1.0)),
    value("n_gauss_huge", f"{CONTACT}.n_gauss", (f"{CONTACT}.n_gauss", 10 ** 9),
          hazard="unchecked"),
    value("n_gauss_max_int", f"{CONTACT}.n_gauss", (f"{CONTACT}.n_gauss", 2 ** 63 - 1),
          hazard="unchecked"),
    value("max_augmentations_negative", f"{CONTACT}.enforcement.max_augmentations",
          (f"{CONTACT}.enforcement", {"max_augmentations": -1})),
    value("max_augmentations_huge", f"{CONTACT}.enforcement.max_augmentations",
          (f"{CONTACT}.enforcement", {"max_augmentations": 10 ** 9}), hazard="unchecked"),
    value("steps_count_huge", "steps.count", ("steps.count", 10 ** 12), hazard="unchecked"),
    value("steps_count_max_int", "steps.count", ("steps.count", 2 ** 63 - 1), hazard="unchecked"),
    value("steps_times_too_many", "steps.times",
          ("steps", {"times": [(k + 1) / 100001 for k in range(100001)]}), hazard="unchecked"),
    value("max_cuts_huge", "steps.max_cuts", ("steps.max_cuts", 10 ** 9), hazard="unchecked"),
    value("min_increment_below_roundoff", "steps.min_increment",
          ("steps.min_increment", 1e-300), ("steps.max_cuts", 50), hazard="unchecked"),
    value("rtol_above_one", "solver.rtol", ("solver", {"rtol": 2.0}), hazard="ignored"),
    value("max_iterations_huge", "solver.max_iterations", ("solver", {"max_iterations": 10 ** 9}),
          hazard="unchecked"),
    value("quadrature_degree_huge", "solver.quadrature_degree",
          ("solver", {"quadrature_degree": 1000}), hazard="unchecked"),
    value("quadrature_degree_40", "solver.quadrature_degree",
          ("solver", {"quadrature_degree": 40}), hazard="unchecked"),
    value("atol_huge", "solver.atol", ("solver", {"atol": 1e30}), stage="run"),
    value("atol_below_roundoff", "solver.atol", ("solver", {"atol": 1e-300}), stage="run"),
    # the load comes after the first target: the check must see the last one (it looked
    # at the first only and passed u = 0 as the answer under the load)
    value("atol_above_late_load", "solver.atol",
          ("curves", {"late": {"t": [0.0, 1.0, 2.0], "value": [0.0, 0.0, 1.0]}}),
          ("pressures[0].value", 1e-4), ("pressures[0].curve", "late"),
          ("steps", {"times": [1.0, 2.0]}), ("solver", {"atol": 1e-4}), stage="run"),
    # a tiny first step under a full load later: the default atol is right for the path
    Case("atol_tiny_first_steps", 0, "done", base(("steps", {"times": [1e-9, 2e-9, 1.0]})),
         stage="run"),
)

# -- mesh generator parameters: cell counts estimated before meshing; gmsh's limits -------
GEN = [
    ("block_huge", "block", {"nx": 10 ** 6, "ny": 10 ** 6}),
    ("block_width_tiny", "block", {"width": 1e-300}),
    ("block_far_away", "block", {"x0": 1e300}),
    ("block_width_nan", "block", {"width": NAN}),
    ("block_height_inf", "block", {"height": INF}),
    ("block_on_slab_huge", "block_on_slab", {"block_nx": 10 ** 7}),
    ("block_on_slab_max_int", "block_on_slab", {"slab_nx": 2 ** 62}),
    ("hertz_tiny_elements", "hertz", {"h_contact": 1e-6}),
    ("hertz_tiny_disk", "hertz", {"R": 1e-3}),
    ("hertz_elements_bigger_than_bodies", "hertz", {"h_contact": 2.0, "h_far": 3.0}),
    ("hertz_h_nan", "hertz", {"h_contact": NAN}),
    ("half_rings_huge", "half_rings", {"fixed_nc": 10 ** 7}),
    ("ironing_huge", "ironing", {"nx": 10 ** 5, "ny": 10 ** 4}),
    ("patch_test_huge", "patch_test", {"lower_nx": 4 * 10 ** 6}),
    ("stacked_blocks_huge", "stacked_blocks", {"lower_nx": 10 ** 7}),
    ("stacked_blocks_gap_huge", "stacked_blocks", {"gap": 1e300}),
]
add(*(Case(f"gen_{id}", 2, "mesh.params", edit(BLOCK, ("mesh", {"generator": g, "params": p})))
      for id, g, p in GEN))

# -- PETSc options: unknown, rejected, unused, writing files, replacing the convergence rule
PETSC = [
    ("unknown_option", "-snes_foo", {"-snes_foo": 1}, "ignored"),
    ("unknown_type", "-ksp_type", {"-ksp_type": "nonsense"}, "wrong"),
    ("unknown_pc", "-pc_type", {"-pc_type": "bogus"}, "wrong"),
    ("not_an_integer", "-snes_max_funcs", {"-snes_max_funcs": "abc"}, "wrong"),
    ("unknown_line_search", "-snes_linesearch_type", {"-snes_linesearch_type": "xyz"}, "wrong"),
    ("never_read", "-mat_mumps_icntl_99", {"-mat_mumps_icntl_99": 50}, "ignored"),
    ("view_never_read", "-snes_view", {"-snes_view": True}, "ignored"),
    # a multigrid level option with the default solver (MUMPS at this size): never read
    ("mg_levels_without_multigrid", "-mg_levels_ksp_max_it", {"-mg_levels_ksp_max_it": 1},
     "ignored"),
    ("viewer_file_outside", "-snes_monitor", {"-snes_monitor": "ascii:../outside.txt"}, "wrong"),
    ("viewer_binary_file", "-ksp_view_mat", {"-ksp_view_mat": "binary:mat.bin"}, "wrong"),
    ("x_window", "-snes_monitor_lg_residualnorm", {"-snes_monitor_lg_residualnorm": True},
     "ignored"),
    ("skip_convergence_test", "-snes_convergence_test", {"-snes_convergence_test": "skip"},
     "wrong"),
    ("ksponly", "-snes_type", {"-snes_type": "ksponly"}, "wrong"),
    ("key_with_space", "-ksp_type gmres", {"-ksp_type gmres": True}, "ignored"),
    # a bare viewer type writes its default file (binaryoutput, output.h5) into the working
    # directory; -ksp_monitor binary crashed PETSc (SEGV)
    ("viewer_binary_bare", "-ksp_monitor", {"-ksp_monitor": "binary"}, "crash"),
    ("viewer_hdf5_bare", "-snes_monitor", {"-snes_monitor": "hdf5"}, "wrong"),
    ("viewer_mat_binary_bare", "-ksp_view_mat", {"-ksp_view_mat": "binary"}, "wrong"),
    # MUMPS writes its messages to Fortran unit 10: a file fort.10 in the working directory
    ("mumps_stream_unit", "-mat_mumps_icntl_1", {"-mat_mumps_icntl_1": 10,
                                                 "-mat_mumps_icntl_4": 3}, "wrong"),
    # the Newton loop's limit and tolerances are the scene's: these were silently overridden
    ("snes_max_it", "solver.max_iterations", {"-snes_max_it": 100000}, "ignored"),
    ("snes_atol", "solver.atol", {"-snes_atol": 1e-3}, "ignored"),
    # PETSc's LU instead of MUMPS with multipliers: zero pivots (the linear_solver rule)
    ("lu_without_pivoting", "-pc_factor_mat_solver_type",
     {"-pc_factor_mat_solver_type": "petsc"}, "wrong"),
]
add(*(value(f"petsc_{id}", key, ("solver", {"petsc": opts}), hazard=hz)
      for id, key, opts, hz in PETSC))
# hypre with multipliers of the standard basis (not condensed), whatever the LU key says
add(value("petsc_hypre_despite_mumps_key", "gmres-hypre", ("solver", {
    "linear_solver": "gmres-hypre", "petsc": {"-pc_factor_mat_solver_type": "mumps"}}),
    (f"{CONTACT}.basis", "standard")))

# -- groups: empty lists, repeats, two bodies on one region, conflicting supports ----------
add(
    value("dirichlet_boundary_empty", "dirichlet[0].boundary", ("dirichlet[0].boundary", [])),
    value("pressure_boundary_empty", "pressures[0].boundary", ("pressures[0].boundary", [])),
    value("traction_boundary_empty", "tractions[0].boundary",
          ("tractions", [{"boundary": [], "value": [0.1, 0.0]}])),
    value("slave_empty", f"{CONTACT}.slave", (f"{CONTACT}.slave", [])),
    value("master_empty", f"{CONTACT}.master", (f"{CONTACT}.master", [])),
    value("pressure_boundary_repeated", "pressures[0].boundary",
          ("pressures[0].boundary", ["block_top", "block_top"])),
    value("slave_repeated", f"{CONTACT}.slave",
          (f"{CONTACT}.slave", ["block_bottom", "block_bottom"]), hazard="ignored"),
    value("dirichlet_boundary_repeated", "dirichlet[0].boundary",
          ("dirichlet[0].boundary", ["slab_bottom", "slab_bottom"]), hazard="ignored"),
    value("two_bodies_one_region", "bodies[1].region", ("bodies[1].region", "block")),
    value("third_body_on_a_region", "bodies[2].region",
          ("bodies[+]", {"name": "again", "region": "slab",
                         "material": {"model": "svk", "E": 10.0, "nu": 0.2}})),
    value("dirichlet_conflict", "dirichlet[2].y",
          ("dirichlet[+]", {"boundary": "slab_bottom", "y": 0.1}), hazard="ignored"),
    value("no_support_in_y", "no entry prescribes y", ("dirichlet[0].y", DELETE)),
    value("no_supports", "no entry prescribes x or y", ("dirichlet", [])),
    value("region_without_body", "'slab'", ("bodies", BASE["bodies"][:1]),
          ("dirichlet", [{"boundary": "block_left", "x": 0.0},
                         {"boundary": "block_top", "y": 0.0}]), stage="mesh"),
    value("group_name_empty", "pressures[0].boundary", ("pressures[0].boundary", "")),
)

# -- names that become file names ---------------------------------------------------------
NAMES = [("traversal", "../../x"), ("slash", "sub/x"), ("dot_dot", ".."), ("empty", ""),
         ("too_long", "a" * 300), ("nul", "a\u0000b"), ("newline", "a\nb"),
         ("leading_dash", "-rf")]
add(*(value(f"pair_name_{id}", f"{CONTACT}.name", (f"{CONTACT}.name", name),
            hazard="wrong" if id == "traversal" else "unchecked") for id, name in NAMES))
add(
    value("support_name_traversal", "dirichlet[0].name", ("dirichlet[0].name", "../x"),
          hazard="unchecked"),
    value("support_name_too_long", "dirichlet[0].name", ("dirichlet[0].name", "s" * 300),
          hazard="unchecked"),
)

# -- values that would be ignored ---------------------------------------------------------
add(
    value("body_with_boundary", "dirichlet[0].body", ("dirichlet[0].body", "slab"),
          hazard="ignored"),
    value("end_with_times", "steps.end", ("steps", {"times": [0.5, 1.0], "end": 5.0}),
          hazard="ignored"),
    square_case("params_with_file", 2, "mesh.params", ("mesh.params", {"nx": 8}),
                hazard="ignored"),
    square_case("cell_with_file", 2, "mesh.cell", ("mesh.cell", "triangle"), hazard="ignored"),
)

# -- the scene file itself ----------------------------------------------------------------
BASE_TEXT = dumps(BASE)
add(
    # command-line misuse: one line too (argparse printed its usage line first)
    Case("cli_empty_out", 2, "--out", base(), argv=("run", "{scene}", "--out", ""),
         mode="process"),
    Case("cli_unknown_command", 2, "'solve'", base(), argv=("solve", "{scene}"),
         mode="process"),
    Case("cli_two_scenes", 2, "unrecognized", base(), argv=("run", "{scene}", "{scene}"),
         mode="process"),
    Case("scene_is_a_directory", 2, "sdir", None, argv=("run", "{dir}/sdir", "--out", "{out}"),
         prepare=mkdir("sdir")),
    Case("scene_dev_zero", 2, "/dev/zero", None, argv=("run", "/dev/zero", "--out", "{out}")),
    Case("scene_dev_null", 2, "/dev/null", None, argv=("run", "/dev/null", "--out", "{out}")),
    Case("scene_fifo", 2, "fifo.toml", None, argv=("run", "{dir}/fifo.toml", "--out", "{out}"),
         prepare=fifo("fifo.toml")),
    Case("scene_latin1", 2, "scene.toml", BASE_TEXT.replace("block on slab", "caf\xe9")
         .encode("latin-1")),
    Case("scene_utf16", 2, "scene.toml", BASE_TEXT.encode("utf-16")),
    # a UTF-8 byte-order mark (Windows editors) was a TOML syntax error "at line 1, column 1"
    # control characters in the title reached the terminal raw (ESC sequences, CR)
    Case("title_control_characters", 0, "fenicsx_mortar:  [2J [31mred second line carriage",
         base(("title", "\x1b[2J\x1b[31mred\nsecond line\rcarriage")), stage="run",
         hazard="unchecked"),
    Case("scene_utf8_bom", 0, "done", b"\xef\xbb\xbf" + BASE_TEXT.encode(), stage="run",
         hazard="ignored"),
    Case("scene_binary", 2, "scene.toml", bytes(range(256)) * 4),
    Case("scene_too_large", 2, "scene.toml", BASE_TEXT + "#" + "x" * (20 << 20) + "\n",
         hazard="unchecked"),
    Case("scene_missing", 2, "nowhere.toml", None,
         argv=("run", "{dir}/nowhere.toml", "--out", "{out}")),
)

# -- --out: a file, under a file, unwritable, read-only -----------------------------------
add(
    Case("out_is_a_file", 2, "--out", base(), prepare=write("out", b"not a directory")),
    Case("out_under_a_file", 2, "--out", base(), argv=("run", "{scene}", "--out", "{dir}/f/out"),
         prepare=write("f", b"a file")),
    Case("out_dev_null", 2, "--out", base(), argv=("run", "{scene}", "--out", "/dev/null")),
    # a name longer than the file system takes (ENAMETOOLONG): a traceback before
    Case("out_name_too_long", 2, "--out", base(),
         argv=("run", "{scene}", "--out", "{dir}/" + "o" * 300), mode="process"),
    Case("restart_name_too_long", 2, "--restart", None,
         argv=("run", "--restart", "{dir}/" + "r" * 300), mode="process"),
    Case("out_unwritable", 2, "--out", base(),
         argv=("run", "{scene}", "--out", "/proc/self/fm_out")),
    Case("out_read_only", 2, "--out", base(), argv=("run", "{scene}", "--out", "{dir}/ro/out"),
         prepare=readonly_dir),
)

# -- restarts and checkpoints -------------------------------------------------------------
def _truncate(d: Path, donors) -> None:
    p = d / "out/checkpoint.npz"
    p.write_bytes(p.read_bytes()[: p.stat().st_size // 2])


def _other_run(d: Path, donors) -> None:
    shutil.copyfile(donors.get("base") / "checkpoint.npz", d / "out/checkpoint.npz")


def _no_fingerprint(a: dict) -> dict:
    return {k: v for k, v in a.items() if not k.startswith("fingerprint")}


def _nan_u(a: dict) -> dict:
    a["u"] = a["u"].copy()
    a["u"].flat[3] = np.nan
    return a


def _ckpt_dir(d: Path, donors) -> None:
    p = d / "out/checkpoint.npz"
    p.unlink()
    p.mkdir()


def _run_then_move_a_node(d: Path, donors) -> None:
    """A run on square.msh in D/out, then the mesh file changes (one node moved)."""
    donors.run_in(d, "run", str(d / "scene.toml"), "--out", str(d / "out"))
    mesh = d / "square.msh"
    text = mesh.read_text()
    assert "\n0.5 0 0\n" in text
    mesh.write_text(text.replace("\n0.5 0 0\n", "\n0.45 0 0\n", 1))
    shutil.copyfile(d / "out/summary.json", d / "summary.before")


def _run_then_regroup(d: Path, donors) -> None:
    """A run on square.msh in D/out, then the mesh file's left side joins the "bottom"
    group (the support): the same nodes and cells, another problem."""
    donors.run_in(d, "run", str(d / "scene.toml"), "--out", str(d / "out"))
    mesh = d / "square.msh"
    text = mesh.read_text()
    left = " 1 5 2 4 -1 \n"
    assert left in text
    mesh.write_text(text.replace(left, " 1 2 2 4 -1 \n", 1))
    shutil.copyfile(d / "out/summary.json", d / "summary.before")


add(
    Case("restart_with_a_scene", 2, "--restart", base(),
         argv=("run", "{scene}", "--restart", "{out}"), prepare=copy_donor(), hazard="ignored"),
    Case("restart_with_out", 2, "--out", None,
         argv=("run", "--restart", "{out}", "--out", "{dir}/other"), prepare=copy_donor(),
         hazard="ignored"),
    Case("restart_missing_dir", 2, "nothing", None, argv=("run", "--restart", "{dir}/nothing")),
    checkpoint_case("restart_no_scene_json", lambda d, _: (d / "out/scene.json").unlink(),
                    key="scene.json"),
    checkpoint_case("restart_scene_json_corrupt", write("out/scene.json", b"{\"mesh\": "),
                    key="scene.json"),
    checkpoint_case("restart_scene_json_latin1", write("out/scene.json", b"{\"title\": \"\xe9\"}"),
                    key="scene.json"),
    checkpoint_case("checkpoint_truncated", _truncate),
    checkpoint_case("checkpoint_garbage", write("out/checkpoint.npz", bytes(range(256)) * 16)),
    checkpoint_case("checkpoint_empty", write("out/checkpoint.npz", b"")),
    checkpoint_case("checkpoint_is_a_directory", _ckpt_dir),
    checkpoint_case("checkpoint_missing_arrays", rewrite_checkpoint(lambda a: {"u": a["u"]})),
    checkpoint_case("checkpoint_nan", rewrite_checkpoint(_nan_u)),
    checkpoint_case("checkpoint_wrong_shape",
                    rewrite_checkpoint(lambda a: {**a, "u": a["u"][:-1]})),
    checkpoint_case("checkpoint_steps_not_json",
                    rewrite_checkpoint(lambda a: {**a, "steps": np.array("[{")})),
    checkpoint_case("checkpoint_without_fingerprint", rewrite_checkpoint(_no_fingerprint),
                    hazard="unchecked"),
    checkpoint_case("checkpoint_of_another_run", _other_run, donor="base_p05"),
    square_case("checkpoint_of_another_mesh", 2, "mesh", argv=("run", "--restart", "{out}"),
                prepare=_run_then_move_a_node, check=summary_unchanged, stage="mesh"),
    # the fingerprint knew nodes and cells only: a boundary moved to another group was
    # restarted as the old problem's continuation (exit 0, a mix of two problems)
    square_case("checkpoint_of_regrouped_mesh", 2, "mesh", argv=("run", "--restart", "{out}"),
                prepare=_run_then_regroup, check=summary_unchanged, stage="mesh"),
    Case("restart_control", 0, "done", None, argv=("run", "--restart", "{out}"),
         prepare=copy_donor(), stage="run"),
)

# -- mesh files ---------------------------------------------------------------------------
add(
    mesh_case("mesh_mixed_cells", "mixed.msh", "mixed.msh"),
    mesh_case("mesh_second_order_triangles", "tri6.msh", "tri6.msh"),
    mesh_case("mesh_second_order_quads", "quad9.msh", "quad9.msh"),
    mesh_case("mesh_serendipity_quads", "quad8.msh", "quad8.msh"),
    mesh_case("mesh_no_2d_cells", "lines_only.msh", "lines_only.msh"),
    mesh_case("mesh_points_only", "points_only.msh", "points_only.msh"),
    mesh_case("mesh_empty_file", "empty.msh", "empty.msh"),
    mesh_case("mesh_garbage", "garbage.msh", "garbage.msh"),
    mesh_case("mesh_truncated", "truncated.msh", "truncated.msh"),
    mesh_case("mesh_overlapping_groups", "overlap.msh", "overlap.msh"),
    mesh_case("mesh_zero_area_cell", "zero_area.msh", "zero_area.msh"),
    # one cell listed twice: a PETSc SEGV, then a process that SIGTERM did not end
    mesh_case("mesh_duplicate_cell", "listed more than once", "duplicate_cell.msh"),
    # "bottom" and "base" on one curve: the Dirichlet boundary silently lost its facets to
    # the other group (a contact surface shrank so: normal force 33.0 against 49.7)
    mesh_case("mesh_curve_in_two_groups", "'bottom' and 'base'", "shared_curve.msh"),
    # a boundary group off the cells: DOLFINx 0.5 crashed (free(): invalid pointer)
    mesh_case("mesh_curve_off_the_cells", "'floating'", "floating.msh"),
    square_case("mesh_curve_off_the_cells_as_master", 2, "'floating'",
                ("contacts", [{"name": "f", "slave": "top", "master": "floating"}]),
                mesh="floating.msh", stage="mesh"),
    Case("mesh_is_a_directory", 2, "mdir", square()[0] | {"mesh": {"file": "mdir"}},
         prepare=mkdir("mdir")),
    Case("mesh_dev_zero", 2, "/dev/zero", square()[0] | {"mesh": {"file": "/dev/zero"}}),
    Case("mesh_fifo", 2, "fifo.msh", square()[0] | {"mesh": {"file": "fifo.msh"}},
         prepare=fifo("fifo.msh")),
    square_case("mesh_control", 0, "done", stage="run"),
    # a quadrilateral with a reentrant corner has positive area but J < 0 at that corner
    mesh_case("mesh_folded_cell", "folded cell", "folded.msh"),
    # a pressure on a curve inside the body: ds never saw it, the load was dropped (exit 0)
    square_case("mesh_pressure_inside", 2, "'cut'", ("pressures[0].boundary", "cut"),
                mesh="interior_curve.msh", stage="mesh"),
    # one name on two curve groups: gmsh names one, the support covered half the bottom
    mesh_case("mesh_name_on_two_groups", "'bottom'", "name_twice.msh"),
    # 3-node boundary lines beside linear cells: DOLFINx dropped them, "has no facets"
    Case("mesh_line3_curves", 2, "Line 3", (HERE / "meshes/line3_curves.toml").read_text(),
         files={"mesh.msh": MESHES / "line3_curves.msh"}, stage="mesh"),
    # what gmsh itself writes when a name was given twice: a nameless group, warned of
    square_case("mesh_nameless_group", 0, "done", mesh="nameless_curve.msh", stage="run",
                mode="process", check=lambda d, out, err: "" if "have no name" in err
                else "no warning of the nameless group"),
)

# -- mesh files are data, never programs (issue 28) -----------------------------------------
def _script(rel: str, body: str):
    """prepare: D/rel holds gmsh script text; ``{dir}`` in it is D (a command would write
    D/pwned there)."""
    def step(d: Path, donors) -> None:
        (d / rel).write_text(body.format(dir=d))
    return step


def _sparse(rel: str, size: int):
    """prepare: D/rel is a sparse file of ``size`` zero bytes (no disk used)."""
    def step(d: Path, donors) -> None:
        with open(d / rel, "wb") as f:
            f.truncate(size)
    return step


def no_command_ran(d: Path, out: str, err: str) -> str:
    return "a command of the mesh file ran (D/pwned exists)" if (d / "pwned").exists() else ""


TOUCH = 'System "touch {dir}/pwned";\n'


def script_case(id: str, rel: str, body: str, key: str, expect: int = 2,
                stage: str = "scene", **kw) -> Case:
    """SQUARE whose mesh.file is ``rel``, written by :func:`_script`."""
    scene = square()[0] | {"mesh": {"file": rel}}
    files = {"square.msh": MESHES / "square.msh"}
    return Case(id, expect, key, scene, files=files, prepare=_script(rel, body),
                check=no_command_ran, stage=stage, hazard="unchecked", **kw)


add(
    # gmsh read anything that is not MSH as a script: a shell command ran, Exit; ended the
    # process with exit 0 and no message
    script_case("mesh_script_system", "mesh.msh", TOUCH, "$MeshFormat"),
    script_case("mesh_script_exit", "mesh.msh", "Exit;\n", "$MeshFormat"),
    script_case("mesh_geo_script", "mesh.geo", TOUCH, "gmsh script"),
    script_case("mesh_geo_unrolled", "mesh.geo_unrolled", TOUCH, "gmsh script"),
    script_case("mesh_opt_as_mesh", "mesh.opt", TOUCH, "gmsh script"),
    script_case("mesh_other_suffix", "mesh.txt", TOUCH, "not a .msh file"),
    script_case("mesh_no_suffix", "mesh", TOUCH, "not a .msh file"),
    # the header must be the first line: gmsh sent a blank first line to the script parser
    script_case("mesh_blank_before_header", "mesh.msh", "\n$MeshFormat\n4.1 0 8\n" + TOUCH,
                "$MeshFormat"),
    script_case("mesh_old_format", "mesh.msh", "$NOD\n1\n1 0 0 0\n$ENDNOD\n" + TOUCH,
                "$MeshFormat"),
    script_case("mesh_version_3", "mesh.msh", "$MeshFormat\n3.0 0 8\n$EndMeshFormat\n",
                "version 3"),
    # a valid header and script lines after it: read as MSH (the lines are skipped), no cells
    script_case("mesh_header_then_script", "mesh.msh",
                "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n" + TOUCH, "no 2D cells",
                stage="mesh"),
    # gmsh ran <file>.opt beside any file it opened: the run is fine, the script never runs
    Case("mesh_opt_beside_mesh", 0, "done", square()[0], files=square()[1],
         prepare=_script("square.msh.opt", TOUCH), check=no_command_ran, stage="run"),
    Case("mesh_check_command_script", 2, "$MeshFormat", square()[0] | {"mesh": {"file": "m.msh"}},
         argv=("check", "{scene}"), prepare=_script("m.msh", "Exit;\n"),
         check=no_command_ran),
    # 1 GiB of zeros was read for minutes and ignored SIGTERM
    Case("mesh_huge_zeros", 2, "MiB", square()[0] | {"mesh": {"file": "zeros.msh"}},
         prepare=_sparse("zeros.msh", 1 << 30), hazard="unchecked"),
    Case("mesh_small_zeros", 2, "$MeshFormat", square()[0] | {"mesh": {"file": "zeros.msh"}},
         prepare=_sparse("zeros.msh", 1 << 16), hazard="unchecked"),
    # cells in no physical group (gmsh's Mesh.SaveAll): DOLFINx aborted (SIGABRT)
    mesh_case("mesh_cells_outside_groups", "no physical surface group", "save_all.msh"),
    # nodes numbered from 1e9: "Unable to allocate 14.9 GiB"; now renumbered
    square_case("mesh_numbered_from_1e9", 0, "done", mesh="numbered_from_1e9.msh",
                stage="run"),
    script_case("mpi_mesh_script_exit", "mesh.msh", "Exit;\n", "$MeshFormat",
                mode="mpi", ranks=2),
    script_case("mpi_mesh_opt_as_mesh", "mesh.opt", TOUCH, "gmsh script", mode="mpi",
                ranks=2),
    mesh_case("mpi_mesh_cells_outside_groups", "no physical surface group", "save_all.msh",
              mode="mpi", ranks=2),
)

# -- physics guards -----------------------------------------------------------------------
SVK = edit(BLOCK, ("bodies[0].material.model", "svk"), ("dirichlet", [
    {"boundary": "bottom", "y": 0.0}, {"boundary": "left", "x": 0.0}]),
    ("pressures[0]", {"boundary": "top", "value": 300.0, "follower": False}),
    ("steps", {"count": 1, "max_cuts": 0}))
#: the top pushed 1.5 down on a block 1 high: from t = 2/3 on every state is inverted
SQUASHED = edit(SVK, ("pressures", []), ("dirichlet[+]", {"boundary": "top", "y": -1.5}),
                ("steps.max_cuts", 3))
#: two blocks, the upper one 4 x 4 elements of 0.25, placed 0.5 deep inside the lower
DEEP_OVERLAP = {
    "title": "deep initial overlap",
    "mesh": {"generator": "stacked_blocks", "params": {
        "lower_width": 2.0, "lower_nx": 8, "lower_ny": 4, "upper_x0": 0.5, "upper_width": 1.0,
        "upper_height": 1.0, "upper_nx": 4, "upper_ny": 4, "gap": -0.5}},
    "bodies": [{"name": n, "material": {"model": "neo-hooke", "E": 1000.0, "nu": 0.3}}
               for n in ("lower", "upper")],
    "dirichlet": [{"boundary": "lower_bottom", "x": 0.0, "y": 0.0},
                  {"boundary": "upper_top", "x": 0.0, "y": -0.05}],
    "contacts": [{"name": "c", "slave": "upper_bottom", "master": "lower_top"}],
    "steps": {"count": 2},
    "output": {"xdmf": False, "plots": False},
}
add(
    # past SVK's limit load Newton finds the inverted branch (J = -1.08 in every cell)
    Case("svk_inverted", 1, "inverts", SVK, stage="run"),
    Case("svk_squashed", 1, "inverts", SQUASHED, stage="run"),
    Case("penalty_penetration", 0, "penetration",
         base((f"{CONTACT}.enforcement", {"type": "penalty", "epsilon": 10.0})),
         check=in_summary("penetration"), stage="run", hazard="ignored"),
    # Newton's answer was |u| = 1e14 with zero reactions (the follower pressure on a
    # collapsed edge), accepted as converged: now refused, the run stops (exit 1)
    Case("E_tiny_flies_off", 1, "NOT converged", base(("bodies[0].material.E", 1e-12)),
         stage="run"),
    # the upper block 0.5 = two elements inside the lower one: converged with the slave
    # folded (its corner cells inverted between the Gauss points), exit 0; now the step is
    # cut, the run stops (exit 1), and a warning said why at the start
    Case("initial_overlap_two_elements", 1, "start inside the master", DEEP_OVERLAP,
         stage="run"),
    Case("factorization_fails", 1, "factorization",
         base(PENALTY, ("steps.max_cuts", 1), ("solver", {"petsc": {
             "-pc_factor_mat_solver_type": "petsc", "-pc_factor_zeropivot": 1e300,
             "-ksp_error_if_not_converged": True}})), stage="run"),
)

def signal_when(sig: signal.Signals, pattern: str):
    """sender: ``sig`` as soon as a file matching ``pattern`` appears under D (e.g. the C
    file FFCx writes before compiling it)."""
    def send(proc: subprocess.Popen, d: Path) -> None:
        deadline = time.time() + 60
        while not any(d.glob(pattern)) and time.time() < deadline and proc.poll() is None:
            time.sleep(0.005)
        if proc.poll() is None:
            proc.send_signal(sig)
    return send


def rerun_succeeds(d: Path, out: str, err: str) -> str:
    """check: no C file without its module is left in the JIT cache, and the same scene,
    run again with the same cache, converges (an interrupted
    compilation left no half-written entry that would time the next one out)."""
    cache = d / "jit-cache/fenics"
    stale = [c.name for c in cache.glob("*.c") if not c.with_suffix(".c.cached").exists()]
    if stale:
        return f"C files without their module left in the JIT cache: {stale}"
    env = {**os.environ, "XDG_CACHE_HOME": str(d / "jit-cache")}
    proc = subprocess.run([sys.executable, "-m", "fenicsx_mortar", "run", str(d / "scene.toml"),
                           "--out", str(d / "out")], cwd=d / "work", env=env, text=True,
                          capture_output=True, timeout=300)
    return "" if proc.returncode == 0 else f"the rerun failed: {proc.stderr[-1000:]}"


# -- signals during start-up, a full disk, and MPI ----------------------------------------
SLOW_MESH = edit(BLOCK, ("mesh.params", {"nx": 700, "ny": 700}))
add(
    # a fresh JIT cache: SIGINT as soon as FFCx writes the first form's C file
    Case("sigint_while_compiling", 1, "SIGINT while compiling", edit(BLOCK, (
        "bodies[0].material.model", "svk")), mode="process", env={
        "XDG_CACHE_HOME": "{dir}/jit-cache"},
        sender=signal_when(signal.SIGINT, "jit-cache/fenics/libffcx_forms_*.c"),
        check=rerun_succeeds, stage="run", timeout=120),
    Case("sigterm_while_meshing", 1, "SIGTERM", SLOW_MESH, mode="process",
         sender=signal_after(signal.SIGTERM, 1.0), stage="run"),
    Case("sigint_while_meshing", 1, "SIGINT", SLOW_MESH, mode="process",
         sender=signal_after(signal.SIGINT, 1.0), stage="run"),
    Case("disk_really_full", 1, "No space left", base(
        ("steps.count", 60), ("output", {"xdmf": False, "plots": False})), mode="process",
        prepare=small_disk, check=full_disk_consistent, stage="run"),
    # the HDF5 library's write fails first here (XDMF on): one line naming the .h5 file
    # and the disk, no traceback, no HDF5 error stack; scene.json stays whole
    Case("disk_full_xdmf", 1, "solution.h5", base(("steps.count", 3)), mode="process",
         prepare=lambda d, donors: (hdf5_fails_first(), small_disk(d, donors, "16k")),
         check=scene_json_whole, stage="run"),
    Case("disk_full", 1, "No space left", base(("steps.count", 3),
                                               ("output", {"xdmf": False, "plots": False})),
         mode="process", fault=True, check=full_disk_kept, stage="run"),
)
add(
    # one cell, two ranks: a rank owns no cell (the inversion guard reshaped an empty array)
    Case("mpi_more_ranks_than_cells", 0, "done", edit(BLOCK, ("mesh.params", {"nx": 1, "ny": 1})),
         mode="mpi", ranks=2, stage="run"),
    Case("mpi_out_is_a_file", 2, "--out", base(), prepare=write("out", b"x"), mode="mpi",
         ranks=2),
    Case("mpi_corrupt_checkpoint", 2, "checkpoint.npz", None, argv=("run", "--restart", "{out}"),
         prepare=keep_summary(then(copy_donor(), _truncate)), check=summary_unchanged,
         mode="mpi", ranks=2, stage="mesh"),
    Case("mpi_disk_full", 1, "No space left", base(("steps.count", 3),
                                                   ("output", {"xdmf": False, "plots": False})),
         mode="mpi", ranks=2, fault=True, check=full_disk_kept, stage="run"),
    # one rank's HDF5 write can fail while the other waits in the collective call: one
    # line, every rank ended (MPI_Abort), no hang, no traceback
    Case("mpi_disk_full_xdmf", 1, "solution.h5", base(("steps.count", 3)), mode="mpi",
         ranks=2, prepare=lambda d, donors: small_disk(d, donors, "16k"),
         check=scene_json_whole, stage="run"),
    Case("mpi_long_pair_name", 2, f"{CONTACT}.name", base((f"{CONTACT}.name", "p" * 300)),
         mode="mpi", ranks=2),
)

# ============================================================ issue 28: the third sweep
# -- checkpoints validated as a whole ------------------------------------------------------
def _checksum(arrays: dict) -> str:
    """The checkpoint's checksum as its format defines it (SHA-256 over every array but
    "checksum": name, type, shape, bytes): what a forger who read the format recomputes."""
    import hashlib
    h = hashlib.sha256()
    for name in sorted(k for k in arrays if k != "checksum"):
        a = np.ascontiguousarray(arrays[name])
        h.update(f"{name}\0{a.dtype.str}\0{a.shape}\0".encode())
        h.update(a.tobytes())
    return h.hexdigest()


def forge_checkpoint(change: Callable[[dict], dict]):
    """prepare step: D/out/checkpoint.npz rewritten with ``change(arrays)`` and its checksum
    recomputed, so only the checks of its content can refuse it."""
    def step(d: Path, donors) -> None:
        path = d / "out/checkpoint.npz"
        with np.load(path) as f:
            arrays = change({k: f[k] for k in f.files})
        arrays["checksum"] = np.array(_checksum(arrays))
        np.savez(path, **arrays)
    return step


def _set(key: str, value):
    def change(a: dict) -> dict:
        a[key] = np.asarray(value)
        return a
    return change


def _records(change: Callable[[list], object]):
    def edit(a: dict) -> dict:
        steps = json.loads(str(a["steps"]))
        a["steps"] = np.array(json.dumps(change(steps)))
        return a
    return edit


def _retime(steps: list) -> list:
    """The last record at 0.75: the checkpoint says t = 1."""
    steps[-1]["time"] = 0.75
    return steps


def _nan_history(a: dict) -> dict:
    a["pair0_multiplier"] = a["pair0_multiplier"].copy()
    a["pair0_multiplier"][1, 0] = NAN
    return a


def _drop_node(a: dict) -> dict:
    a["node"], a["u"] = a["node"][:-1], a["u"][:-1]
    return a


def _swap_nodes(a: dict) -> dict:
    a["node"] = a["node"].copy()
    a["node"][[0, 1]] = a["node"][[1, 0]]
    return a


def _zip_claims_4gib(d: Path, donors) -> None:
    """prepare step: the checkpoint's zip directory says one array unpacks to ~4 GiB (the
    central directory's size field of the first member, patched)."""
    path = d / "out/checkpoint.npz"
    raw = bytearray(path.read_bytes())
    at = raw.find(b"PK\x01\x02")
    raw[at + 24:at + 28] = (0xFFFFFFF0).to_bytes(4, "little")
    path.write_bytes(bytes(raw))


DEEP = 50_000


def _deep_json(d: Path, donors) -> None:
    (d / "out/scene.json").write_text("[" * DEEP + "]" * DEEP)


add(
    # the issue's edits: time 1.0 written into a checkpoint of t = 0.5 (here: 0.5 into one
    # of t = 1), time 5, -1, step -7; NaN in the pair history (cut 6 times); a history two
    # nodes short (an IndexError traceback). Plain edits break the checksum; forged ones
    # (checksum recomputed) meet the content checks
    checkpoint_case("ckpt_time_edited", rewrite_checkpoint(_set("time", 0.5))),
    checkpoint_case("ckpt_forged_time_off_records", forge_checkpoint(_set("time", 0.5))),
    checkpoint_case("ckpt_forged_time_beyond_path", forge_checkpoint(_set("time", 5.0))),
    checkpoint_case("ckpt_forged_time_negative", forge_checkpoint(_set("time", -1.0))),
    checkpoint_case("ckpt_forged_time_nan", forge_checkpoint(_set("time", NAN))),
    checkpoint_case("ckpt_forged_step_negative", forge_checkpoint(_set("step", -7))),
    checkpoint_case("ckpt_forged_step_behind", forge_checkpoint(_set("step", 1))),
    checkpoint_case("ckpt_forged_step_float", forge_checkpoint(_set("step", 2.0))),
    checkpoint_case("ckpt_forged_time_array", forge_checkpoint(_set("time", [1.0]))),
    checkpoint_case("ckpt_forged_records_disagree", forge_checkpoint(_records(_retime))),
    checkpoint_case("ckpt_forged_records_missing",
                    forge_checkpoint(_records(lambda st: st[:1]))),
    checkpoint_case("ckpt_forged_records_deep",
                    forge_checkpoint(lambda a: {**a, "steps": np.array("[" * DEEP + "]" * DEEP)})),
    checkpoint_case("ckpt_history_nan", rewrite_checkpoint(_nan_history)),
    checkpoint_case("ckpt_forged_history_nan", forge_checkpoint(_nan_history)),
    checkpoint_case("ckpt_forged_history_short", forge_checkpoint(
        lambda a: {**a, "pair0_multiplier": a["pair0_multiplier"][:-2]})),
    checkpoint_case("ckpt_forged_history_integer", forge_checkpoint(
        lambda a: {**a, "pair0_multiplier": a["pair0_multiplier"].astype(np.int64)})),
    checkpoint_case("ckpt_forged_history_extra_array",
                    forge_checkpoint(_set("pair0_bogus", [1.0, 2.0]))),
    checkpoint_case("ckpt_forged_history_of_no_pair",
                    forge_checkpoint(_set("pair1_multiplier", np.zeros((5, 2))))),
    checkpoint_case("ckpt_forged_segment_out_of_range",
                    forge_checkpoint(lambda a: {**a, "pair0_ref_seg": a["pair0_ref_seg"] + 10**6}),
                    donor="nts_friction"),
    checkpoint_case("ckpt_forged_nodes_unsorted", forge_checkpoint(_swap_nodes)),
    checkpoint_case("ckpt_forged_node_missing", forge_checkpoint(_drop_node)),
    checkpoint_case("ckpt_forged_u_text", forge_checkpoint(_set("u", "0"))),
    checkpoint_case("ckpt_no_checksum",
                    rewrite_checkpoint(lambda a: {k: v for k, v in a.items() if k != "checksum"})),
    checkpoint_case("ckpt_checksum_wrong_type", rewrite_checkpoint(_set("checksum", 7))),
    checkpoint_case("ckpt_zip_claims_4gib", _zip_claims_4gib, hazard="unchecked"),
    checkpoint_case("restart_scene_json_deep", _deep_json, key="scene.json"),
    Case("restart_control_nts_friction", 0, "done", None, argv=("run", "--restart", "{out}"),
         prepare=copy_donor("nts_friction"), stage="run"),
    Case("mpi_ckpt_forged_time", 2, "checkpoint.npz", None, argv=("run", "--restart", "{out}"),
         prepare=keep_summary(then(copy_donor(), forge_checkpoint(_set("time", 5.0)))),
         check=summary_unchanged, mode="mpi", ranks=2, stage="mesh"),
    Case("mpi_ckpt_forged_history_short", 2, "checkpoint.npz", None,
         argv=("run", "--restart", "{out}"), prepare=keep_summary(then(
             copy_donor(), forge_checkpoint(lambda a: {
                 **a, "pair0_multiplier": a["pair0_multiplier"][:-2]}))),
         check=summary_unchanged, mode="mpi", ranks=2, stage="mesh"),
    Case("mpi_ckpt_forged_segment", 2, "checkpoint.npz", None,
         argv=("run", "--restart", "{out}"), prepare=keep_summary(then(
             copy_donor("nts_friction"), forge_checkpoint(
                 lambda a: {**a, "pair0_nts_segment": a["pair0_nts_segment"] - 10})),),
         check=summary_unchanged, mode="mpi", ranks=2, stage="mesh"),
)

# -- supports: one value per node, no rigid motion left free --------------------------------
#: the Hertz half-disk (centre (0, 1), its flat top y = 1) on a block, coarse
HERTZ = {
    "title": "disk on block",
    "mesh": {"generator": "hertz", "params": {"h_contact": 0.1, "h_far": 0.25}},
    "bodies": [{"name": n, "material": {"model": "neo-hooke", "E": 1000.0, "nu": 0.3}}
               for n in ("disk", "block")],
    "dirichlet": [{"boundary": "block_bottom", "x": 0.0, "y": 0.0},
                  {"point": [0.0, 1.0], "body": "disk", "x": 0.0},
                  {"point": [0.0, 0.5], "body": "disk", "x": 0.0}],
    "tractions": [{"boundary": "disk_top", "value": [0.0, -0.5]}],
    "contacts": [{"name": "c", "slave": "disk_arc", "master": "block_top"}],
    "steps": {"count": 1},
    "output": {"xdmf": False, "plots": False},
}
#: the disk held at its centre only: nothing stops it turning (frictionless contact on an
#: arc about that centre); it converged, normal force 13 % off
DISK_AT_CENTRE = edit(HERTZ, ("dirichlet", [HERTZ["dirichlet"][0], {
    "point": [0.0, 1.0], "body": "disk", "x": 0.0, "y": 0.0}]))
LATE = ("curves", {"late": {"t": [0.0, 0.5, 1.0], "value": [0.0, 0.0, 1.0]}})
add(
    # two groups give their shared corner two values: it converged with reactions -26.2 and
    # +32.3 for a load of 1
    square_case("support_corner_two_values", 2, "dirichlet[1].y",
                ("dirichlet[+]", {"boundary": "left", "y": 0.1}), stage="mesh"),
    square_case("support_point_on_group", 2, "dirichlet[1].y",
                ("dirichlet[+]", {"point": [0.5, 0.0], "body": "block", "y": 0.2}),
                stage="mesh"),
    # one value, two curves: they differ on the way (0.05 against 0 at t = 0.5)
    square_case("support_corner_two_curves", 2, "dirichlet[1].y", LATE,
                ("dirichlet[0].y", 0.1),
                ("dirichlet[+]", {"boundary": "left", "y": 0.1, "curve": "late"}),
                stage="mesh"),
    square_case("support_motion_meets_fixed", 2, "dirichlet[1].x",
                ("dirichlet[+]", {"boundary": "left", "motion": {"translation": [0.1, 0.0]}}),
                stage="mesh"),
    square_case("support_corner_same_value", 0, "done",
                ("dirichlet[+]", {"boundary": "left", "x": 0.0}), stage="run"),
    Case("support_disk_at_centre", 2, "turning about (0, 1)", DISK_AT_CENTRE, stage="mesh"),
    # one node holds both components: the block turns about it
    square_case("support_one_point_only", 2, "turning about (0, 0)",
                ("dirichlet", [{"point": [0.0, 0.0], "body": "block", "x": 0.0, "y": 0.0}]),
                stage="mesh"),
    # no support and no contact on the block: it floats
    value("support_body_floats", "body 'block'", ("dirichlet", BASE["dirichlet"][:1]),
          ("contacts", []), stage="mesh"),
    # x along a vertical side and y at one node: every rigid motion is held
    square_case("support_side_and_point", 0, "done",
                ("dirichlet", [{"boundary": "left", "x": 0.0},
                               {"point": [0.0, 0.0], "body": "block", "y": 0.0}]),
                stage="run"),
    # the block is held along y by contact only: a warning naming it, in the log and the
    # summary
    Case("support_held_by_contact_only", 0, "held by no support", base(),
         check=in_summary("held by no support"), stage="run", hazard="ignored"),
    Case("mpi_support_corner_two_values", 2, "dirichlet[1].y",
         square(("dirichlet[+]", {"boundary": "left", "y": 0.1}))[0],
         files=square()[1], mode="mpi", ranks=2, stage="mesh"),
    Case("mpi_support_disk_at_centre", 2, "turning about (0, 1)", DISK_AT_CENTRE,
         mode="mpi", ranks=2, stage="mesh"),
)

# -- contact surfaces on the bodies' outer boundary ----------------------------------------
add(
    # a master on a curve inside a body: accepted, the bodies overlapped with zero force
    square_case("contact_master_inside", 2, "contacts[0].master",
                ("contacts", [{"name": "c", "slave": "top", "master": "cut"}]),
                mesh="interior_curve.msh", stage="mesh"),
    square_case("contact_slave_inside", 2, "contacts[0].slave",
                ("contacts", [{"name": "c", "slave": "cut", "master": "bottom"}]),
                mesh="interior_curve.msh", stage="mesh"),
    square_case("contact_one_master_group_inside", 2, "contacts[0].master",
                ("contacts", [{"name": "c", "slave": "top", "master": ["bottom", "cut"]}]),
                mesh="interior_curve.msh", stage="mesh"),
)

# -- --out: links, the lock -----------------------------------------------------------------
def link(rel: str, target: str, content: bytes | None = None, directory: bool = False):
    """prepare step: D/rel a symbolic link to D/target (made: a directory, or a file holding
    ``content``)."""
    def step(d: Path, donors) -> None:
        t = d / target
        if directory:
            t.mkdir(parents=True, exist_ok=True)
        elif content is not None:
            t.parent.mkdir(parents=True, exist_ok=True)
            t.write_bytes(content)
        (d / rel).parent.mkdir(parents=True, exist_ok=True)
        os.symlink(t, d / rel)
    return step


VICTIM = b"not yours\n"


def victim_kept(*rels: str):
    """check: D/victim still holds VICTIM and each D/out/rel is a file of its own."""
    def check(d: Path, out: str, err: str) -> str:
        if (d / "victim").read_bytes() != VICTIM:
            return "the link's target was overwritten"
        linked = [r for r in rels if (d / "out" / r).is_symlink()]
        return f"still links: {linked}" if linked else ""
    return check


def hold_lock(d: Path, donors) -> None:
    """prepare step: D/out exists and this process holds its lock (as a run would)."""
    import fcntl
    (d / "out").mkdir(exist_ok=True)
    fd = os.open(d / "out", os.O_RDONLY)
    fcntl.flock(fd, fcntl.LOCK_EX)
    _HELD[d] = fd


LONG_BASE = base(("steps.count", 60), ("output", {"xdmf": False, "plots": False}))


def run_in_background(d: Path, donors) -> None:
    """prepare step: a run of LONG_BASE into D/out, started; returns once it has begun
    writing there (its scene.json)."""
    (d / "long.toml").write_text(dumps(LONG_BASE))
    proc = subprocess.Popen([sys.executable, "-m", "fenicsx_mortar", "run", str(d / "long.toml"),
                             "--out", str(d / "out")], cwd=d / "work",
                            env={**(donors.env or os.environ), "PYTHONUNBUFFERED": "1"},
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                            start_new_session=True)
    _BACKGROUND[d] = proc
    deadline = time.time() + 120
    while not (d / "out/scene.json").exists() and proc.poll() is None and time.time() < deadline:
        time.sleep(0.05)
    # held still (with its lock) until the check: on an idle machine it could otherwise end
    # before the second run starts
    if proc.poll() is None:
        os.killpg(proc.pid, signal.SIGSTOP)


def first_run_whole(d: Path, out: str, err: str) -> str:
    """check: the run that held --out first ends converged with all its steps."""
    proc = _BACKGROUND[d]
    if proc.poll() is None:
        os.killpg(proc.pid, signal.SIGCONT)
    try:
        proc.wait(timeout=240)
    except subprocess.TimeoutExpired:
        return "the first run did not end"
    s = json.loads((d / "out/summary.json").read_text())
    if proc.returncode != 0 or not s["converged"] or len(s["steps"]) != 60:
        return f"the first run lost its outputs (exit {proc.returncode}, {len(s['steps'])} steps)"
    return ""


PLOTS = base(("output", {"xdmf": False, "plots": True}))
#: SQUASHED to 0.3 and 0.6 of its height, then past it (inverted): the run stops at step 3
SVK_STOPS = edit(SQUASHED, ("steps", {"times": [0.2, 0.4, 1.0], "max_cuts": 0}),
                 ("output", {"xdmf": True, "plots": False}))


def _run_stopping_at_step_2(d: Path, donors) -> None:
    """prepare step: D/out a run of SVK_STOPS (XDMF on), stopped after step 2: a
    restart continues it in its own solution_from_step_2.xdmf."""
    (d / "svk.toml").write_text(dumps(SVK_STOPS))
    proc = donors.run_in(d, "run", str(d / "svk.toml"), "--out", str(d / "out"))
    assert proc.returncode == 1 and "inverts" in proc.stderr, proc.stderr[-2000:]
add(
    # a link inside --out was followed: the CSVs went to ../elsewhere
    Case("out_interface_link", 2, "interface", base(),
         prepare=link("out/interface", "elsewhere", directory=True)),
    Case("out_interface_is_a_file", 2, "interface", base(), prepare=then(
        mkdir("out"), write("out/interface", b"x"))),
    Case("out_summary_link", 0, "done", base(), stage="run",
         prepare=link("out/summary.json", "victim", VICTIM),
         check=victim_kept("summary.json")),
    # savefig wrote through a link at a plot's path
    Case("out_plot_link", 0, "done", PLOTS, stage="run",
         prepare=link("out/reactions.png", "victim", VICTIM), check=victim_kept("reactions.png")),
    Case("out_pressure_plot_link", 0, "done", PLOTS, stage="run",
         prepare=link("out/interface/c_pressure.png", "victim", VICTIM),
         check=victim_kept("interface/c_pressure.png")),
    Case("out_csv_link", 0, "done", base(), stage="run",
         prepare=link("out/interface/c_0001.csv", "victim", VICTIM),
         check=victim_kept("interface/c_0001.csv")),
    Case("out_h5_link", 0, "done", base(), stage="run",
         prepare=link("out/solution.h5", "victim", VICTIM), check=victim_kept("solution.h5")),
    # a restart's own XDMF file is not cleared first: the link is replaced all the same
    Case("restart_xdmf_link", 1, "inverts", None, argv=("run", "--restart", "{out}"),
         stage="run", prepare=then(_run_stopping_at_step_2,
                                   link("out/solution_from_step_2.h5", "victim", VICTIM)),
         check=victim_kept("solution_from_step_2.h5")),
    Case("out_checkpoint_link", 0, "done", base(), stage="run",
         prepare=link("out/checkpoint.npz", "victim", VICTIM),
         check=victim_kept("checkpoint.npz")),
    # two runs into one --out: both exited 0, one silently lost its outputs
    Case("out_locked", 2, "another run", base(), prepare=hold_lock),
    Case("restart_locked", 2, "another run", None, argv=("run", "--restart", "{out}"),
         prepare=then(copy_donor(), hold_lock)),
    Case("out_two_runs_at_once", 2, "another run", base(), prepare=run_in_background,
         check=first_run_whole, mode="process", timeout=120),
    Case("mpi_out_locked", 2, "another run", base(), prepare=hold_lock, mode="mpi", ranks=2),
    Case("mpi_out_interface_link", 2, "interface", base(), mode="mpi", ranks=2,
         prepare=link("out/interface", "elsewhere", directory=True)),
    Case("mpi_out_summary_link", 0, "done", base(), stage="run", mode="mpi", ranks=2,
         prepare=link("out/summary.json", "victim", VICTIM), check=victim_kept("summary.json")),
)

# -- the environment ------------------------------------------------------------------------
def close_stdout_after(n: int):
    """sender: read ``n`` characters of stdout, then close it (``| head -c n``)."""
    def send(proc: subprocess.Popen, d: Path) -> None:
        proc.seen = proc.stdout.read(n)
        proc.stdout.close()
        proc.stdout = None
    return send


def converged_summary(d: Path, out: str, err: str) -> str:
    s = json.loads((d / "out/summary.json").read_text())
    if not s["converged"]:
        return "summary.json does not say converged"
    return "a PETSc error report on stderr" if "PETSC ERROR" in err else ""


def corrupt_jit_cache(d: Path, donors) -> None:
    """prepare step: D/jit-cache/fenics a copy of the JIT cache the donor run filled, every
    compiled module cut to 100 bytes."""
    donors.get("base")
    home = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache")
    shutil.copytree(home / "fenics", d / "jit-cache/fenics")
    for so in (d / "jit-cache/fenics").glob("*.so"):
        so.write_bytes(so.read_bytes()[:100])


def env_case(id: str, expect: int, key: str, env: dict, scene=None, **kw) -> Case:
    return Case(id, expect, key, base() if scene is None else scene, env=env,
                mode=kw.pop("mode", "process"), stage=kw.pop("stage", "run"), **kw)


UNSET_HOMES = {"XDG_CACHE_HOME": None, "XDG_CONFIG_HOME": None}


def warned(word: str):
    """check: a warning on stderr names ``word`` (the run goes on: exit 0)."""
    def check(d: Path, out: str, err: str) -> str:
        return "" if "warning" in err and word in err else f"no warning naming {word!r}"
    return check


def petsc_env_case(id: str, word: str, env: dict, **kw) -> Case:
    """PETSc options from outside the scene: ignored, with a warning naming ``word``."""
    return env_case(id, 0, "done", env, hazard="unchecked", check=warned(word), **kw)


add(
    # PETSc read options from the environment and .petscrc, unchecked: a viewer wrote
    # outside --out
    petsc_env_case("env_petsc_options_viewer", "PETSC_OPTIONS",
                   {"PETSC_OPTIONS": "-log_view :../x"}),
    petsc_env_case("env_petsc_options_solver", "PETSC_OPTIONS",
                   {"PETSC_OPTIONS": "-snes_type ksponly -snes_convergence_test skip"}),
    petsc_env_case("env_petsc_options_yaml", "PETSC_OPTIONS_YAML",
                   {"PETSC_OPTIONS_YAML": "log_view: ':../x'"}),
    petsc_env_case("env_petscrc_in_work_dir", ".petscrc", {},
                   prepare=write("work/.petscrc", b"-log_view :../y\n")),
    petsc_env_case("env_petscrc_named_petscrc", "petscrc", {},
                   prepare=write("work/petscrc", b"-ksp_view_mat binary:../mat.bin\n")),
    # stdout closed early (| head -c 20): a PETSc signal-13 dump, MPI_ABORT, no summary.json
    env_case("env_stdout_closed", 0, "fenicsx_mortar", {}, sender=close_stdout_after(20),
             check=converged_summary),
    # stdout on /dev/full: a traceback at the first log line
    env_case("env_stdout_full", 0, "", {}, stdout="/dev/full", check=converged_summary),
    env_case("env_ascii_title", 0, "caf\\xe9", {"PYTHONIOENCODING": "ascii"},
             scene=base(("title", "caf\xe9 \u2192 block"))),
    env_case("env_ascii_file_name", 2, "caf", {"PYTHONIOENCODING": "ascii"}, stage="scene",
             argv=("run", "{dir}/caf\xe9.toml", "--out", "{out}")),
    # the JIT cache under a file, read-only, corrupt; HOME under a file: tracebacks
    env_case("env_jit_cache_is_a_file", 1, "XDG_CACHE_HOME",
             {"XDG_CACHE_HOME": "{dir}/cachefile"}, prepare=write("cachefile", b"x")),
    env_case("env_jit_cache_read_only", 1, "XDG_CACHE_HOME", {"XDG_CACHE_HOME": "{dir}/ro"},
             prepare=readonly_dir),
    env_case("env_jit_cache_corrupt", 1, "JIT cache",
             {"XDG_CACHE_HOME": "{dir}/jit-cache"}, prepare=corrupt_jit_cache),
    env_case("env_home_under_a_file", 1, "HOME", {"HOME": "{dir}/homefile/home", **UNSET_HOMES},
             prepare=write("homefile", b"x")),
    env_case("env_config_home_a_file", 1, "XDG_CONFIG_HOME",
             {"XDG_CONFIG_HOME": "{dir}/cfgfile"}, prepare=write("cfgfile", b"x")),
    # DOLFINx and FFCx read JIT settings from the working directory: the cache put outside
    # --out, the number type changed
    env_case("env_jit_settings_in_work_dir", 1, "dolfinx_jit_parameters.json", {},
             prepare=write("work/dolfinx_jit_parameters.json",
                           b'{"cache_dir": "../elsewhere-cache"}'), hazard="unchecked"),
    env_case("env_ffcx_settings_in_work_dir", 1, "ffcx_parameters.json", {},
             prepare=write("work/ffcx_parameters.json", b'{"scalar_type": "float"}'),
             hazard="unchecked"),
    petsc_env_case("mpi_env_petsc_options", "PETSC_OPTIONS",
                   {"PETSC_OPTIONS": "-log_view :../x"}, mode="mpi", ranks=2),
)

# -- parsers: nesting depth -----------------------------------------------------------------
add(
    # 50 000 deep: a RecursionError traceback
    Case("toml_deep_array", 2, "scene.toml", "a = " + "[" * DEEP + "]" * DEEP + "\n"),
    Case("toml_deep_inline_tables", 2, "scene.toml", "a = " + "{b = " * DEEP + "1"
         + "}" * DEEP + "\n"),
    Case("toml_deep_dotted_key", 2, "nested", ".".join(["a"] * DEEP) + " = 1\n"),
    # deeper than any scene is, but parseable: refused where it is
    Case("toml_nested_40_in_params", 2, "nested",
         edit(BASE, ("mesh.params.slab_nx", json.loads("[" * 40 + "1" + "]" * 40)))),
    Case("restart_scene_json_nested_40", 2, "nested", None, argv=("run", "--restart", "{out}"),
         prepare=then(copy_donor(), lambda d, _: (d / "out/scene.json").write_text(
             json.dumps({"title": json.loads("[" * 40 + "]" * 40)}))), stage="mesh"),
)

# -- numbers that overflow later; tolerances the problem's scale cannot meet ----------------
BIG_BLOCK = edit(BLOCK, ("mesh.params", {"nx": 4, "ny": 4, "width": 5e5, "height": 5e5}),
                 ("pressures[0].value", 1.0))
BIG_STACK = {**DEEP_OVERLAP, "title": "stacked, lengths x 5e5", "mesh": {
    "generator": "stacked_blocks", "params": {
        "lower_width": 1e6, "lower_height": 5e5, "lower_nx": 8, "lower_ny": 4,
        "upper_x0": 2.5e5, "upper_width": 5e5, "upper_height": 2.5e5, "upper_nx": 4,
        "upper_ny": 2}},
    "dirichlet": [{"boundary": "lower_bottom", "x": 0.0, "y": 0.0},
                  {"boundary": "upper_left", "x": 0.0}],
    "pressures": [{"boundary": "upper_top", "value": 1.0}]}
HUGE = ("curves", {"huge": {"t": [0.0, 1.0], "value": [0.0, 1e60]}})
add(
    # E = 1e308: NaN in the first assembly, six cuts naming no key
    value("E_1e308", "bodies[0].material.E", ("bodies[0].material.E", 1e308)),
    value("E_1e150", "bodies[1].material.E", ("bodies[1].material.E", 1e150)),
    value("pressure_times_curve_overflows", "pressures[0].value", HUGE,
          ("pressures[0].value", 1e60), ("pressures[0].curve", "huge")),
    value("traction_times_curve_overflows", "tractions[0].value[1]", HUGE,
          ("tractions", [{"boundary": "block_right", "value": [0.0, 1e60], "curve": "huge"}])),
    value("dirichlet_times_curve_overflows", "dirichlet[1].x", HUGE,
          ("dirichlet[1]", {"boundary": "block_left", "x": 1e60, "curve": "huge"})),
    value("motion_times_curve_overflows", "dirichlet[1].motion.translation[0]", HUGE,
          ("dirichlet[1]", {"boundary": "block_left", "motion": {
              "translation": [1e60, 0.0], "translation_curve": "huge"}})),
    value("epsilon_1e300", f"{CONTACT}.enforcement.epsilon",
          (f"{CONTACT}.enforcement", {"type": "penalty", "epsilon": 1e300})),
    value("mu_1e200", f"{CONTACT}.friction.mu", (f"{CONTACT}.friction.mu", 1e200), COULOMB_LAW),
    # lengths 5e5: the default atol 1000x below the residual's round-off floor, every step
    # "Newton failed"
    Case("length_scale_5e5", 2, "solver.atol", BIG_BLOCK, stage="run"),
    Case("length_scale_5e5_contact", 2, "solver.atol", BIG_STACK, stage="run"),
    Case("length_scale_5e5_atol_above_floor", 0, "done",
         edit(BIG_BLOCK, ("solver", {"atol": 1e-6})), stage="run"),
    # loads far below E's round-off: no atol can tell an answer from u = 0
    value("loads_below_stiffness_roundoff", "material.E",
          ("bodies[0].material.E", 1e20), ("bodies[1].material.E", 1e20),
          ("pressures[0].value", 1e-3), stage="run"),
)


#: donor runs the restart cases copy: name -> scene
DONORS = {"base": base(("output", {"xdmf": False})),
          "base_p05": base(("pressures[0].value", 0.5), ("output", {"xdmf": False})),
          # node-to-segment with friction: integer history (segment numbers)
          "nts_friction": base(("output", {"xdmf": False}), (f"{CONTACT}.method", "nts"),
                               (f"{CONTACT}.friction", {"law": "coulomb", "mu": 0.3}))}

assert len({c.id for c in CASES}) == len(CASES), "duplicate case ids"
