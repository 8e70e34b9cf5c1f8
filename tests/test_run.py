"""End-to-end runs through the CLI: outputs, exit codes, and nothing lost on failure."""
import json

from conftest import ROOT, run_cli

FAILING = (ROOT / "demos/scenes/block_compression.toml").read_text() + """
[curves.crush]
t = [0.0, 0.5, 1.0]
value = [0.0, 0.5, 500.0]
"""


def test_run_writes_outputs(tmp_path):
    out = tmp_path / "out"
    proc = run_cli("run", str(ROOT / "demos/scenes/block_compression.toml"), "--out", str(out))
    assert proc.returncode == 0, proc.stderr
    s = json.loads((out / "summary.json").read_text())
    assert s["converged"] and len(s["steps"]) == 4
    assert s["effects"][0].startswith("material neo-hooke")
    assert proc.stdout.splitlines()[1].strip().startswith("effect:")
    assert set(s["timings"]) >= {"mesh", "jit", "bulk_assembly", "linear_solve", "output", "total"}
    assert "contact" not in s["timings"]  # no contact pair declared: no contact code ran
    for f in ("solution.xdmf", "solution.h5", "reactions.png", "convergence.png"):
        assert (out / f).stat().st_size > 0
    # equilibrium of the last step: the bottom carries p × current top width
    assert s["steps"][-1]["reactions"]["bottom"]["y"] > 100.0


def test_failed_run_keeps_converged_steps(tmp_path):
    scene = tmp_path / "crush.toml"
    scene.write_text(FAILING.replace('value = 100.0', 'value = 100.0\ncurve = "crush"')
                     .replace("count = 4", "count = 4\nmax_cuts = 1"))
    out = tmp_path / "out"
    proc = run_cli("run", str(scene), "--out", str(out))
    assert proc.returncode == 1
    s = json.loads((out / "summary.json").read_text())
    assert not s["converged"]
    assert len(s["steps"]) >= 2 and s["steps"][-1]["time"] < 1.0
    assert "stopped at pseudo-time" in s["message"]
    assert "Traceback" not in proc.stderr
