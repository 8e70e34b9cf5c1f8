"""Coulomb friction on the block-on-slab benchmark (B5, docs/benchmarks.md)."""
import numpy as np
import pytest

from conftest import ROOT
from fenicsx_mortar import Friction, Traction, load_scene, solve


def b5(times, **change):
    scene = load_scene(ROOT / "demos/scenes/block_on_slab.toml")
    scene.steps.times = times
    for k, v in change.items():
        setattr(scene.contacts[0], k, v)
    return scene


@pytest.mark.parametrize("method", ["mortar", "nts"])
def test_sliding_block_carries_mu_times_normal_force(method):
    result = solve(b5([1.0, 1.5, 2.0], method=method), log=lambda s: None)
    assert result.converged, result.message
    last = result.steps[-1]
    c = last["contact"]["interface"]
    d = result.pairs[0].interface()
    on = d["pressure"] > 0
    assert on.sum() >= 5 and np.all(d["status"][on] == "slip")
    # every slipping node sits on the cone: |t_T| = μ p
    assert np.allclose(np.abs(d["t_tangential"][on]), 0.3 * d["pressure"][on], rtol=1e-12)
    # resultants: tangential = μ × normal (contact frame), and the push is what the
    # interface carries (Cartesian equilibrium of the block)
    assert abs(c["tangential_force"]) == pytest.approx(0.3 * c["normal_force"], rel=1e-8)
    fx = c["force_on_slave"][0] + c["tangential_force_on_slave"][0]
    assert last["reactions"]["push"]["x"] == pytest.approx(-fx, rel=1e-8)
    assert last["reactions"]["push"]["x"] > 0.29


def test_stuck_block_carries_the_applied_force():
    """Load-controlled: a traction on the left edge with resultant 0.8 μN; the block does
    not slide and the interface carries exactly the applied force."""
    scene = b5([1.0, 2.0])
    scene.dirichlet = [d for d in scene.dirichlet if d.name != "push"]
    applied = 0.8 * 0.3 * 1.0
    scene.tractions = [Traction(boundary="block_left", value=[applied / 0.5, 0.0], curve="slide")]
    result = solve(scene, log=lambda s: None)
    assert result.converged, result.message
    c = result.steps[-1]["contact"]["interface"]
    fx = c["force_on_slave"][0] + c["tangential_force_on_slave"][0]
    assert -fx == pytest.approx(applied, rel=1e-8)
    d = result.pairs[0].interface()
    on = d["pressure"] > 0
    assert np.mean(d["status"][on] == "stick") > 0.5


def test_zero_mu_reproduces_frictionless():
    runs = []
    for fr in (Friction(), Friction(law="coulomb", mu=0.0)):
        scene = b5([1.0], friction=fr)
        result = solve(scene, log=lambda s: None)
        assert result.converged, result.message
        runs.append(result.u.x.array.copy())
    assert np.abs(runs[0] - runs[1]).max() <= 1e-10 * np.abs(runs[0]).max()
