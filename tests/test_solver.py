"""Newton driver (fenicsx_mortar.solver): the retry with full Newton steps."""
from __future__ import annotations

import pytest

from fenicsx_mortar import solve
from benchmarks.study.cases import Case
from benchmarks.study.scenes import make_scene


def test_full_newton_retry_rescues_stiff_penalty_hertz(monkeypatch):
    """Hertz (dead load F = 1, the disk held by contact alone), mortar, penalty 10 E/h at
    h = a/2, without the penalty continuation (every solve at the final ε): the l2 line
    search stalls on the active set's kinks in the first increment (this failed at every
    cut down to the floor); the increment retried with full Newton steps converges.
    Checked physically: the contact force on the disk balances the load (F = 1 downward,
    so the block pushes the disk up with 1)."""
    from fenicsx_mortar.contact import enforcement
    monkeypatch.setattr(enforcement.Penalty, "begin_step",
                        lambda self: self.epsilon.fill(self.epsilon0))
    scene = make_scene(Case("hertz", "mortar", "none", "penalty-10", 0))
    res = solve(scene, log=lambda s: None)
    assert res.converged, res.message
    rec = res.steps[-1]["contact"]["hertz"]
    assert rec["force_on_slave"][1] == pytest.approx(1.0, rel=1e-8)
