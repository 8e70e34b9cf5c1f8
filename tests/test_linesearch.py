"""The ``l2-full`` line search (fenicsx_mortar/linesearch.py) on small algebraic systems
driven by PETSc's SNES: away from the quadratic tail it is PETSc's ``l2`` step for step,
in the tail it is Newton's full step at one residual evaluation per iteration."""
import numpy as np
import pytest
from petsc4py import PETSc

from fenicsx_mortar import _dolfinx as dx
from fenicsx_mortar.linesearch import FullStepOrSecant
from fenicsx_mortar.petsc_options import line_search_options as _line_search_options


def arctan_system(x):
    """Full Newton diverges on arctan from |x| > 1.39; the weak cubic (scaled so that it does
    not dominate the norm l2 minimizes) converges from anywhere."""
    return np.array([np.arctan(x[0]), 0.1 * (x[1] ** 3 + 0.5 * x[1] - 3.0) + 0.01 * x[0]])


def arctan_jacobian(x):
    return np.array([[1.0 / (1.0 + x[0] ** 2), 0.0], [0.01, 0.1 * (3.0 * x[1] ** 2 + 0.5)]])


def log_system(x, domain_everywhere: bool = True):
    """(log x₀ − log 3, x₁ − 1): from x₀ = 10 the full Newton step lands at x₀ < 0, where
    F is NaN. With ``domain_everywhere`` False, F is NaN off the starting point."""
    with np.errstate(invalid="ignore"):
        v = np.array([np.log(x[0]) - np.log(3.0), x[1] - 1.0])
    if not domain_everywhere and x[0] != 10.0:
        v[:] = np.nan
    return v


def log_jacobian(x):
    return np.array([[1.0 / x[0], 0.0], [0.0, 1.0]])


def newton(x0, line_search: str, accept: float | None = None, system=arctan_system,
           jacobian=arctan_jacobian, atol: float = 1e-13):
    """Reason, iterates with their residual norms, the number of F evaluations and, per
    ``l2-full`` iteration, whether the step was scaled — of SNES newtonls."""
    snes = PETSc.SNES().create(PETSc.COMM_SELF)
    x, f = PETSc.Vec().createSeq(2), PETSc.Vec().createSeq(2)
    J = PETSc.Mat().createDense([2, 2], comm=PETSc.COMM_SELF)
    J.setUp()
    calls = []

    def evaluate(xv, fv):
        calls.append(xv.getArray(readonly=True).copy())
        fv.setArray(system(xv.getArray(readonly=True)))

    reasons = PETSc.SNES.ConvergedReason
    ls = FullStepOrSecant(evaluate, snes.getFunctionNorm,
                          fail=lambda: snes.setConvergedReason(reasons.DIVERGED_LINE_SEARCH),
                          **({} if accept is None else {"accept": accept}))

    def residual(s, xv, fv):
        if not ls.take(xv, fv):
            evaluate(xv, fv)

    def assemble_jacobian(s, xv, A, P):
        A.setValues([0, 1], [0, 1], jacobian(xv.getArray(readonly=True)).ravel())
        A.assemble()

    iterates, scaled = [], []

    def precheck(xv, yv):
        scaled.append(ls.precheck(xv, yv))
        return scaled[-1]

    snes.setFunction(residual, f)
    snes.setJacobian(assemble_jacobian, J)
    snes.setMonitor(lambda s, it, norm: iterates.append(
        (s.getSolution().getArray(readonly=True).copy(), norm)))
    opts = PETSc.Options()
    prefix = f"ls{id(snes)}_"
    snes.setOptionsPrefix(prefix)
    keys = {"snes_type": "newtonls", "ksp_type": "preonly", "pc_type": "lu",
            **_line_search_options(line_search),    # l2: PETSc >= 3.24's secant
            "snes_atol": atol, "snes_rtol": 1e-14, "snes_max_it": 40}
    for k, v in keys.items():
        opts[prefix + k] = v
    snes.setFromOptions()
    for k in keys:
        opts.delValue(prefix + k)
    if line_search == "l2-full":
        snes.setLineSearchPreCheck(precheck)
    x.setArray(x0)
    snes.solve(None, x)
    reason = snes.getConvergedReason()
    return reason, iterates, len(calls), scaled


def test_full_newton_diverges_here():
    """The set-up needs a line search: full Newton steps from x₀ = 2 do not converge."""
    reason, *_ = newton([2.0, 3.0], "basic")
    assert reason <= 0


def test_without_full_steps_it_is_petsc_l2():
    """With the full step never accepted the iterates are PETSc l2's, to the last bit (the
    same three points and the same secant formula; PETSc >= 3.24: its secant search, until
    round-off)."""
    r1, ours, _, scaled = newton([2.0, 3.0], "l2-full", accept=0.0)
    r2, petsc, *_ = newton([2.0, 3.0], "l2")
    assert all(scaled)
    assert r1 > 0 and r2 > 0
    assert len(ours) == len(petsc)
    # PETSc >= 3.24's secant (l2 renamed) arranges the same formula otherwise: the last bit
    # differs once the residual is at round-off level (the step from 7e-6 to 1e-11 here)
    exact = dx.LINE_SEARCH_SECANT == "l2"
    for (xa, na), (xb, nb) in zip(ours, petsc):
        if exact or min(na, nb) > 1e-5:
            assert np.array_equal(xa, xb) and na == nb
        else:
            assert np.abs(xa - xb).max() < 1e-9 and abs(na - nb) < 1e-9


@pytest.mark.parametrize("x0", [[1.5, 2.0], [2.0, 3.0], [-1.8, 0.2]])
def test_one_evaluation_per_accepted_full_step(x0):
    """It converges where full Newton does not; an iteration whose full step halves the
    residual norm costs one F evaluation (three otherwise), and in the quadratic tail every
    step is the full step, so the tail is Newton's: r_{k+1}/r_k² bounded."""
    reason, its, n_calls, scaled = newton(x0, "l2-full")
    assert reason > 0
    full = scaled.count(False)
    assert 0 < full < len(scaled)      # both kinds of step occur here
    # one evaluation at x₀, one per full step, three per secant step
    assert n_calls == 1 + full + 3 * (len(scaled) - full)
    _, _, petsc_calls, _ = newton(x0, "l2")
    assert n_calls < petsc_calls
    norms = np.array([n for _, n in its])
    assert not any(scaled[-3:])
    tail = norms[norms > 1e-12][-3:]
    assert (tail[1:] / tail[:-1] ** 2).max() < 10.0


def _solve_log(line_search: str, domain_everywhere: bool = True):
    """Reason and x₀ iterates from x = (10, 1) on :func:`log_system`."""
    reason, its, _, _ = newton([10.0, 1.0], line_search, atol=1e-12, jacobian=log_jacobian,
                               system=lambda x: log_system(x, domain_everywhere))
    return reason, [xk[0] for xk, _ in its]


def test_after_a_nan_the_step_stays_short_of_it():
    """The full step gives NaN: as l2, halve, and never take a secant step beyond 0.95 of
    the step that gave NaN (without that cap the secant step went to λ = 2.05, back into
    the NaN, and Newton stopped with DIVERGED_FNORM_NAN); the first step is l2's."""
    r_ours, ours = _solve_log("l2-full")
    r_petsc, petsc = _solve_log("l2")
    assert r_ours > 0 and r_petsc > 0
    assert ours[1] == petsc[1] and abs(ours[-1] - 3.0) < 1e-12


def test_no_finite_step_is_a_line_search_failure():
    """F is NaN at every step length down to 1e-12: SNES stops with DIVERGED_LINE_SEARCH,
    as with l2 (not a success with a step of 1e-12)."""
    reasons = PETSc.SNES.ConvergedReason
    assert _solve_log("l2-full", domain_everywhere=False)[0] == reasons.DIVERGED_LINE_SEARCH
    assert _solve_log("l2", domain_everywhere=False)[0] == reasons.DIVERGED_LINE_SEARCH
