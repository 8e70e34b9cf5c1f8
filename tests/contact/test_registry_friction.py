"""A registered enforcement with Coulomb friction (issue 27): the friction tangent takes ∇p
from the enforcement's own ∂p/∂g̃, ∂p/∂A, so a new nodal law is one class and its
registration, friction included. The toy law of test_registry.py (a penalty stiffening with
the penetration, made exact by Uzawa) has a consistent tangent in stick and in slip: the
Taylor remainder of the assembled system falls as h² (with ∇p rebuilt from ε it fell as h)."""
from __future__ import annotations

import numpy as np
import pytest

from fenicsx_mortar.contact.registry import ENFORCEMENTS
from test_pair import assert_second_order, system, taylor_remainders, upper_block_state
from test_registry import StiffeningUzawa


@pytest.fixture
def stiffening():
    ENFORCEMENTS.register("toy-stiffening")(StiffeningUzawa)
    yield
    ENFORCEMENTS.unregister("toy-stiffening")


@pytest.mark.parametrize("state", ["stick", "slip"])
@pytest.mark.parametrize("method", ["mortar", "nts"])
def test_registered_enforcement_with_coulomb_has_the_exact_tangent(stiffening, method, state):
    solver, pair = system(method, "toy-stiffening", mu=0.3)
    assert type(pair.enforcement) is StiffeningUzawa
    rng = np.random.default_rng(13)
    x, b = solver.x, solver.x.duplicate()
    x.array[:] = upper_block_state(solver, 0.0005, rng)
    solver.evaluate_residual(x, b)                  # anchors the reference points here
    pair.enforcement.multiplier[:] = rng.uniform(0.5, 1.5, pair.slave.n)
    pair.enforcement.traction[:] = 0.01 * rng.uniform(-1.0, 1.0, pair.slave.n)
    x.array[:] = upper_block_state(solver, 0.0005 + (1e-9 if state == "stick" else 0.013), rng)
    want = 1 if state == "stick" else 2

    def check(st):
        on = st.active
        assert on.sum() >= 5 and np.all(st.tangential.status[on] == want)
        # the law is not ε's: ∂p/∂g̃ differs from −ε/A by the stiffening factor
        A = np.where(st.A > 0, st.A, 1.0)
        assert np.all(np.abs(st.law.dp_dg[on] * A[on] / pair.enforcement.epsilon[on]) > 1.5)

    hs, rem = taylor_remainders(solver, pair, rng, check)
    assert_second_order(hs, rem)
