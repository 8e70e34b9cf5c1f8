"""Normal-contact enforcement (fenicsx_mortar.contact.enforcement): the penalty
continuation solves each load step first at E/h and raises ε ×10 per converged solve; only
the last solve, at the scene's ε, defines the answer."""
from __future__ import annotations

import numpy as np
import pytest

from fenicsx_mortar import solve
from fenicsx_mortar.contact import enforcement
from benchmarks.study.cases import Case
from benchmarks.study.scenes import make_scene


def _hertz(level: int, enf: str):
    return make_scene(Case("hertz", "mortar", "none", enf, level))


def test_penalty_continuation_gives_the_stiff_penalty_answer(monkeypatch):
    # Hertz a/8, penalty 100 E/h converges both ways: the continuation must end at the
    # same discrete solution as the direct solve (the same equations, another start)
    cont = solve(_hertz(2, "penalty-100"), log=lambda s: None)
    assert cont.converged, cont.message
    assert all(s["augmentations"] >= 2 for s in cont.steps)      # E/h -> 10 -> 100 E/h
    monkeypatch.setattr(enforcement.Penalty, "begin_step",
                        lambda self: self.epsilon.fill(self.epsilon0))
    direct = solve(_hertz(2, "penalty-100"), log=lambda s: None)
    assert direct.converged, direct.message
    assert all(s["augmentations"] == 0 for s in direct.steps)
    u, u0 = cont.u.x.array, direct.u.x.array
    assert np.abs(u - u0).max() <= 1e-8 * np.abs(u0).max()


@pytest.mark.parametrize("level", [1, 3])
def test_stiff_penalty_hertz_converges(level):
    # a/4 and a/16 with 100 E/h stalled in the first increment before the continuation
    # (every cut down to the floor); checked physically: the contact force on the disk
    # balances the dead load F = 1; the last solve ran at the scene's ε
    res = solve(_hertz(level, "penalty-100"), log=lambda s: None)
    assert res.converged, res.message
    rec = res.steps[-1]["contact"]["hertz"]
    assert rec["force_on_slave"][1] == pytest.approx(1.0, rel=1e-8)
    assert rec["epsilon_max"] == rec["epsilon"]
