"""MPI runs equal the serial one: the bulk is distributed by DOLFINx, contact surfaces are
cut across ranks (each rank integrates the slave segments of the nodes it owns).

For each scene the serial run and the runs on N ranks (``mpirun -n N`` with Open MPI, the
venv's ``mpiexec -n N`` with PyPI's MPICH: fenicsx_mortar/mpi_launch.py) are compared step
by step:
nodal displacement (node by node, by mesh-file number: a coordinate sort would swap the
coincident nodes of two touching bodies), contact pressure (and, with friction, tangential
traction and stick/slip status) per slave node, the step records that summary.json holds
(reactions, contact forces), and the Newton iterations, augmentations and cuts of every
step. Floats agree to ``tol`` relative to the step's scale of the quantity (largest |u|,
largest pressure, largest reaction, the pair's normal force): a component that is zero up
to round-off (the net tangential force of a symmetric press) has no relative accuracy of
its own. Counts agree exactly, except the half-rings' Newton iterations (see
HALF_RINGS_ITERATIONS).

To keep mpirun and interpreter starts few, one process per rank count runs every scene it
is needed for (tests/dump_solution.py); the tests then compare the saved results. The
files written by ``fenicsx-mortar run`` under mpirun are checked by test_cli_outputs.
"""
import json
import os
import subprocess
import sys

import numpy as np
import pytest

from conftest import MPI_ENV, ROOT, mpi_command, run_python

pytestmark = pytest.mark.mpi


def _edit(text: str, *changes: tuple[str, str]) -> str:
    for old, new in changes:
        assert text.count(old) == 1, f"scene file changed: {old!r} not found once"
        text = text.replace(old, new)
    return text


# scene name -> (scene file, edits making it small and short)
SCENES = {
    "clamped_block": ("clamped_block", ()),
    "patch_test": ("patch_test", ()),
    # coarse Hertz: h_c = a/4 (the demo's a/10 is 0.0048)
    "hertz": ("hertz", (("h_contact = 0.0048", "h_contact = 0.012"),)),
    # B5 with Coulomb mu = 0.3: pressed in one step (10 of 11 nodes stick, one slips), then
    # two steps of the push; at t = 1.1 every node slips (|t_T| = mu p)
    "block_on_slab": ("block_on_slab", (
        ("times = [0.5, 1.0, 1.1, 1.2, 1.3, 1.4, 1.5, 1.6, 1.7, 1.8, 1.9, 2.0]",
         "times = [1.0, 1.1, 1.2]"),)),
    # B3 half-rings made frictional (mu = 0.3), the default coarse mesh (4 x 32, 4 x 60),
    # pressed in two steps, then turned by 5 % and 10 % of the full turn (sliding)
    "half_rings": ("half_rings", (
        ('enforcement = { type = "lagrange" }\n',
         'enforcement = { type = "lagrange" }\nfriction = { law = "coulomb", mu = 0.3 }\n'),
        ("times = [0.25, 0.5, 0.75, 1.0, 1.05, 1.1, 1.15, 1.2, 1.25, 1.3, 1.35, 1.4, 1.45, "
         "1.5, 1.55, 1.6, 1.65, 1.7, 1.75, 1.8, 1.85, 1.9, 1.95, 2.0]",
         "times = [0.5, 1.0, 1.05, 1.1]"))),
    # two-sided smoothing: Hermite master and a Hermite curve through the slave nodes; the
    # slave curve couples a slave node to its neighbours, which straddle the rank boundary
    "shrink_fit_two_sided": ("shrink_fit", (
        ('smoothing = "none"', 'smoothing = "hermite"\nslave_smoothing = "hermite"'),)),
}
# the same contact scenes with the Uzawa ALM (the demo scenes use Lagrange multipliers)
_ALM = ('enforcement = { type = "lagrange" }', 'enforcement = { type = "alm" }')
for _name in ("patch_test", "hertz", "block_on_slab", "half_rings"):
    _stem, _edits = SCENES[_name]
    if any(_ALM[0] in old for old, _ in _edits):
        _edits = tuple((old, new.replace(*_ALM)) for old, new in _edits)
    else:
        _edits = _edits + (_ALM,)
    SCENES[f"{_name}_alm"] = (_stem, _edits)

# (scene, ranks, tolerance): bulk alone to 1e-10, with contact to 1e-8
CASES = [
    ("clamped_block", 2, 1e-10),
    ("clamped_block", 3, 1e-10),
    ("patch_test", 2, 1e-8),
    ("patch_test", 3, 1e-8),
    ("patch_test", 4, 1e-8),
    ("hertz", 2, 1e-8),
    ("hertz", 3, 1e-8),
    ("block_on_slab", 2, 1e-8),
    ("block_on_slab", 3, 1e-8),
    ("half_rings", 2, 1e-8),
    ("half_rings", 3, 1e-8),
    ("shrink_fit_two_sided", 2, 1e-8),
    ("patch_test_alm", 2, 1e-8),
    ("hertz_alm", 2, 1e-8),
    ("block_on_slab_alm", 2, 1e-8),
    ("half_rings_alm", 2, 1e-8),
]


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """runs(n) -> folder with every needed scene's results on n ranks (run on first use)."""
    base = tmp_path_factory.mktemp("mpi")
    scenes = {}
    for name, (stem, edits) in SCENES.items():
        path = base / f"{name}.toml"
        path.write_text(_edit((ROOT / f"demos/scenes/{stem}.toml").read_text(), *edits))
        scenes[name] = path
    done = {}

    def get(n: int):
        if n not in done:
            names = list(SCENES) if n == 1 else [s for s, r, _ in CASES if r == n]
            out = base / f"n{n}"
            out.mkdir()
            proc = run_python([sys.executable, str(ROOT / "tests/dump_solution.py"), str(out),
                               *(str(scenes[s]) for s in names)], ranks=n)
            done[n] = (out, proc)
        out, proc = done[n]
        assert proc.returncode == 0, proc.stdout[-1000:] + proc.stderr[-3000:]
        return out
    get.base = base
    return get


def _load(folder, name):
    """(arrays, summary-like dict) of one scene's dump_solution run."""
    with np.load(folder / f"{name}.npz") as f:
        arrays = {k: f[k] for k in f.files}
    summary = {"converged": bool(arrays["converged"]), "ranks": int(arrays["ranks"]),
               "dofs": int(arrays["dofs"]), "steps": json.loads(str(arrays["steps"]))}
    return arrays, summary


class Diff:
    """Collects the largest scaled difference per quantity."""

    def __init__(self):
        self.worst: dict[str, float] = {}
        self.mismatch: list[str] = []

    def close(self, what: str, a, b, scale: float) -> None:
        a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
        assert a.shape == b.shape, f"{what}: shapes {a.shape} != {b.shape}"
        d = float(np.abs(a - b).max(initial=0.0)) / scale if scale > 0 else 0.0
        key = what.split("[")[0]
        self.worst[key] = max(self.worst.get(key, 0.0), d)

    def same(self, what: str, a, b) -> None:
        if not np.array_equal(np.asarray(a), np.asarray(b)):
            self.mismatch.append(f"{what}: serial {a} vs parallel {b}")


def compare(serial, parallel, diff: Diff) -> None:
    (a, sa), (b, sb) = serial, parallel
    assert sa["converged"] and sb["converged"]
    assert sa["dofs"] == sb["dofs"]
    assert np.array_equal(a["node"], b["node"])
    assert np.abs(a["X"] - b["X"]).max() <= 1e-12
    compare_records(sa["steps"], sb["steps"], diff)
    assert len(sa["steps"]) == len(a["u"]) == len(b["u"])
    for k, ra in enumerate(sa["steps"]):
        step = f"step {k + 1}"
        scale_u = np.abs(a["u"][k]).max()
        assert scale_u > 1e-3  # a real deformation, not a trivial zero field
        diff.close(f"displacement[{step}]", a["u"][k], b["u"][k], scale_u)
        for pair in ra.get("contact", {}):
            # per slave node, by mesh-file node number
            assert np.array_equal(a[f"{pair}:slave_node"], b[f"{pair}:slave_node"])
            p = a[f"{pair}:pressure"][k]
            assert p.max() > 0
            diff.close(f"{pair} pressure[{step}]", p, b[f"{pair}:pressure"][k], p.max())
            if f"{pair}:status" in a:
                diff.close(f"{pair} t_tangential[{step}]", a[f"{pair}:t_tangential"][k],
                           b[f"{pair}:t_tangential"][k], p.max())
                diff.same(f"{step} {pair} stick/slip status", a[f"{pair}:status"][k],
                          b[f"{pair}:status"][k])


def compare_records(steps_a: list[dict], steps_b: list[dict], diff: Diff) -> None:
    """Per-step records (summary.json "steps"): counts exactly, forces to the tolerance."""
    assert len(steps_a) == len(steps_b)
    for k, (ra, rb) in enumerate(zip(steps_a, steps_b)):
        step = f"step {k + 1}"
        for key in ("time", "newton_iterations", "augmentations", "cuts"):
            diff.same(f"{step} {key}", ra[key], rb[key])
        # reactions: every support, every prescribed component
        assert ra["reactions"].keys() == rb["reactions"].keys()
        comps = [(lab, c) for lab, r in ra["reactions"].items() for c in r]
        assert comps == [(lab, c) for lab, r in rb["reactions"].items() for c in r]
        if comps:
            Ra = np.array([ra["reactions"][lab][c] for lab, c in comps])
            Rb = np.array([rb["reactions"][lab][c] for lab, c in comps])
            diff.close(f"reactions[{step}]", Ra, Rb, np.abs(Ra).max())
        assert ra.get("contact", {}).keys() == rb.get("contact", {}).keys()
        for pair, ca in ra.get("contact", {}).items():
            cb = rb["contact"][pair]
            assert ca.keys() == cb.keys()
            force = max(abs(ca["normal_force"]), *map(abs, ca["force_on_slave"]))
            for key in ca:
                if key in ("active_nodes", "stick_nodes", "slip_nodes", "augmentations"):
                    diff.same(f"{step} {pair} {key}", ca[key], cb[key])
                elif key in ("normal_force", "force_on_slave", "tangential_force",
                             "tangential_force_on_slave"):
                    diff.close(f"{pair} {key}[{step}]", ca[key], cb[key], force)
                elif key == "kkt_residual":
                    continue  # a convergence measure at round-off level, not a result
                else:  # max_pressure, active_length, epsilon, epsilon_max
                    diff.close(f"{pair} {key}[{step}]", ca[key], cb[key], abs(ca[key]))


HALF_RINGS_ITERATIONS = (
    "frictional half-rings with the Uzawa ALM: the converged states agree to 5e-11, but a "
    "step's Newton iterations differ by 1 in most parallel runs, not all (10 of 12 runs at "
    "n=2, 7 of 9 at n=3; counted with converged Uzawa solves, before the inexact updates of "
    "issue 31, which still differ): serial [30, 30, 32, 27], n=2 [30, 30, 32|33, 27|28], "
    "n=3 [30, 30, 32|33, 27|28]; it varies from run to run (MUMPS in parallel is not "
    "bitwise reproducible). Two "
    "round-off ties: (1) friction.Coulomb.traction classifies slip by "
    "|eps_T g_T| - mu p > 0, and at the first iterate of a step every node that slipped in "
    "the previous step sits on the cone to round-off (the moving-cone commit puts it "
    "there), so stick or slip tangent, hence the first Newton direction, is decided by "
    "round-off (step 3's first-iterate residual: 42.47 serial, 36.7..45.8 over parallel "
    "runs; with a relative tie tolerance of 1e-8 in that test it agrees to 1e-12); (2) in "
    "step 4 one Newton solve lands at |R| = 0.98e-9 .. 1.10e-9 over runs, on the "
    "atol = 1e-9 threshold, so one more iteration or not")


@pytest.mark.parametrize("scene,ranks,tol", CASES)
def test_mpi_equals_serial(scene, ranks, tol, runs):
    serial, parallel = _load(runs(1), scene), _load(runs(ranks), scene)
    assert parallel[1]["ranks"] == ranks and serial[1]["ranks"] == 1
    diff = Diff()
    compare(serial, parallel, diff)
    report = ", ".join(f"{k} {v:.1e}" for k, v in sorted(diff.worst.items()))
    print(f"{scene} n={ranks}: {report}; {'; '.join(diff.mismatch) or 'counts equal'}")
    if scene == "half_rings_alm":
        # round-off ties decide a Newton iteration (HALF_RINGS_ITERATIONS) and, since the
        # inexact Uzawa updates (issue 31), where a solve stops for an update: a step's
        # Newton iterations differ by a few (19 against 25 once: an update more), the
        # run's by a tenth at most; the converged states still agree to tol (below)
        its = [(s["newton_iterations"], t["newton_iterations"])
               for s, t in zip(serial[1]["steps"], parallel[1]["steps"])]
        total = [sum(k) for k in zip(*its)]
        assert abs(total[0] - total[1]) <= 0.1 * total[0], its
        diff.mismatch = [m for m in diff.mismatch
                         if "newton_iterations:" not in m and "augmentations:" not in m]
    assert not diff.mismatch, "; ".join(diff.mismatch[:8])
    assert max(diff.worst.values()) <= tol, f"relative differences: {report}"


@pytest.mark.xfail(strict=False, reason=HALF_RINGS_ITERATIONS)
@pytest.mark.parametrize("ranks", [2])
def test_mpi_half_rings_newton_iterations(ranks, runs):
    """Not strict: the mismatch comes and goes from run to run (round-off ties). With
    Lagrange multipliers (the scene's own enforcement) the counts are compared exactly by
    test_mpi_equals_serial."""
    its = [[s["newton_iterations"] for s in _load(runs(n), "half_rings_alm")[1]["steps"]]
           for n in (1, ranks)]
    assert its[0] == its[1]


@pytest.mark.parametrize("scene,ranks", [
    ("clamped_block", 2),
    ("patch_test", 2)])
def test_cli_outputs(scene, ranks, runs, tmp_path):
    """``fenicsx-mortar run`` under mpirun: rank 0 writes the outputs once, and their
    summary.json and checkpoint hold what the serial run computes."""
    runs(1)  # writes the edited scene files and the serial results
    folder = runs.base
    out = tmp_path / "out"
    # 20 s: the run takes ~6 s; the hang below is cut by timeout (SIGTERM, the launcher
    # ends its ranks)
    cmd = ["timeout", "-k", "5", "20", *mpi_command(ranks), sys.executable, "-m",
           "fenicsx_mortar", "run", str(folder / f"{scene}.toml"), "--out", str(out)]
    proc = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT,
                          env={**os.environ, **MPI_ENV})
    assert proc.returncode == 0, f"exit {proc.returncode}: " + proc.stderr[-2000:]
    assert proc.stdout.count("done: ") == 1  # one log, from rank 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["converged"] and summary["ranks"] == ranks
    for name in ("solution.xdmf", "solution.h5", "checkpoint.npz", "scene.json",
                 "reactions.png", "convergence.png"):
        assert (out / name).is_file(), name
    a, serial = _load(folder / "n1", scene)
    if "contact" in serial["steps"][-1]:
        assert list((out / "interface").glob("*.csv"))
    assert summary["dofs"] == serial["dofs"]
    diff = Diff()
    compare_records(serial["steps"], summary["steps"], diff)
    with np.load(out / "checkpoint.npz") as ck:  # displacement per mesh-file node
        assert np.array_equal(ck["node"], a["node"])
        diff.close("displacement", a["u"][-1], ck["u"], np.abs(a["u"][-1]).max())
    assert not diff.mismatch, "; ".join(diff.mismatch[:8])
    assert max(diff.worst.values()) <= 1e-8, diff.worst


def test_the_launcher_starts_the_ranks_of_this_python():
    # Open MPI's mpirun or the venv's MPICH mpiexec, whichever this Python's mpi4py uses:
    # every rank must see the same world of 3 (a launcher of the other MPI starts 3
    # singletons that each see a world of 1)
    # (rank 0 prints what every rank saw: three ranks writing at once interleave)
    proc = run_python([sys.executable, "-c", "from mpi4py import MPI; c = MPI.COMM_WORLD; "
                       "seen = c.gather((c.rank, c.size)); "
                       "print(sorted(seen) if c.rank == 0 else '', end='')"],
                      ranks=3, timeout=120)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert proc.stdout.strip() == "[(0, 3), (1, 3), (2, 3)]", proc.stdout
    with pytest.raises(ValueError, match="ranks: a positive whole number"):
        mpi_command(0)
