"""Reference values the benchmarks measure against: the Hertz solution of the B2 scene and
its pressure metrics, and the error and oscillation of a B3 reaction curve.

One definition for the study, ``hertz_refinement.py`` and the tests; ``demos/demo_hertz.py``
keeps its own two lines of the formulas so that it reads on its own (tests/test_study.py
checks that the two agree).
"""
from __future__ import annotations

import math

import numpy as np
from scipy.integrate import trapezoid

# ---------------------------------------------------------------- Hertz (B2)
# demos/scenes/hertz.toml, docs/hertz.md: R = 1, F = 1 (traction 0.5 on the flat edge of
# width 2), both bodies E = 1000, nu = 0.3


def effective_modulus(E1: float, nu1: float, E2: float, nu2: float) -> float:
    """E* of two elastic bodies: 1/E* = (1 − ν₁²)/E₁ + (1 − ν₂²)/E₂."""
    return 1.0 / ((1.0 - nu1**2) / E1 + (1.0 - nu2**2) / E2)


def half_width(F: float, R: float, E_star: float) -> float:
    """Contact half-width a = 2 √(F R / (π E*)) (plane strain, force per unit thickness)."""
    return 2.0 * math.sqrt(F * R / (math.pi * E_star))


def peak_pressure(F: float, a: float) -> float:
    """p₀ = 2F / (π a)."""
    return 2.0 * F / (math.pi * a)


def pressure(x, a: float, p0: float):
    """The Hertz pressure p₀ √(1 − x²/a²), 0 outside [−a, a]."""
    x = np.asarray(x)
    return p0 * np.sqrt(np.clip(1 - x**2 / a**2, 0, None))


HERTZ_R, HERTZ_F, HERTZ_E, HERTZ_NU = 1.0, 1.0, 1000.0, 0.3
HERTZ_E_STAR = effective_modulus(HERTZ_E, HERTZ_NU, HERTZ_E, HERTZ_NU)
HERTZ_A = half_width(HERTZ_F, HERTZ_R, HERTZ_E_STAR)
HERTZ_P0 = peak_pressure(HERTZ_F, HERTZ_A)


def pressure_metrics(x, p, force: float) -> dict:
    """Nodal pressures ``p`` at the slave nodes' current positions ``x`` against the B2
    solution, and ``force`` F_c, the vertical contact force on the disk (the block pushes it
    up with F): ``p0_error`` = p_max/p₀ − 1, ``a_error`` = a_fit/a − 1 (a_fit: least-squares
    fit of p_max √(1 − x²/a_fit²) to the nodal pressures), ``l2_error`` = relative L2 error
    of the piecewise-linear nodal pressure on [−a, a], ``force_error`` = |F_c − F|/F; also
    ``p_max`` and ``a_fit``."""
    from scipy.optimize import minimize_scalar
    a, p0 = HERTZ_A, HERTZ_P0
    order = np.argsort(x)
    x, p = np.asarray(x)[order], np.asarray(p)[order]
    p_max = float(p.max())
    fit = minimize_scalar(lambda s: np.sum((p - pressure(x, s, p_max))**2),
                          bounds=(0.5 * a, 2.0 * a), method="bounded", options={"xatol": 1e-10})
    xs = np.linspace(-a, a, 4001)
    exact = pressure(xs, a, p0)
    l2 = np.sqrt(trapezoid((np.interp(xs, x, p) - exact)**2, xs) / trapezoid(exact**2, xs))
    a_fit = float(fit.x)
    return {"p0_error": p_max / p0 - 1.0, "a_error": a_fit / a - 1.0, "l2_error": float(l2),
            "force_error": abs(force - HERTZ_F) / HERTZ_F, "p_max": p_max, "a_fit": a_fit}


def hertz_metrics(result) -> dict:
    """:func:`pressure_metrics` of a solved B2 scene, from its first contact pair: the
    disk's arc is the slave (``demos/scenes/hertz.toml``) or, roles swapped, the master."""
    d = result.pairs[0].interface()
    pair = result.scene.contacts[0]
    f = result.steps[-1]["contact"][pair.name]["force_on_slave"][1]
    return pressure_metrics(d["x"], d["pressure"], f if pair.slave == "disk_arc" else -f)


# ---------------------------------------------------------------- B3 reaction curves


def reaction_errors(curve: list, reference: list | None, times: list[float],
                    turn_start: float = 1.0) -> tuple[float, float]:
    """(error, oscillation) of a reaction curve [[t, Rx, Ry], ...] sampled at ``times``.

    error: max over ``times`` of |R(t) − R_ref(t)| / max |R_ref| (NaN without a reference).
    oscillation: over the turn (the times from ``turn_start`` on; the B3 scene's press ends
    at t = 1), the largest distance of R(t) from its least-squares cubic in t, divided by
    max |R|: 0 for a curve as smooth as a cubic, about the wiggle amplitude / max |R| for a
    curve that wiggles as the slave nodes pass the master's nodes. Both are NaN when the
    curve misses one of the times it needs (a run that stopped early)."""
    R = _at_times(curve, times)
    osc = float("nan")
    turn = [k for k, t in enumerate(times) if t > turn_start - 1e-12]
    if not np.isnan(R[turn]).any():
        t = np.array(times)[turn] - turn_start
        V = np.vander(t, 4)
        fit = V @ np.linalg.lstsq(V, R[turn], rcond=None)[0]
        osc = float(np.linalg.norm(R[turn] - fit, axis=1).max()
                    / np.linalg.norm(R, axis=1).max())
    err = float("nan")
    if reference:
        Rr = _at_times(reference, times)
        if not (np.isnan(R).any() or np.isnan(Rr).any()):
            err = float(np.linalg.norm(R - Rr, axis=1).max() / np.linalg.norm(Rr, axis=1).max())
    return err, osc


def _at_times(curve: list, times: list[float]) -> np.ndarray:
    """Reactions at ``times`` (rows of NaN where the run did not reach a time)."""
    out = np.full((len(times), 2), np.nan)
    for t, rx, ry in curve:
        for k, tk in enumerate(times):
            if abs(t - tk) < 1e-9:
                out[k] = rx, ry
    return out
