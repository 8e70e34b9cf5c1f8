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
    # the why on stderr, one line (the log on stdout has the residuals too)
    assert proc.stderr.startswith("fenicsx-mortar: error: run failed: stopped at pseudo-time")
    assert proc.stderr.count("\n") == 1 and "residuals" not in proc.stderr, proc.stderr


def test_a_new_run_replaces_the_previous_runs_files(tmp_path):
    """A second run into the same --out (other pair name, no XDMF, no plots, fewer steps)
    leaves none of the first run's outputs beside its own; other files stay."""
    base = (ROOT / "tests/bad_input/_base.toml").read_text()
    first, second = tmp_path / "first.toml", tmp_path / "second.toml"
    first.write_text(base.replace('name = "c"', 'name = "old"').replace("count = 2", "count = 3"))
    second.write_text(base.replace("count = 2", "count = 1") + "[output]\nxdmf = false\n"
                      "plots = false\n")
    out = tmp_path / "out"
    assert run_cli("run", str(first), "--out", str(out)).returncode == 0
    assert (out / "interface" / "old_0003.csv").is_file() and (out / "solution.h5").is_file()
    (out / "notes.txt").write_text("mine")
    proc = run_cli("run", str(second), "--out", str(out))
    assert proc.returncode == 0, proc.stderr
    left = sorted(str(p.relative_to(out)) for p in out.rglob("*") if p.is_file())
    assert left == ["checkpoint.npz", "interface/c_0001.csv", "notes.txt", "scene.json",
                    "summary.json"], left
    assert len(json.loads((out / "summary.json").read_text())["steps"]) == 1


def test_clearing_a_previous_run_stays_inside_out(tmp_path):
    """Only the previous run's own files go: through a symbolic link named interface/
    nothing is removed, and in interface/ only the files of the pairs its scene.json
    names."""
    from fenicsx_mortar.io.output import clear_previous
    out, elsewhere = tmp_path / "out", tmp_path / "elsewhere"
    out.mkdir()
    elsewhere.mkdir()
    (out / "scene.json").write_text(json.dumps({"contacts": [{"name": "old"}]}))
    (out / "summary.json").write_text("{}")
    for name in ("old_0001.csv", "experiment_2024.csv", "old_notes.csv"):
        (elsewhere / name).write_text("x")
    (out / "interface").symlink_to(elsewhere)
    assert clear_previous(out) == 2                     # scene.json, summary.json
    assert sorted(p.name for p in elsewhere.iterdir()) == [
        "experiment_2024.csv", "old_0001.csv", "old_notes.csv"]
    (out / "interface").unlink()
    (out / "interface").mkdir()
    (out / "scene.json").write_text(json.dumps({"contacts": [{"name": "old"}]}))
    for name in ("old_0001.csv", "old_pressure.png", "experiment_2024.csv", "old_notes.csv"):
        (out / "interface" / name).write_text("x")
    assert clear_previous(out) == 3
    assert sorted(p.name for p in (out / "interface").iterdir()) == [
        "experiment_2024.csv", "old_notes.csv"]
