"""A new smoothing, enforcement or friction law is one class plus one registration: each toy
class below is defined and registered here alone, and the contact patch test (B1) then runs
with it through the scene layer (validation, the pair, the solver) and stays exact: σ_yy = −1
in every cell (docs/benchmarks.md B1)."""
import numpy as np
import pytest

from conftest import ROOT
from fenicsx_mortar import load_scene, solve
from fenicsx_mortar.contact import ad
from fenicsx_mortar.contact.curves import MasterCurve, Polyline
from fenicsx_mortar.contact.enforcement import AugmentedLagrangian, NodalPressure
from fenicsx_mortar.contact.friction import INACTIVE, SLIP, STICK, Coulomb
from fenicsx_mortar.contact.registry import ENFORCEMENTS, FRICTION_LAWS, SMOOTHINGS


class WarpedPolyline(Polyline):
    """The polyline with a non-uniform parametrization x(ξ) = x_c + φ(ξ)(x_d − x_c),
    φ = ξ + κ ξ(1 − ξ): the same geometry, so the projection (closest point, safeguarded
    Newton on the power form) and the mortar integrals must give the polyline's answer."""
    kappa = 0.5

    def derivatives(self, seg_index, xi, P, order):
        c, d = P[1], P[2]
        e = ad.sub(d, c)
        k = self.kappa
        phi = xi + (xi - xi * xi) * k
        out = [ad.add(c, ad.scale(e, phi)), ad.scale(e, 1.0 + k - 2.0 * k * xi),
               ad.scale(e, -2.0 * k)]
        return out[:order + 1]

    def _coefficients(self, seg_index, P):
        c, d = P[1], P[2]
        e = ad.sub(d, c)
        return [c, ad.scale(e, 1.0 + self.kappa), ad.scale(e, -self.kappa)]

    # the polyline's closed-form shortcuts do not hold for this parametrization
    project = MasterCurve.project
    gap = MasterCurve.gap


class StiffeningUzawa(AugmentedLagrangian):
    """p = ⟨p̂ + ε γ (1 + |γ|/γ₀)⟩₊ with γ = −g̃/A (the average penetration), γ₀ = 1e-3: a
    penalty that stiffens with the penetration, made exact by the augmented Lagrangian's
    Uzawa updates (its ``augment``): only the nodal law is new."""
    gamma0 = 1e-3

    def pressure(self, g, A):
        seen = A > 0
        As = np.where(seen, A, 1.0)
        gamma = -g / As
        eps = self.epsilon
        trial = np.where(seen, self.multiplier + eps * gamma * (1 + np.abs(gamma) / self.gamma0),
                         -np.inf)
        active = trial >= 0.0
        dp_dgamma = eps * (1.0 + 2.0 * np.abs(gamma) / self.gamma0)
        return NodalPressure(np.where(active, trial, 0.0), active, -dp_dgamma / As,
                             dp_dgamma * g / As**2)


class Tresca(Coulomb):
    """Tresca friction: the tangential traction is bounded by a constant shear strength τ
    (the scene's ``mu`` read as τ), not by μ p."""

    def traction(self, trial, p, active):
        tau = self.mu
        slip = active & (np.abs(trial) > tau)
        stick = active & ~slip
        t = np.where(stick, trial, np.where(slip, tau * np.sign(trial), 0.0))
        status = np.where(stick, STICK, np.where(slip, SLIP, INACTIVE))
        return t, status, np.where(stick, 1.0, 0.0), np.zeros_like(t)


@pytest.fixture
def registered():
    """Register the toys (one line each), unregister them afterwards."""
    SMOOTHINGS.register("toy-warped")(WarpedPolyline)
    ENFORCEMENTS.register("toy-stiffening")(StiffeningUzawa)
    FRICTION_LAWS.register("toy-tresca")(Tresca)
    yield
    SMOOTHINGS.unregister("toy-warped")
    ENFORCEMENTS.unregister("toy-stiffening")
    FRICTION_LAWS.unregister("toy-tresca")


def patch_test(**changes):
    scene = load_scene(ROOT / "demos/scenes/patch_test.toml")
    c = scene.contacts[0]
    c.smoothing = changes.get("smoothing", c.smoothing)
    c.enforcement.type = changes.get("enforcement", c.enforcement.type)
    if "friction" in changes:
        c.friction.law, c.friction.mu = changes["friction"], 0.05
    scene.validate()                         # the scene layer knows the new names
    res = solve(scene, log=lambda s: None)
    assert res.converged, res.message
    return res


@pytest.mark.parametrize("change", [{"smoothing": "toy-warped"},
                                    {"enforcement": "toy-stiffening"},
                                    {"friction": "toy-tresca"}], ids=lambda d: str(d))
def test_registered_toy_passes_the_patch_test(registered, change):
    res = patch_test(**change)
    sigma = res.stress.values()
    assert np.abs(sigma[:, 1, 1] + 1.0).max() <= 1e-8
    assert np.abs(sigma[:, 0, 0]).max() <= 1e-8 and np.abs(sigma[:, 0, 1]).max() <= 1e-8
    pair = res.pairs[0]
    kind = next(iter(change))
    used = {"smoothing": type(pair.state.curve), "enforcement": type(pair.enforcement),
            "friction": type(pair.friction)}[kind]
    assert used is {"smoothing": WarpedPolyline, "enforcement": StiffeningUzawa,
                    "friction": Tresca}[kind]
    d = pair.interface()
    active = d["pressure"] > 0
    assert np.allclose(d["pressure"][active], 1.0, rtol=1e-8)
    if kind == "friction":   # both blocks expand alike about x = 2: no slip, no traction
        assert np.abs(d["t_tangential"]).max() <= 1e-8


def test_unknown_names_list_the_registered_ones(registered):
    scene = load_scene(ROOT / "demos/scenes/patch_test.toml")
    scene.contacts[0].smoothing = "toy-nonesuch"
    with pytest.raises(ValueError, match="toy-warped"):
        scene.validate()
