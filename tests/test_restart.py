"""Nothing lost: a run stopped by SIGTERM keeps its converged steps, and
``fenicsx-mortar run --restart DIR`` reaches the same final state as an uninterrupted run."""
import json
import os
import signal
import subprocess
import sys
import time

import numpy as np

from conftest import MPI_ENV, ROOT, run_cli

SCENE = (ROOT / "demos/scenes/clamped_block.toml").read_text().replace(
    "nx = 16, ny = 8", "nx = 48, ny = 24").replace("count = 3", "count = 24")


def test_sigterm_then_restart_equals_uninterrupted(tmp_path):
    scene = tmp_path / "scene.toml"
    scene.write_text(SCENE)
    full, cut = tmp_path / "full", tmp_path / "cut"
    assert run_cli("run", str(scene), "--out", str(full)).returncode == 0

    proc = subprocess.Popen([sys.executable, "-m", "fenicsx_mortar", "run", str(scene),
                             "--out", str(cut)], cwd=ROOT, env={**os.environ, **MPI_ENV},
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    summary = cut / "summary.json"
    deadline = time.time() + 120
    while time.time() < deadline:
        if summary.exists() and len(json.loads(summary.read_text())["steps"]) >= 3:
            break
        time.sleep(0.02)
    proc.send_signal(signal.SIGTERM)
    out, err = proc.communicate(timeout=120)
    assert proc.returncode == 1, err
    s = json.loads(summary.read_text())
    assert not s["converged"] and "interrupted by SIGTERM" in s["message"]
    n_done = len(s["steps"])
    assert 3 <= n_done < 24

    proc = run_cli("run", "--restart", str(cut))
    assert proc.returncode == 0, proc.stderr
    s = json.loads(summary.read_text())
    assert s["converged"] and len(s["steps"]) == 24
    assert [r["step"] for r in s["steps"]] == list(range(1, 25))
    a, b = np.load(full / "checkpoint.npz"), np.load(cut / "checkpoint.npz")
    assert np.array_equal(a["node"], b["node"])
    assert np.abs(a["u"] - b["u"]).max() <= 1e-10 * np.abs(a["u"]).max()


def test_restart_without_checkpoint_is_refused(tmp_path):
    (tmp_path / "scene.json").write_text("{}")
    proc = run_cli("run", "--restart", str(tmp_path))
    assert proc.returncode == 2 and "Traceback" not in proc.stderr


def test_restart_of_a_contact_run_equals_uninterrupted(tmp_path):
    """A B-spline master is rebuilt from the master's nodes at the start of each step; a
    restart must start its first step from the restored state, not from the reference
    configuration (before: the first restarted step's curve and crossing check used the
    undeformed mesh, and the end state differed)."""
    from fenicsx_mortar import Friction, load_scene, solve
    from fenicsx_mortar.scene import load_scene_json

    scene = load_scene(ROOT / "demos/scenes/half_rings.toml")
    scene.contacts[0].smoothing = "bspline"
    scene.contacts[0].friction = Friction(law="coulomb", mu=0.3)
    scene.steps.times = [0.5, 1.0, 1.1, 1.2]
    scene.output.xdmf = scene.output.plots = False

    def quiet(s):
        pass

    def stop_after_two(rec, state):
        if rec["step"] == 2:
            os.kill(os.getpid(), signal.SIGTERM)   # the run's own handler: a clean stop

    full = solve(scene, out=tmp_path / "full", log=quiet)
    cut = solve(scene, out=tmp_path / "cut", log=quiet, on_step=stop_after_two)
    assert full.converged and not cut.converged and len(cut.steps) == 2
    again = solve(load_scene_json(tmp_path / "cut" / "scene.json"), out=tmp_path / "cut",
                  log=quiet, restart=True)
    assert again.converged and len(again.steps) == 4
    a, b = np.load(tmp_path / "full" / "checkpoint.npz"), np.load(tmp_path / "cut" /
                                                                  "checkpoint.npz")
    assert np.abs(a["u"] - b["u"]).max() <= 1e-12 * np.abs(a["u"]).max()
