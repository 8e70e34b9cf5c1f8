"""Master curves (fenicsx_mortar.contact.curves): interpolation and continuity of the
smoothed curves, averaged normals on inscribed polygons, the factory, and the B-spline's
point map with its frozen parametrization."""
import numpy as np
import pytest

from _chains import chain
from fenicsx_mortar.contact.curves import (AveragedNormals, BSpline, Hermite, Polyline,
                                           make_curve)
from fenicsx_mortar.contact.registry import SMOOTHINGS


def wavy_open(n=14, seed=3):
    """Open chain with convex and concave parts, irregular spacing."""
    rng = np.random.default_rng(seed)
    t = np.sort(np.concatenate([[0.0, 3.0], rng.uniform(0.0, 3.0, n - 2)]))
    return chain(np.c_[t, 0.4 * np.sin(2.1 * t)])


def irregular_circle(n=11, R=1.3, seed=4):
    """Closed chain on a circle, clockwise (outward normal), irregular angles."""
    rng = np.random.default_rng(seed)
    phi = np.sort(rng.uniform(0.0, 2 * np.pi, n))[::-1]
    return chain(R * np.c_[np.cos(phi), np.sin(phi)], closed=True), phi


def _values(curve, seg, xi, order):
    seg = np.asarray(seg)
    P = curve.split_points(curve.local_points(seg))
    out = curve.derivatives(seg, np.broadcast_to(xi, seg.shape).astype(float), P, order)
    return [np.stack(np.broadcast_arrays(*v), axis=-1) for v in out]


# ---------------------------------------------------------------- B-spline
@pytest.mark.parametrize("config", ["open", "closed"])
def test_bspline_interpolates_every_node(config):
    x, seg = wavy_open() if config == "open" else irregular_circle()[0]
    curve = BSpline(x, seg)
    s = np.arange(len(seg))
    x0, = _values(curve, s, 0.0, 0)
    x1, = _values(curve, s, 1.0, 0)
    assert np.abs(x0 - x[seg[:, 0]]).max() <= 1e-12
    assert np.abs(x1 - x[seg[:, 1]]).max() <= 1e-12
    # the control points are not the nodes (a real interpolation, not a polygon; an open
    # chain has two more: the end derivative conditions)
    P = curve.points()
    assert P.shape[0] == len(x) + (2 if config == "open" else 0)
    assert np.abs(P[:len(x)] - x).max() > 1e-2


@pytest.mark.parametrize("config", ["open", "closed"])
def test_bspline_is_c2_across_nodes(config):
    x, seg = wavy_open() if config == "open" else irregular_circle()[0]
    curve = BSpline(x, seg)
    par = curve.parametrization.chains[0]
    du = np.diff(par["ubar"])
    scale = [np.abs(_values(curve, np.arange(len(seg)), 0.5, 2)[k]).max() for k in range(3)]
    jumps, checked = np.zeros(3), 0
    # every knot is a node (knots at the parameters): d/dt = d/dξ / Δū across the nodes
    for s in range(len(seg)):
        nxt = curve.next_seg[s]
        if nxt < 0:
            continue
        checked += 1
        left = _values(curve, [s], 1.0, 2)
        right = _values(curve, [nxt], 0.0, 2)
        for k in range(3):
            jump = left[k][0] / du[s] ** k - right[k][0] / du[nxt] ** k
            jumps[k] = max(jumps[k], np.abs(jump).max() * du[s] ** k / scale[k])
    assert checked >= len(seg) - 1
    assert np.all(jumps <= 1e-9), jumps
    # the third derivative does jump at knots (the test can see a discontinuity)
    x3 = []
    for s, nxt in ((1, 2), (3, 4)):
        c3 = [curve._W[i, :, 3] @ curve.local_points(np.array([i]))[0] * 6 / du[i] ** 3
              for i in (s, nxt)]
        x3.append(np.abs(c3[0] - c3[1]).max())
    assert max(x3) > 1e-3


def test_bspline_point_map_contract():
    x, seg = wavy_open()
    curve = BSpline(x, seg)
    pm = curve.point_map
    assert pm.shape == (len(x) + 2, len(x))     # open: + the two end derivative conditions
    # P = point_map @ X solves the interpolation system of the (frozen) parametrization
    chain = curve.parametrization.chains[0]       # one open chain: point k = control k
    assert np.abs(chain["A"] @ (pm @ x) - x[chain["nodes"]]).max() < 1e-13
    # stencils index points; local_points uses the map
    st = curve.stencil(np.arange(len(seg)))
    assert st.shape == (len(seg), 4) and st.max() < pm.shape[0]
    assert np.allclose(curve.local_points(np.arange(len(seg))), (pm @ x)[st], atol=0)
    # frozen parametrization: the curve at a fixed (segment, ξ) is linear in the nodes
    rng = np.random.default_rng(0)
    dx = rng.normal(size=x.shape)
    c1, c2 = curve.with_nodes(x + dx), curve.with_nodes(x + 2 * dx)
    s = np.arange(len(seg))
    p0, = _values(curve, s, 0.3, 0)
    p1, = _values(c1, s, 0.3, 0)
    p2, = _values(c2, s, 0.3, 0)
    assert np.abs(p2 - 2 * p1 + p0).max() < 1e-13
    # and still passes through the moved nodes
    assert np.abs(_values(c1, s, 0.0, 0)[0] - (x + dx)[seg[:, 0]]).max() < 1e-12
    # local curves: points are nodes
    for name in SMOOTHINGS.names()[:-1]:
        assert make_curve(name, x, seg).point_map is None


# ---------------------------------------------------------------- Hermite
@pytest.mark.parametrize("config", ["open", "closed"])
def test_hermite_is_c1_at_nodes(config):
    x, seg = wavy_open() if config == "open" else irregular_circle()[0]
    curve = Hermite(x, seg)
    s = np.flatnonzero(curve.next_seg >= 0)
    nxt = curve.next_seg[s]
    l = np.linalg.norm(x[seg[:, 1]] - x[seg[:, 0]], axis=1)
    xl, al = _values(curve, s, 1.0, 1)
    xr, ar = _values(curve, nxt, 0.0, 1)
    assert np.abs(xl - x[seg[s, 1]]).max() < 1e-14 and np.abs(xr - xl).max() < 1e-14
    # dx/ds with s = l ξ (chord length): the same unit vector ā on both sides
    tl, tr = al / l[s, None], ar / l[nxt, None]
    assert np.abs(tl - tr).max() < 1e-14
    assert np.allclose(np.linalg.norm(tl, axis=1), 1.0, atol=1e-14)
    # a real curve: the second derivative jumps (C1, not C2) and the curve leaves the chord
    _, _, bl = _values(curve, s, 1.0, 2)
    _, _, br = _values(curve, nxt, 0.0, 2)
    assert np.abs(bl / l[s, None] ** 2 - br / l[nxt, None] ** 2).max() > 1e-3
    mid, = _values(curve, np.arange(len(seg)), 0.5, 0)
    assert np.abs(mid - 0.5 * (x[seg[:, 0]] + x[seg[:, 1]])).max() > 1e-3


def test_hermite_node_tangent_is_curve_tangent():
    x, seg = wavy_open()
    curve = Hermite(x, seg)
    s = np.arange(len(seg))
    P = curve.split_points(curve.local_points(s))
    tc, td = curve.node_tangents(s, P)
    _, a0 = _values(curve, s, 0.0, 1)
    _, a1 = _values(curve, s, 1.0, 1)
    for t, a in ((tc, a0), (td, a1)):
        t = np.stack(t, axis=1)
        assert np.abs(t[:, 0] * a[:, 1] - t[:, 1] * a[:, 0]).max() < 1e-14
        assert np.all(np.einsum("ij,ij->i", t, a) > 0)


# ---------------------------------------------------------------- averaged normals
def _node_normals(curve, x, seg):
    s = np.arange(len(seg))
    P = curve.split_points(curve.local_points(s))
    nc, _ = curve.node_normals(s, P)
    return np.stack(nc, axis=1)                      # normal at each segment's start node


@pytest.mark.parametrize("variant", ["simple", "weighted", "tangent"])
def test_averaged_normals_exact_on_regular_polygon(variant):
    n, R = 9, 2.0
    phi = np.linspace(0.0, 2 * np.pi, n, endpoint=False)[::-1] + 0.3
    x, seg = chain(R * np.c_[np.cos(phi), np.sin(phi)], closed=True)
    curve = AveragedNormals(x, seg, variant)
    exact = x[seg[:, 0]] / R
    assert np.abs(_node_normals(curve, x, seg) - exact).max() < 1e-15
    # the node normal is also the gap direction: a point on the normal line projects onto
    # the node with gap = distance, from both adjacent segments
    s = np.arange(len(seg))
    prev = curve.prev_seg
    for segs, xi_node in ((s, 0.0), (prev, 1.0)):
        P = curve.split_points(curve.local_points(segs))
        xs = x[seg[:, 0]] + 0.05 * exact
        g, xi = curve.gap(segs, (xs[:, 0], xs[:, 1]), P)
        assert np.allclose(xi, xi_node, atol=1e-14) and np.allclose(g, 0.05, atol=1e-14)


def test_averaged_normals_on_irregular_inscribed_polygon():
    (x, seg), phi = irregular_circle()
    # clockwise: the arc before node i is Δ_p = φ_{i−1} − φ_i, after it Δ_d = φ_i − φ_{i+1}
    dp = np.roll(phi, 1) - phi
    dp[0] += 2 * np.pi
    dd = phi - np.roll(phi, -1)
    dd[-1] += 2 * np.pi
    exact_angle = phi
    err = {}
    for variant in ("simple", "weighted", "tangent"):
        n = _node_normals(AveragedNormals(x, seg, variant), x, seg)
        ang = np.arctan2(n[:, 1], n[:, 0])
        err[variant] = np.angle(np.exp(1j * (ang - exact_angle)))
    # closed forms (see AveragedNormals): simple = tangent, error (Δ_d − Δ_p)/4 · sign,
    # weighted twice that
    assert np.allclose(err["simple"], err["tangent"], atol=1e-15)
    assert np.allclose(np.abs(err["simple"]), np.abs(dd - dp) / 4, atol=1e-14)
    assert np.allclose(np.abs(err["weighted"]), np.abs(dd - dp) / 2, atol=1e-14)
    assert np.abs(err["weighted"]).max() > 1e-2      # irregular: not the circle's normal


def test_averaged_normal_field_is_interpolated():
    x, seg = wavy_open()
    curve = AveragedNormals(x, seg, "weighted")
    s = np.arange(len(seg))
    P = curve.split_points(curve.local_points(s))
    nc, nd = curve.node_normals(s, P)
    nm = np.stack(curve.normal_at(s, np.full(len(s), 0.25), P), axis=1)
    ref = 0.75 * np.stack(nc, 1) + 0.25 * np.stack(nd, 1)
    assert np.allclose(nm, ref / np.linalg.norm(ref, axis=1)[:, None], atol=1e-15)
    # at an open end the averaged normal is the end segment's own normal
    e = x[1] - x[0]
    assert np.allclose(np.stack(nc, 1)[0], [-e[1], e[0]] / np.linalg.norm(e), atol=1e-15)


# ---------------------------------------------------------------- factory
def test_factory_names_and_unknown():
    x, seg = wavy_open()
    kinds = {"none": Polyline, "averaged-simple": AveragedNormals,
             "averaged-weighted": AveragedNormals, "averaged-tangent": AveragedNormals,
             "hermite": Hermite, "bspline": BSpline}
    assert set(kinds) == set(SMOOTHINGS.names())
    for name, cls in kinds.items():
        c = make_curve(name, x, seg)
        assert isinstance(c, cls) and c.name == name
        assert type(c.with_nodes(x + 0.1)) is type(c)
        if name.startswith("averaged-"):
            assert c.variant == c.with_nodes(x).variant == name.removeprefix("averaged-")
    for bad in ("spline", "averaged-foo", "Hermite"):
        with pytest.raises(ValueError, match=repr(bad)):
            make_curve(bad, x, seg)
