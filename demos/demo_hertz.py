"""Hertz contact of a half-disk on a block (B2) — mortar pressure against the analytic one.

Problem: a half-disk of radius R = 1 (slave surface: its arc) is pressed onto the block
[−1, 1] × [−1, 0] (master: its top) by a dead traction 0.5 on its flat edge, total force
F = 1 per unit thickness; E = 1000, ν = 0.3 for both, plane strain, Neo-Hooke (scene
``demos/scenes/hertz.toml``; element size h_c = a/10 near the contact). The disk is held
vertically by contact alone.

Analytic (small strain): 1/E* = 2(1 − ν²)/E, a = 2√(F R/(π E*)), p₀ = 2F/(π a),
p(x) = p₀ √(1 − x²/a²).

Expected result: the largest nodal pressure is within 2 % of p₀, the contact half-width
from a least-squares fit of p₀√(1 − x²/a²) to the nodal pressures is within 2 % of a,
the relative L2 error of the pressure over [−a, a] is a few per cent, and the total
contact force equals the applied force to round-off.
"""
from pathlib import Path

import numpy as np
from scipy.integrate import trapezoid
from scipy.optimize import minimize_scalar

from fenicsx_mortar import load_scene, solve

F, R, E, NU = 1.0, 1.0, 1000.0, 0.3
E_star = 1.0 / (2.0 * (1.0 - NU**2) / E)
a = 2.0 * np.sqrt(F * R / (np.pi * E_star))
p0 = 2.0 * F / (np.pi * a)


def hertz_metrics(result) -> dict:
    """p_max/p₀ − 1, a_fit/a − 1, relative L2 pressure error on [−a, a], force balance."""
    d = result.pairs[0].interface()
    x, p = d["x"], d["pressure"]
    order = np.argsort(x)
    x, p = x[order], p[order]
    p_max = p.max()
    fit = minimize_scalar(
        lambda s: np.sum((p - p_max * np.sqrt(np.clip(1 - x**2 / s**2, 0, None)))**2),
        bounds=(0.5 * a, 2.0 * a), method="bounded", options={"xatol": 1e-10})
    xs = np.linspace(-a, a, 4001)
    exact = p0 * np.sqrt(np.clip(1 - xs**2 / a**2, 0, None))
    l2 = np.sqrt(trapezoid((np.interp(xs, x, p) - exact)**2, xs) / trapezoid(exact**2, xs))
    fy = result.steps[-1]["contact"]["hertz"]["force_on_slave"][1]  # block pushes disk up
    return {"p0_error": p_max / p0 - 1, "a_error": fit.x / a - 1, "l2_error": l2,
            "force_error": abs(fy - F) / F, "p_max": p_max, "a_fit": fit.x}


if __name__ == "__main__":
    scene = load_scene(Path(__file__).parent / "scenes" / "hertz.toml")
    result = solve(scene, log=lambda s: None)
    assert result.converged, result.message
    m = hertz_metrics(result)
    print(f"analytic: a = {a:.5f}, p0 = {p0:.4f}")
    print(f"computed: a_fit = {m['a_fit']:.5f} ({100 * m['a_error']:+.2f} %), "
          f"p_max = {m['p_max']:.4f} ({100 * m['p0_error']:+.2f} %)")
    print(f"relative L2 pressure error on [-a, a]: {100 * m['l2_error']:.2f} %")
    print(f"|total contact force - F| / F = {m['force_error']:.1e}")
    print("Newton iterations per step:", [s["newton_iterations"] for s in result.steps],
          " augmentations:", [s["augmentations"] for s in result.steps])
    assert abs(m["p0_error"]) < 0.02 and abs(m["a_error"]) < 0.02 and m["force_error"] < 1e-8
    print("OK: p0 and a within 2 %, force balance to round-off")
