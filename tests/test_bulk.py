"""Bulk physics against closed-form homogeneous plane-strain solutions (docs/design.md §2).

A unit block, u_y = 0 at the bottom, u_x = 0 on the left, a pressure p on the top, right edge
free. The exact deformation is homogeneous, F = diag(λ₁, λ₂), which linear elements
represent exactly, so nodal displacements and cell stresses must match to solver precision.
"""
import numpy as np
import pytest
from scipy.optimize import fsolve

from fenicsx_mortar import (Body, Dirichlet, Material, MeshSource, Pressure, Scene,
                            SolverSettings, Steps, solve)
from fenicsx_mortar.scene.materials import lame

E, NU, P = 1000.0, 0.3, 150.0


def block_scene(model: str, cell: str, follower: bool, steps: int = 3) -> Scene:
    return Scene(
        mesh=MeshSource(generator="block", cell=cell, params={"nx": 3, "ny": 5}),
        bodies=[Body("block", Material(model, E, NU))],
        dirichlet=[Dirichlet(boundary="bottom", y=0.0), Dirichlet(boundary="left", x=0.0)],
        pressures=[Pressure(boundary="top", value=P, follower=follower)],
        steps=Steps(count=steps),
        solver=SolverSettings(atol=1e-11, rtol=1e-12),
    )


def exact_stretches(model: str) -> tuple[float, float]:
    """(λ₁, λ₂) from σ_xx = 0 and the top load, solved to machine precision."""
    mu, lm = lame(E, NU)

    def eqs(s):
        l1, l2 = s
        J = l1 * l2
        if model == "neo-hooke":   # σ = J⁻¹[μ(FFᵀ − I) + λ ln J I]
            sxx = (mu * (l1**2 - 1) + lm * np.log(J)) / J
            syy = (mu * (l2**2 - 1) + lm * np.log(J)) / J
        elif model == "svk":       # σ = J⁻¹ F S Fᵀ
            E11, E22 = 0.5 * (l1**2 - 1), 0.5 * (l2**2 - 1)
            sxx = l1**2 * (lm * (E11 + E22) + 2 * mu * E11) / J
            syy = l2**2 * (lm * (E11 + E22) + 2 * mu * E22) / J
        else:                      # small strain; with a dead load σ_yy = −p
            e11, e22 = l1 - 1, l2 - 1
            return [lm * (e11 + e22) + 2 * mu * e11, lm * (e11 + e22) + 2 * mu * e22 + P]
        return [sxx, syy + P]  # follower pressure: Cauchy σ_yy = −p on the current top
    sol = fsolve(eqs, [1.0, 1.0], xtol=1e-12)
    assert np.abs(eqs(sol)).max() <= 1e-11 * P
    return float(sol[0]), float(sol[1])


def assert_homogeneous(res, l1: float, l2: float) -> np.ndarray:
    """Converged to the exact homogeneous state: nodal displacements ((λ₁ − 1) X, (λ₂ − 1) Y),
    cell stresses σ_yy = −p and σ_xx = 0, all to solver precision; returns the stresses."""
    assert res.converged
    u = res.u.x.array.reshape(-1, 2)
    X = res.u.function_space.tabulate_dof_coordinates()[:, :2]
    exact = np.column_stack([(l1 - 1) * X[:, 0], (l2 - 1) * X[:, 1]])
    assert np.abs(u - exact).max() <= 1e-8 * np.abs(exact).max()
    sigma = res.stress.values()
    assert np.abs(sigma[:, 1, 1] + P).max() <= 1e-8 * P
    assert np.abs(sigma[:, 0, 0]).max() <= 1e-8 * P
    return sigma


@pytest.mark.parametrize("cell", ["quadrilateral", "triangle"])
@pytest.mark.parametrize("model", ["neo-hooke", "svk"])
def test_homogeneous_compression_hyperelastic(model, cell):
    l1, l2 = exact_stretches(model)
    res = solve(block_scene(model, cell, follower=True))
    sigma = assert_homogeneous(res, l1, l2)
    assert np.abs(sigma[:, 0, 1]).max() <= 1e-8 * P
    # equilibrium: the bottom support carries the pressure on the current top width λ₁
    assert res.steps[-1]["reactions"]["bottom"]["y"] == pytest.approx(P * l1, rel=1e-9)
    # Newton on a smooth problem: few iterations per step
    assert max(s["newton_iterations"] for s in res.steps) <= 6


@pytest.mark.parametrize("cell", ["quadrilateral", "triangle"])
def test_homogeneous_compression_linear(cell):
    l1, l2 = exact_stretches("linear")
    res = solve(block_scene("linear", cell, follower=False, steps=1))
    assert_homogeneous(res, l1, l2)
    # a linear problem: Newton converges in one iteration
    assert res.steps[0]["newton_iterations"] == 1
