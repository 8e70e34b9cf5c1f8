"""Projection of many points onto a master curve: vectorized safeguarded Newton
(docs/design.md §3, §6).

Every :class:`~.curves.MasterCurve` states its projection condition on a segment as a
scalar function F(ξ) (:meth:`~.curves.MasterCurve.condition`) that *decreases* through the
wanted root:

* closest point (polyline, Hermite, B-spline; docs/design.md §3 and §6.5):
      F(ξ) = (x_s − x(ξ))·x′(ξ),     F′ = −|x′|² + (x_s − x)·x″      (−F = dD/dξ, D = ½|x_s − x|²)
  (the Hermite and B-spline conditions are quintic in ξ);
* projection along the smoothed normal (averaged normals, §3):
      F(ξ) = (x_s − x(ξ)) × m(ξ),    m = (1−ξ) n̄_c + ξ n̄_d   (quadratic in ξ).

:func:`solve_on_segments` finds, per batch entry, the root on the segment's own curve piece
(extended beyond ξ ∈ [0, 1] as a polynomial) inside the window ``WINDOW``, evaluating F from
its power coefficients (:meth:`~.curves.MasterCurve.condition_polynomial`, values only: a
few array operations per iteration instead of the curve's jet-capable evaluation):

1. bracketing: F at ``N_SAMPLES`` equidistant ξ of the window; among the sign changes
   F > 0 → F ≤ 0 the one nearest to x_s is taken, of those reaching into ξ ∈ [0, 1] if
   there are any;
2. safeguarded Newton (Numerical Recipes' rtsafe): a Newton step that leaves the bracket or
   does not halve the step is replaced by bisection; the bracket shrinks every iteration,
   so at most ``MAX_ITER`` iterations are made (bisection alone reaches 1e-16 in 60);
3. no sign change: the root lies outside the window; ξ is returned at the window end
   (status BELOW / ABOVE) — "not on this segment", never a wrong root;
4. failure (no convergence, non-finite input): status FAILED, reported by the callers.

:func:`project` adds the exact derivatives when the inputs are :class:`~.ad.Jet2`: with the
converged float root ξ₀ and D = F′(ξ₀) it makes two chord steps in jet arithmetic,
    ξ₁ = ξ₀ − F(ξ₀)/D,   ξ₂ = ξ₁ − F(ξ₁)/D.
The error of ξ₀ in the local variables δ is O(δ); a chord step with the exact D at the base
point maps an O(δᵏ) error to O(δᵏ⁺¹), so ξ₂ is exact to second order: its gradient is the
implicit-function derivative −F_x/F_ξ and its Hessian
−(F_xx + F_xξ ξ_xᵀ + ξ_x F_ξx + F_ξξ ξ_x ξ_xᵀ)/F_ξ (tests/contact/test_projection.py).

:func:`closest_segments` picks, per slave node, its master segment among candidates (NTS,
friction).
"""
from __future__ import annotations

import numpy as np

from . import ad
from .ad import Jet2

WINDOW = (-1.0, 2.0)
N_SAMPLES = 13
MAX_ITER = 60
STEP_TOL = 1e-11      # a Newton step this small leaves an error ~ (F″/2F′)·STEP_TOL² ≈ 1e-22
FOUND, BELOW, ABOVE, FAILED = 0, 1, 2, -1


class ProjectionError(RuntimeError):
    """The safeguarded Newton did not converge for some points."""


def _values(v):
    return (ad.value(v[0]), ad.value(v[1]))


def _is_jet(*items) -> bool:
    return any(isinstance(c, Jet2) for v in items for c in v)


def _polynomial(breaks: np.ndarray, Fc: np.ndarray, xi):
    """F(ξ) and F′(ξ) from per-piece power coefficients (:meth:`~.curves.MasterCurve.
    condition_polynomial`): Horner on every piece, then the piece that holds at ξ."""
    out = []
    for c in Fc:
        F, dF = c[-1], 0.0
        for r in range(c.shape[0] - 2, -1, -1):
            dF = dF * xi + F
            F = F * xi + c[r]
        out.append((F, dF))
    if len(out) == 1:
        return out[0]
    piece = sum((xi >= b).astype(np.int64) for b in breaks)
    return (np.choose(piece, [F for F, _ in out]), np.choose(piece, [dF for _, dF in out]))


def solve_on_segments(curve, seg_index, xs, P, window=WINDOW, n_samples: int = N_SAMPLES,
                      max_iter: int = MAX_ITER):
    """Float root ξ of the curve's projection condition on each entry's segment.

    ``seg_index``, ``xs`` (2-tuple) and the local points ``P`` (list of 2-tuples) broadcast
    to a batch shape B (values of jets are used). Returns ``(xi, dF, status)``, each of
    shape B: the root, F′ there, and FOUND / BELOW / ABOVE (root outside the window, ξ at
    the window's end) / FAILED.
    """
    seg = np.asarray(seg_index)
    xs = _values(xs)
    P = [_values(p) for p in P]
    shape = np.broadcast_shapes(seg.shape, *(np.shape(c) for c in xs),
                                *(np.shape(c) for p in P for c in p))
    nd = len(shape)
    lo, hi = window
    grid = np.linspace(lo, hi, n_samples).reshape((-1,) + (1,) * nd)
    breaks, Fc = curve.condition_polynomial(seg, xs, P)
    F = np.broadcast_to(_polynomial(breaks, Fc, grid)[0], (n_samples,) + shape)
    x = curve.derivatives(seg, grid, P, 0)[0]
    d2 = np.broadcast_to((xs[0] - x[0]) ** 2 + (xs[1] - x[1]) ** 2, (n_samples,) + shape)

    # 1. bracket: a decreasing sign change, the one nearest to x_s among those that reach
    # into the segment (ξ ∈ [0, 1]) if any: the extension of a strongly curved piece can
    # come back nearer to x_s than the segment's own root (seen on a B-spline's end
    # segment), but only a root on the segment is a closest point of it
    down = (F[:-1] > 0.0) & (F[1:] <= 0.0)
    score = np.where(down, np.minimum(d2[:-1], d2[1:]), np.inf)
    ga = grid[:-1]
    on_segment = (ga < 1.0) & (ga + (hi - lo) / (n_samples - 1) > 0.0)
    k = np.argmin(np.where(on_segment, score, np.inf), axis=0)
    inside = np.isfinite(np.take_along_axis(score, k[None], 0)[0])
    k = np.where(inside, k, np.argmin(score, axis=0))
    has = np.isfinite(np.take_along_axis(score, k[None], 0)[0])
    a = np.take_along_axis(np.broadcast_to(grid, F.shape)[:-1], k[None], 0)[0].copy()
    b = a + (hi - lo) / (n_samples - 1)
    Fa = np.take_along_axis(F[:-1], k[None], 0)[0]
    Fb = np.take_along_axis(F[1:], k[None], 0)[0]

    # 3. no bracket: the root is beyond the window on the side where the distance decreases
    status = np.full(shape, FOUND, dtype=np.int64)
    all_pos, all_neg = np.all(F > 0.0, axis=0), np.all(F <= 0.0, axis=0)
    near_lo = d2[0] <= d2[-1]
    status[~has] = np.where(all_pos | (~all_neg & ~near_lo), ABOVE, BELOW)[~has]
    finite = np.all(np.isfinite(F), axis=0)
    status[~finite] = FAILED

    # 2. safeguarded Newton, started by regula falsi inside the bracket
    with np.errstate(divide="ignore", invalid="ignore"):
        xi = np.where(Fa - Fb > 0.0, a + Fa * (b - a) / (Fa - Fb), 0.5 * (a + b))
    xi = np.where(has, xi, np.where(status == ABOVE, hi, lo))
    active = has & finite
    last_step = np.full(shape, hi - lo)
    dF = np.full(shape, -1.0)
    for _ in range(max_iter):
        if not active.any():
            break
        Fx, dFx = _polynomial(breaks, Fc, xi)
        Fx, dFx = np.broadcast_to(Fx, shape), np.broadcast_to(dFx, shape)
        dF = np.where(active, dFx, dF)
        right = Fx > 0.0                                  # the root lies right of xi
        a = np.where(active & right, xi, a)
        b = np.where(active & ~right, xi, b)
        with np.errstate(divide="ignore", invalid="ignore"):
            step = -Fx / dFx
        new = xi + step
        newton = (new > a) & (new < b) & (np.abs(step) <= 0.5 * last_step)
        new = np.where(newton, new, 0.5 * (a + b))
        done = (Fx == 0.0) | (newton & (np.abs(step) <= STEP_TOL)) | (b - a <= 1e-15)
        last_step = np.where(active, np.abs(new - xi), last_step)
        xi = np.where(active & (Fx != 0.0), new, xi)
        active &= ~done
    status[active] = FAILED
    return xi, dF, status


def project(curve, seg_index, xs, P):
    """Root ξ̄ of the projection condition on each entry's segment (unclamped), as a jet
    when ``xs`` or ``P`` are jets (exact to second order, see the module docstring).

    Entries whose root lies outside the window get ξ̄ at the window's end (−1 or 2), i.e.
    "not on this segment". Raises :class:`ProjectionError` naming the number of entries
    where the safeguarded Newton failed.
    """
    xi0, dF, status = solve_on_segments(curve, seg_index, xs, P)
    failed = int(np.count_nonzero(status == FAILED))
    if failed:
        raise ProjectionError(f"{type(curve).__name__}: projection failed for {failed} of "
                              f"{status.size} points (no convergence or non-finite input)")
    if not _is_jet(xs, *P):
        return xi0
    D = np.where((status == FOUND) & (dF < 0.0), dF, -1.0)
    inv = 1.0 / D
    xi1 = xi0 - curve.condition(seg_index, xi0, xs, P) * inv
    return xi1 - curve.condition(seg_index, xi1, xs, P) * inv


STICKY_TOL = 1e-8
WEDGE = 0.5


def closest_segments(slave_x, master_x, nodes, segs, curve, previous=None):
    """Per slave node, the qualifying candidate segment with the smallest |g| (values
    only): NTS contact (:mod:`.nts`) and the friction kinematics (:mod:`.friction`).

    Candidates are (``nodes``, ``segs``) rows; a segment qualifies where the node projects
    into ξ ∈ [0, 1]; with none, the segments within ``WEDGE`` of it do (the blind wedge
    outside a convex master corner: the closest master point is the corner node itself,
    whose gap the callers measure along the averaged normal).

    With ``previous`` (segment chosen per slave node before, −1 for none) a node keeps its
    segment while it projects within [−tol, 1 + tol] of it: at a master node the two
    adjacent segments tie, their normals differ, and a choice that flips with round-off
    between Newton iterations makes the residual jump (Newton then cycles)."""
    P = curve.split_points(curve.local_points(segs, master_x))
    xj = (slave_x[nodes, 0], slave_x[nodes, 1])
    g, xi = curve.gap(segs, xj, P)
    g, xi = ad.value(g), ad.value(xi)
    ok = (xi >= 0.0) & (xi <= 1.0)
    kept = np.zeros_like(ok)
    if previous is not None:
        kept = (previous[nodes] == segs) & (xi >= -STICKY_TOL) & (xi <= 1.0 + STICKY_TOL)
    # blind wedge outside a convex master corner: no segment qualifies, the closest master
    # point is the corner node itself (its gap is measured along the averaged normal)
    regular = np.zeros(int(nodes.max(initial=-1)) + 1, dtype=bool)
    regular[nodes[ok | kept]] = True
    wedge = ~regular[nodes] & (xi >= -WEDGE) & (xi <= 1.0 + WEDGE)
    ok |= kept | wedge
    nodes, segs, g, kept = nodes[ok], segs[ok], g[ok], kept[ok]
    order = np.lexsort((np.abs(g), ~kept, nodes))
    nodes, segs = nodes[order], segs[order]
    first = np.ones(nodes.shape[0], dtype=bool)
    first[1:] = nodes[1:] != nodes[:-1]
    return nodes[first], segs[first]
