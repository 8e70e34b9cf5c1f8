"""MPI runs equal the serial one: the bulk is distributed by DOLFINx, contact surfaces are
cut across ranks (each rank integrates the slave segments of the nodes it owns)."""
import sys

import numpy as np
import pytest

from conftest import ROOT, run_python

pytestmark = pytest.mark.mpi

SCENES = {
    "clamped_block": lambda text: text,
    "patch_test": lambda text: text,
    "hertz": lambda text: text.replace("h_contact = 0.0048", "h_contact = 0.012"),
}


@pytest.mark.parametrize("scene_name,ranks,tol", [("clamped_block", 2, 1e-10),
                                                  ("clamped_block", 3, 1e-10),
                                                  ("patch_test", 2, 1e-8),
                                                  ("patch_test", 3, 1e-8),
                                                  ("hertz", 2, 1e-8)])
def test_mpi_equals_serial(scene_name, ranks, tol, tmp_path):
    """Bulk alone to 1e-10; with contact to 1e-8 relative; same Newton iterations."""
    text = (ROOT / f"demos/scenes/{scene_name}.toml").read_text()
    scene = tmp_path / f"{scene_name}.toml"
    scene.write_text(SCENES[scene_name](text))
    script = str(ROOT / "tests/dump_solution.py")
    serial, parallel = tmp_path / "serial.npz", tmp_path / "parallel.npz"
    for n, path in ((1, serial), (ranks, parallel)):
        proc = run_python([sys.executable, script, str(scene), str(path)], ranks=n)
        assert proc.returncode == 0, proc.stderr[-2000:]
    a, b = np.load(serial), np.load(parallel)
    assert bool(a["converged"]) and bool(b["converged"])
    assert np.abs(a["X"] - b["X"]).max() <= 1e-12
    scale = np.abs(a["u"]).max()
    assert scale > 1e-3  # a real deformation, not a trivial zero field
    assert np.abs(a["u"] - b["u"]).max() <= tol * scale
    assert list(a["iterations"]) == list(b["iterations"])
