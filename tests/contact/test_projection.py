"""Projection onto master curves (fenicsx_mortar.contact.projection): agreement with brute
force for 10⁴ points (near nodes, both sides, beyond the ends), exact derivatives of the
projected ξ (Taylor tests), and reported failures."""
import numpy as np
import pytest

from _chains import rates
from benchmarks.gap_accuracy import closest_point
from fenicsx_mortar.contact import projection
from fenicsx_mortar.contact.ad import Jet2
from fenicsx_mortar.contact.curves import make_curve
from fenicsx_mortar.contact.registry import SMOOTHINGS

from test_curves import irregular_circle, wavy_open

CLOSEST = ["none", "hermite", "bspline"]
GOLD = (np.sqrt(5.0) - 1.0) / 2.0


def _eval(curve, seg, xi):
    seg, xi = np.broadcast_arrays(np.asarray(seg), np.asarray(xi, dtype=float))
    P = curve.split_points(curve.local_points(seg.ravel()))
    x = curve.derivatives(seg.ravel(), xi.ravel(), P, 0)[0]
    return np.stack(x, axis=-1).reshape(seg.shape + (2,))


def _points(curve, x, seg, n, rng):
    """n points: offsets of both signs along the chord normal from random curve points,
    a quarter of them within 1 % of a segment's length from a node, and (open chains)
    points beyond both ends."""
    h = np.linalg.norm(x[seg[:, 1]] - x[seg[:, 0]], axis=1).mean()
    s = rng.integers(0, len(seg), n)
    xi = rng.uniform(0.0, 1.0, n)
    xi[: n // 4] = rng.choice([0.0, 1.0], n // 4) + rng.uniform(-0.01, 0.01, n // 4)
    xi = np.clip(xi, 0.0, 1.0)
    base = _eval(curve, s, xi)
    e = x[seg[s, 1]] - x[seg[s, 0]]
    nrm = np.stack([-e[:, 1], e[:, 0]], 1) / np.linalg.norm(e, axis=1)[:, None]
    pts = base + rng.uniform(-0.3, 0.3, (n, 1)) * h * nrm
    if curve.prev_seg.min() < 0:                        # open chain: beyond the ends
        k = n // 10
        for end, inward in ((x[seg[0, 0]], x[seg[0, 1]]), (x[seg[-1, 1]], x[seg[-1, 0]])):
            d = (end - inward) / np.linalg.norm(end - inward)
            pts[-k:] = end + rng.uniform(0.0, 0.5, (k, 1)) * h * d \
                + rng.uniform(-0.3, 0.3, (k, 1)) * h * np.array([-d[1], d[0]])
            k *= 2
    return pts


def brute_force_distance(curve, seg_count, pts, n_samples=64):
    """Distance from each point to the curve: dense sampling of every segment, then
    golden-section refinement around each segment's best sample (independent of Newton)."""
    xi = np.linspace(0.0, 1.0, n_samples)
    S = np.repeat(np.arange(seg_count), n_samples)
    X = _eval(curve, S, np.tile(xi, seg_count)).reshape(seg_count, n_samples, 2)
    d2 = ((pts[:, None, None, :] - X[None]) ** 2).sum(-1)          # (n, seg, samples)
    k = np.argmin(d2, axis=2)
    seg = np.broadcast_to(np.arange(seg_count), k.shape)
    a = xi[np.maximum(k - 1, 0)]
    b = xi[np.minimum(k + 1, n_samples - 1)]
    P = np.broadcast_to(pts[:, None, :], seg.shape + (2,))

    def f(t):
        return ((P - _eval(curve, seg, t)) ** 2).sum(-1)
    c, d = b - GOLD * (b - a), a + GOLD * (b - a)
    fc, fd = f(c), f(d)
    for _ in range(64):
        left = fc < fd
        b = np.where(left, d, b)
        a = np.where(left, a, c)
        c, d = np.where(left, b - GOLD * (b - a), d), np.where(left, c, a + GOLD * (b - a))
        new = f(np.where(left, c, d))
        fc, fd = np.where(left, new, fd), np.where(left, fc, new)
    ends = np.minimum(f(a), f(b))
    return np.sqrt(np.minimum(np.minimum(fc, fd), ends).min(axis=1))


@pytest.mark.parametrize("smoothing", CLOSEST)
@pytest.mark.parametrize("config", ["open", "closed"])
def test_closest_point_matches_brute_force(smoothing, config):
    x, seg = wavy_open() if config == "open" else irregular_circle()[0]
    curve = make_curve(smoothing, x, seg)
    rng = np.random.default_rng(7)
    pts = _points(curve, x, seg, 10_000, rng)
    cp = closest_point(curve, pts)
    assert cp.ok.all()
    assert np.all((cp.xi >= 0.0) & (cp.xi <= 1.0))
    assert np.allclose(cp.x, _eval(curve, cp.seg, cp.xi), atol=1e-15)
    ref = brute_force_distance(curve, len(seg), pts)
    err = np.abs(cp.distance - ref)
    assert err.max() <= 1e-10, (err.max(), pts[np.argmax(err)])
    # interior results satisfy the closest-point condition; ends clamp to the end node
    inner = (cp.xi > 1e-9) & (cp.xi < 1 - 1e-9)
    P = curve.split_points(curve.local_points(cp.seg[inner]))
    F = curve.condition(cp.seg[inner], cp.xi[inner], (pts[inner, 0], pts[inner, 1]), P)
    assert np.abs(F).max() < 1e-12
    if config == "open":
        beyond = (cp.seg == 0) & (cp.xi == 0.0) | (cp.seg == len(seg) - 1) & (cp.xi == 1.0)
        assert beyond.sum() > 500


@pytest.mark.parametrize("variant", ["averaged-simple", "averaged-weighted"])
def test_projection_along_averaged_normal(variant):
    # projection along the smoothed normal: (x_s − x(ξ̄)) ∥ n̂(ξ̄), checked against an
    # independent bisection of the cross condition on every segment
    x, seg = irregular_circle()[0]
    curve = make_curve(variant, x, seg)
    rng = np.random.default_rng(2)
    pts = _points(curve, x, seg, 2000, rng)
    cp = closest_point(curve, pts)
    assert cp.ok.all()
    P = curve.split_points(curve.local_points(cp.seg))
    n = np.stack(curve.normal_at(cp.seg, cp.xi, P), 1)
    r = pts - cp.x
    assert np.abs(r[:, 0] * n[:, 1] - r[:, 1] * n[:, 0]).max() < 1e-12
    # brute force: roots in [0, 1] of F on all segments by sampling + bisection; the
    # nearest one is the answer (these points lie within one shadow)
    S = len(seg)
    grid = np.linspace(0.0, 1.0, 33)
    segs = np.arange(S)[None, :, None]
    Pall = curve.split_points(curve.local_points(np.arange(S)))
    Pb = [(p[0][None, :, None], p[1][None, :, None]) for p in Pall]
    xs = (pts[:, 0][:, None, None], pts[:, 1][:, None, None])
    F = curve.condition(segs, grid[None, None, :], xs, Pb)
    best = np.full(len(pts), np.inf)
    for k in range(len(grid) - 1):
        br = (F[..., k] > 0) & (F[..., k + 1] <= 0)
        a = np.full(br.shape, grid[k])
        b = np.full(br.shape, grid[k + 1])
        for _ in range(60):
            m = 0.5 * (a + b)
            Fm = curve.condition(segs[..., 0], m, (xs[0][..., 0], xs[1][..., 0]),
                                 [(p[0][..., 0], p[1][..., 0]) for p in Pb])
            a, b = np.where(Fm > 0, m, a), np.where(Fm > 0, b, m)
        xm = np.stack(curve.derivatives(segs[..., 0], a, [(p[0][..., 0], p[1][..., 0])
                                                         for p in Pb], 0)[0], -1)
        d = np.linalg.norm(pts[:, None, :] - xm, axis=-1)
        best = np.minimum(best, np.where(br, d, np.inf).min(axis=1))
    assert np.abs(best - cp.distance).max() < 1e-10


@pytest.mark.parametrize("smoothing", SMOOTHINGS.names())
def test_projected_xi_has_exact_derivatives(smoothing):
    # ξ̄(x_s, P) from the float Newton + two chord steps in jet arithmetic: Taylor test
    # of value and gradient over all local coordinates (second-order remainders)
    x, seg = wavy_open()
    curve = make_curve(smoothing, x, seg)
    rng = np.random.default_rng(3)
    s = np.arange(1, len(seg) - 1)
    xi0 = rng.uniform(0.1, 0.9, len(s))
    base = _eval(curve, s, xi0)
    xs = base + rng.uniform(-0.1, 0.1, (len(s), 1)) * np.array([[0.3, 1.0]])
    Z0 = np.concatenate([xs, curve.local_points(s).reshape(len(s), -1)], axis=1)
    dZ = rng.uniform(-1.0, 1.0, Z0.shape) * 0.1

    def xi_jet(Z):
        v = Jet2.variables(Z)
        P = [(v[2 + 2 * i], v[3 + 2 * i]) for i in range(curve.stencil_size)]
        return curve.project(s, (v[0], v[1]), P)
    J0 = xi_jet(Z0)
    assert np.all((J0.val > 0.0) & (J0.val < 1.0))
    hs = 10.0 ** -np.arange(2.0, 4.6, 0.5)
    r0, r1 = [], []
    for h in hs:
        J = xi_jet(Z0 + h * dZ)
        r0.append(np.abs(J.val - J0.val - h * np.einsum("ki,ki->k", J0.grad, dZ)).max())
        r1.append(np.abs(J.grad - J0.grad - h * np.einsum("kij,kj->ki", J0.hess, dZ)).max())
    r0, r1 = np.array(r0), np.array(r1)
    if smoothing == "none":
        assert np.all(r0 > 0)                        # closed form, same test
    assert np.all((rates(hs, r0) > 1.8) & (rates(hs, r0) < 2.2)), r0
    assert np.all((rates(hs, r1) > 1.8) & (rates(hs, r1) < 2.2)), r1


def test_failures_are_reported():
    x, seg = wavy_open()
    curve = make_curve("hermite", x, seg)
    s = np.array([2, 3, 4])
    P = curve.split_points(curve.local_points(s))
    mid = 0.5 * (x[3] + x[4]) + [0.0, 0.05]                 # above segment 3 = s[1]
    xs = (np.array([np.nan, mid[0], 1.2]), np.array([0.3, mid[1], np.nan]))
    _, _, status = projection.solve_on_segments(curve, s, xs, P)
    assert status.tolist() == [projection.FAILED, projection.FOUND, projection.FAILED]
    with pytest.raises(projection.ProjectionError, match="failed for 2 of 3"):
        curve.project(s, xs, P)
    cp = closest_point(curve, np.array([[1.0, 0.3], [np.nan, 0.0]]))
    assert cp.ok.tolist() == [True, False]
    # a root beyond the window is "not on this segment", not a failure
    far = (np.array([x[-1, 0] + 5.0]), np.array([x[-1, 1]]))
    xi, _, st = projection.solve_on_segments(curve, np.array([2]), far, [
        (p[0][:1], p[1][:1]) for p in P])
    assert st[0] == projection.ABOVE and xi[0] == projection.WINDOW[1]


@pytest.mark.parametrize("smoothing", SMOOTHINGS.names())
@pytest.mark.parametrize("shape", [lambda: irregular_circle()[0], wavy_open],
                         ids=["closed", "open"])
def test_condition_polynomial_is_the_condition(smoothing, shape):
    # the power form the Newton iterations use equals F and F′ of the curve itself, on
    # every piece (B-spline break points) and beyond [0, 1]
    x, seg = shape()
    curve = make_curve(smoothing, x, seg)
    rng = np.random.default_rng(5)
    segs = rng.integers(0, len(seg), 500)
    xi = rng.uniform(-1.0, 2.0, 500)
    xs = tuple(x[seg[segs, 0]].T + rng.uniform(-0.2, 0.2, (2, 500)))
    P = curve.split_points(curve.local_points(segs))
    F, dF = curve.condition(segs, xi, xs, P, derivative=True)
    G, dG = projection._polynomial(*curve.condition_polynomial(segs, xs, P), xi)
    scale = np.abs(F).max()
    assert np.abs(G - F).max() < 1e-13 * scale
    assert np.abs(dG - dF).max() < 1e-13 * np.abs(dF).max()


@pytest.mark.parametrize("smoothing, n, ratio", [("hermite", 8, 10.0), ("hermite", 16, 10.0),
                                                 ("hermite", 32, 10.0), ("bspline", 16, 1.5),
                                                 ("bspline", 32, 1.5)])
def test_smoothed_curves_keep_their_order_up_to_an_open_chain_end(smoothing, n, ratio):
    """On an open quarter-circle arc the Hermite and B-spline curves' end segments are as
    accurate as their interior (Hermite: the end tangent from the circle through the last
    three nodes; B-spline: end derivatives from the quartic through the last five nodes —
    with the earlier not-a-knot ends its end error was 2.7x the interior's): the gap error
    of points projecting onto the end segments within ``ratio`` x the interior's, and both
    fall as h^4 (the polyline's end error is its interior's, O(h^2))."""
    from benchmarks.gap_accuracy import open_arc_errors
    rng = np.random.default_rng(4)
    end, interior = open_arc_errors(smoothing, n, rng)
    assert end <= ratio * interior
    end2, interior2 = open_arc_errors(smoothing, 2 * n, np.random.default_rng(4))
    assert np.log2(end / end2) > 3.5 and np.log2(interior / interior2) > 3.5


def test_bspline_end_segments_are_fourth_order_on_a_non_circular_curve():
    """The B-spline's end derivative comes from a polynomial in the chord-length parameter,
    not from a circle: on y = 0.3 sin(2x) (curvature varying along the chain, irregular
    spacing) the largest deviation on the end segments falls as h^4 too, and stays within
    2x the interior's."""
    def errors(n):
        rng = np.random.default_rng(5)
        t = np.linspace(0.0, 1.5, n + 1)
        t[1:-1] += rng.uniform(-0.2, 0.2, n - 1) * 1.5 / n
        x = np.c_[t, 0.3 * np.sin(2.0 * t)]
        seg = np.c_[np.arange(n), np.arange(1, n + 1)]
        curve = make_curve("bspline", x, seg)
        xi = np.linspace(0.0, 1.0, 41)
        e = np.array([np.abs(p[:, 1] - 0.3 * np.sin(2.0 * p[:, 0])).max()
                      for p in (_eval(curve, np.full(41, s), xi) for s in range(n))])
        return max(e[0], e[-1]), e[1:-1].max()
    (end1, in1), (end2, in2) = errors(16), errors(32)
    assert end1 <= 2.0 * in1 and end2 <= 2.0 * in2
    assert np.log2(end1 / end2) > 3.5
