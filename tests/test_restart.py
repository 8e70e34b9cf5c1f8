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
