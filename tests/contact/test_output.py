"""The contact records of a step (fenicsx_mortar.contact.output)."""
import pytest

from conftest import ROOT
from fenicsx_mortar import load_scene, solve


def test_normal_force_is_the_force_carried_where_the_slave_leaves_the_master(tmp_path):
    """A block pushed off the slab's end: at t = 0.3875 three slave nodes in a row are
    barely over the master, so none can take another's terms, and with the dual basis
    their ∫Φ_j is far from their area A_j. The record's normal force must still be the
    force the slave carries (here the applied load, on a flat interface); Σ p A reported
    6.0 for a force of 0.39."""
    scene = load_scene(ROOT / "tests/bad_input/_base.toml")
    scene.dirichlet[1].x = 5.0
    scene.steps.count = None
    scene.steps.times = [0.1, 0.2, 0.3, 0.35, 0.375, 0.3875]
    result = solve(scene, tmp_path / "out")
    assert result.converged
    last = result.steps[-1]["contact"]["c"]
    assert last["max_pressure"] > 100.0       # the barely supported nodes are there
    for step in result.steps:
        c = step["contact"]["c"]
        assert c["normal_force"] == pytest.approx(c["force_on_slave"][1], rel=1e-3)
