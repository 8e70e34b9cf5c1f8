"""Reference values the benchmarks measure against: the Hertz solution of the B2 scene and
its pressure metrics, and the error and oscillation of a B3 reaction curve.

One definition for the study, ``hertz_refinement.py`` and the tests; ``demos/demo_hertz.py``
keeps its own two lines of the formulas so that it reads on its own (tests/test_study.py
checks that the two agree).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

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


# ---------------------------------------------------------------- shrink fit (curved interface)
# meshes/shrink_fit.py, demos/scenes/shrink_fit.toml, docs/curved_interface.md: an inner ring
# a <= r <= b + δ shrunk into an outer ring b <= r <= c (radial interference δ), plane
# strain, no other load. Lamé: a thick ring carries u(r) = A r + B/r.


def lame_displacement(r, r_in: float, r_out: float, p_in: float, p_out: float,
                      E: float, nu: float):
    """Radial displacement u(r) of a plane-strain thick ring r_in ≤ r ≤ r_out under the
    pressures p_in (on r = r_in) and p_out (on r = r_out), p > 0 compressive (Lamé; e.g.
    Timoshenko & Goodier, Theory of Elasticity, §28, with E → E/(1−ν²), ν → ν/(1−ν)):

        u(r) = (1+ν)/E · [ (1−2ν) (p_in r_in² − p_out r_out²) r
                           + (p_in − p_out) r_in² r_out² / r ] / (r_out² − r_in²)."""
    r = np.asarray(r, dtype=float)
    d = r_out**2 - r_in**2
    return (1.0 + nu) / E * ((1.0 - 2.0 * nu) * (p_in * r_in**2 - p_out * r_out**2) * r
                             + (p_in - p_out) * r_in**2 * r_out**2 / r) / d


def ring_compliance_inside(r_in: float, r_out: float, E: float, nu: float) -> float:
    """u(r_in)/p of a plane-strain ring under internal pressure p alone (the outer ring of a
    shrink fit; Lamé): (1+ν) r_in/E · ((1−2ν) r_in² + r_out²)/(r_out² − r_in²)."""
    return (1.0 + nu) * r_in / E * ((1.0 - 2.0 * nu) * r_in**2 + r_out**2) / (r_out**2 - r_in**2)


def ring_compliance_outside(r_in: float, r_out: float, E: float, nu: float) -> float:
    """−u(r_out)/p of a plane-strain ring under external pressure p alone (the inner ring of
    a shrink fit; Lamé): (1+ν) r_out/E · ((1−2ν) r_out² + r_in²)/(r_out² − r_in²)."""
    return (1.0 + nu) * r_out / E * ((1.0 - 2.0 * nu) * r_out**2 + r_in**2) / (r_out**2 - r_in**2)


def shrink_fit_pressure(a: float, b: float, c: float, delta: float, E1: float, nu1: float,
                        E2: float | None = None, nu2: float | None = None) -> float:
    """Classical (small-interference) shrink-fit contact pressure, plane strain: inner ring
    a ≤ r ≤ b (E1, ν1), outer ring b ≤ r ≤ c (E2, ν2, default those of the inner ring),
    radial interference δ. Compatibility u_outer(b) − u_inner(b) = δ with the two Lamé
    compliances gives

        p_c = δ / ( b [ (1+ν₂)/E₂ · ((1−2ν₂) b² + c²)/(c² − b²)
                      + (1+ν₁)/E₁ · ((1−2ν₁) b² + a²)/(b² − a²) ] ),

    for one material p_c = E δ (c² − b²)(b² − a²) / (2 (1−ν²) b³ (c² − a²)) (the textbook
    plane-stress formula, e.g. Shigley's Mechanical Engineering Design §3-16, with
    E → E/(1−ν²)). Exact to first order in δ/b."""
    E2 = E1 if E2 is None else E2
    nu2 = nu1 if nu2 is None else nu2
    return delta / (ring_compliance_inside(b, c, E2, nu2) + ring_compliance_outside(a, b, E1, nu1))


@dataclass
class ShrinkFit:
    """A shrink-fit solution at the interface: ``pressure`` p = f/r_c per unit current
    length (what the mortar's nodal pressures are), ``force`` f = the radial contact force
    per radian, ``r_contact`` r_c the current contact radius, ``u_inner`` and ``u_outer`` the
    radial displacements of the inner ring's outer arc (r = b + δ, < 0) and of the outer
    ring's inner arc (r = b, > 0)."""
    pressure: float
    force: float
    r_contact: float
    u_inner: float
    u_outer: float


def shrink_fit_linear(a: float, b: float, c: float, delta: float, E1: float, nu1: float,
                      E2: float | None = None, nu2: float | None = None) -> ShrinkFit:
    """The exact solution of the package's ``linear`` model of the shrink fit: small-strain
    Lamé rings on their reference geometry (inner a ≤ r ≤ b + δ, outer b ≤ r ≤ c), contact
    in the current configuration, b + δ + u_inner = b + u_outer = r_c. The contact force
    per radian f is the traction times the reference radius on either ring, so with the
    compliances C_in = −u_inner/q (ring a..b+δ, external q) and C_out = u_outer/q (ring
    b..c, internal q) of :func:`ring_compliance_outside` / :func:`ring_compliance_inside`:

        f = δ / ( C_in/(b+δ) + C_out/b ),   u_outer = f C_out / b,   r_c = b + u_outer,
        p = f / r_c   (per current length; = p_c of :func:`shrink_fit_pressure` + O(δ/b))."""
    E2 = E1 if E2 is None else E2
    nu2 = nu1 if nu2 is None else nu2
    bi = b + delta
    c_in = ring_compliance_outside(a, bi, E1, nu1)
    c_out = ring_compliance_inside(b, c, E2, nu2)
    f = delta / (c_in / bi + c_out / b)
    u_out = f * c_out / b
    r_c = b + u_out
    return ShrinkFit(pressure=f / r_c, force=f, r_contact=r_c, u_inner=-f * c_in / bi,
                     u_outer=u_out)


def _neo_hooke_radial(lr, lt, mu: float, lmbda: float):
    """Principal first Piola stresses (P_r, P_θ) and ∂P_r/∂λ_r, ∂P_r/∂λ_θ of the plane-strain
    compressible Neo-Hooke law (fenicsx_mortar/materials.py) at stretches λ_r, λ_θ."""
    lnJ = np.log(lr * lt)
    Pr = mu * (lr - 1.0 / lr) + lmbda * lnJ / lr
    Pt = mu * (lt - 1.0 / lt) + lmbda * lnJ / lt
    dPr_dlr = mu * (1.0 + 1.0 / lr**2) + lmbda * (1.0 - lnJ) / lr**2
    dPr_dlt = lmbda / (lr * lt)
    return Pr, Pt, dPr_dlr, dPr_dlt


def shrink_fit_neo_hooke(a: float, b: float, c: float, delta: float, E: float, nu: float,
                         tol: float = 1e-11) -> ShrinkFit:
    """The axisymmetric finite-deformation solution of the shrink fit for the plane-strain
    Neo-Hooke law ψ = μ/2 (tr C − 2) − μ ln J + λ/2 (ln J)² (both rings E, ν), computed
    numerically (not closed form): the deformation R ↦ r(R) of each ring has stretches
    λ_r = r′, λ_θ = r/R, J = λ_r λ_θ, principal Piola stresses
    P_r = μ(λ_r − 1/λ_r) + λ ln J/λ_r, P_θ = μ(λ_θ − 1/λ_θ) + λ ln J/λ_θ, and satisfies the
    radial equilibrium dP_r/dR + (P_r − P_θ)/R = 0 with P_r = 0 on r = a and r = c, and at
    the interface r_inner(b + δ) = r_outer(b) = r_c and equal forces per radian,
    f = −(b + δ) P_r,inner = −b P_r,outer. Both rings are solved together as one
    two-point boundary value problem (scipy ``solve_bvp``, relative tolerance ``tol``, from
    the linear solution); p = f/r_c is the Cauchy pressure at the interface. Tends to
    :func:`shrink_fit_linear` as δ → 0."""
    from scipy.integrate import solve_bvp

    mu = E / (2.0 * (1.0 + nu))
    lmbda = E * nu / ((1.0 + nu) * (1.0 - 2.0 * nu))
    bi = b + delta
    L1, L2 = bi - a, c - b
    lin = shrink_fit_linear(a, b, c, delta, E, nu)

    def radii(t):
        return a + t * L1, b + t * L2

    def rhs(t, y):
        out = []
        for (R, L), (r, dr) in zip(zip(radii(t), (L1, L2)), (y[0:2], y[2:4])):
            lr, lt = dr / L, r / R                     # dr is dr/dt
            Pr, Pt, dlr, dlt = _neo_hooke_radial(lr, lt, mu, lmbda)
            # dP_r/dR = (P_θ − P_r)/R, with dP_r/dR = ∂P_r/∂λ_r r″ + ∂P_r/∂λ_θ (r′ − r/R)/R
            r2 = ((Pt - Pr) / R - dlt * (lr - lt) / R) / dlr
            out += [dr, r2 * L**2]
        return np.vstack(out)

    def bc(y0, y1):
        Pr1a = _neo_hooke_radial(y0[1] / L1, y0[0] / a, mu, lmbda)[0]
        Pr1b = _neo_hooke_radial(y1[1] / L1, y1[0] / bi, mu, lmbda)[0]
        Pr2b = _neo_hooke_radial(y0[3] / L2, y0[2] / b, mu, lmbda)[0]
        Pr2c = _neo_hooke_radial(y1[3] / L2, y1[2] / c, mu, lmbda)[0]
        return np.array([Pr1a / E, Pr2c / E, (y1[0] - y0[2]) / b, (bi * Pr1b - b * Pr2b) / E])

    t = np.linspace(0.0, 1.0, 41)
    R1, R2 = radii(t)
    q1, q2 = lin.force / bi, lin.force / b
    u1 = lame_displacement(R1, a, bi, 0.0, q1, E, nu)
    u2 = lame_displacement(R2, b, c, q2, 0.0, E, nu)
    du1 = np.gradient(R1 + u1, t)
    du2 = np.gradient(R2 + u2, t)
    sol = solve_bvp(rhs, bc, t, np.vstack([R1 + u1, du1, R2 + u2, du2]), tol=tol,
                    max_nodes=100000)
    if not sol.success:
        raise RuntimeError(f"shrink_fit_neo_hooke: solve_bvp failed: {sol.message}")
    y1 = sol.sol(1.0)
    y0 = sol.sol(0.0)
    Pr = _neo_hooke_radial(y1[1] / L1, y1[0] / bi, mu, lmbda)[0]
    f = -bi * float(Pr)
    r_c = float(y0[2])
    return ShrinkFit(pressure=f / r_c, force=f, r_contact=r_c, u_inner=float(y1[0]) - bi,
                     u_outer=r_c - b)
