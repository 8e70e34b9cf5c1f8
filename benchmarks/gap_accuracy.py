"""Gap accuracy of the master-surface smoothings (docs/design.md §6; issue: smoothed master
surfaces). Regenerates docs/smoothing.md and docs/smoothing_gap_error.png.

A circle of radius R is the exact master surface; the discrete master is the closed
polygon of n nodes on it (clockwise, so that n = e3 × t points outward), and, for the
chain ends, an open quarter arc (the end segments' errors reported apart from the
interior's). Slave points lie at a known signed distance ±d from the circle (outside:
gap +d, inside: gap −d) at random angles. Each smoothing computes the gap as the contact
kernels do — the projection onto the curve (closest point, or along the smoothed normal
for the averaged-normal variants), then g = (x_s − x(ξ̄))·n(ξ̄) on that segment — and its
error against the exact gap is reported (maximum over all points), for n = 8, 16, 32, 64.

    .venv/bin/python benchmarks/gap_accuracy.py
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from typing import NamedTuple  # noqa: E402

from scipy.spatial import cKDTree  # noqa: E402

from fenicsx_mortar.contact.curves import make_curve  # noqa: E402
from fenicsx_mortar.contact.projection import FAILED, solve_on_segments  # noqa: E402
from fenicsx_mortar.contact.registry import SMOOTHINGS  # noqa: E402

class ClosestPoint(NamedTuple):
    seg: np.ndarray        # (n,) segment of the projection
    xi: np.ndarray         # (n,) ξ ∈ [0, 1] on it
    x: np.ndarray          # (n, 2) the curve point
    distance: np.ndarray   # (n,) |x_s − x| (for a closest-point curve the distance to it)
    ok: np.ndarray         # (n,) False: Newton failed or the hand-over did not settle


def _nearest_nodes(nodes: np.ndarray, pts: np.ndarray, k: int) -> np.ndarray:
    """(n, k) indices of the k nodes nearest to each point; a non-finite point gets node 0
    (its projection then fails and is reported). SciPy >= 1.15's KD-tree refuses
    non-finite query points ("'x' must be finite"), so only the finite ones are asked."""
    finite = np.isfinite(pts).all(axis=1)
    near = np.zeros((pts.shape[0], k), dtype=np.intp)
    if finite.any():
        _, idx = cKDTree(nodes).query(pts[finite], k=k)
        idx = np.asarray(idx).reshape(int(finite.sum()), k)
        near[finite] = np.where(idx < nodes.shape[0], idx, 0)
    return near


def closest_point(curve, points: np.ndarray, n_starts: int = 2,
                  max_hops: int = 64) -> ClosestPoint:
    """Project ``points (n, 2)`` onto the whole curve (values only).

    Starts on both segments at each of the ``n_starts`` nearest nodes, hands over to the
    next / previous segment while the root on the current one lies beyond ξ = 1 / ξ = 0,
    stops at a chain end or when it would return to the segment it came from (a corner
    node), clamps ξ to [0, 1], and keeps the nearest of the results. Failures are
    reported in ``ok``, not raised.
    """
    pts = np.asarray(points, dtype=float).reshape(-1, 2)
    n = pts.shape[0]
    before, after = curve.node_segments()
    used = np.unique(curve.seg)
    near = _nearest_nodes(curve.x[used], pts, min(n_starts, used.shape[0]))
    near = used[near]
    starts = np.concatenate([before[near], after[near]], axis=1)          # (n, 2 n_starts)
    starts = np.where(starts >= 0, starts, np.concatenate([after[near], before[near]], 1))
    owner = np.repeat(np.arange(n), starts.shape[1])
    seg = starts.ravel()
    xs = (pts[owner, 0], pts[owner, 1])
    came = np.full(seg.shape, -1)
    moving = np.ones(seg.shape, dtype=bool)
    for _ in range(max_hops):
        P = curve.split_points(curve.local_points(seg))
        xi, _, status = solve_on_segments(curve, seg, xs, P)
        nxt, prv = curve.next_seg[seg], curve.prev_seg[seg]
        go_next = (xi > 1.0) & (nxt >= 0) & (nxt != came)
        go_prev = (xi < 0.0) & (prv >= 0) & (prv != came)
        moving = go_next | go_prev
        if not moving.any():
            break
        came = np.where(moving, seg, came)
        seg = np.where(go_next, nxt, np.where(go_prev, prv, seg))
    xi = np.clip(xi, 0.0, 1.0)
    P = curve.split_points(curve.local_points(seg))
    xm = curve.derivatives(seg, xi, P, 0)[0]
    dist = np.hypot(xs[0] - xm[0], xs[1] - xm[1])
    ok = (status != FAILED) & ~moving
    dist_rank = np.where(ok, dist, np.inf).reshape(n, -1)
    best = np.argmin(dist_rank, axis=1) + np.arange(n) * starts.shape[1]
    return ClosestPoint(seg[best], xi[best], np.stack([xm[0][best], xm[1][best]], axis=1),
                        dist[best], ok.reshape(n, -1).any(axis=1))


R = 1.0
D = 0.02 * R                    # distance of the slave points from the circle
NS = [8, 16, 32, 64]
N_POINTS = 4000


def polygon(n: int, rotation: float = 0.1):
    phi = rotation - 2 * np.pi * np.arange(n) / n            # clockwise
    x = R * np.c_[np.cos(phi), np.sin(phi)]
    seg = np.stack([np.arange(n), np.roll(np.arange(n), -1)], axis=1)
    return x, seg


def slave_points(rng, start: float = 0.0, span: float = 2 * np.pi):
    """N_POINTS points at ±D from the circle (alternately outside and inside) at random
    angles in [start, start + span], and their exact gaps."""
    theta = rng.uniform(start, start + span, N_POINTS)
    sign = np.where(np.arange(N_POINTS) % 2 == 0, 1.0, -1.0)  # outside / inside
    r = R + sign * D
    return np.c_[r * np.cos(theta), r * np.sin(theta)], sign * D


def _gap_errors(curve, pts, exact, what: str) -> tuple[np.ndarray, np.ndarray]:
    """|g − exact| of every point's closest-point projection onto ``curve``, and the
    segment each projects onto."""
    cp = closest_point(curve, pts)
    if not cp.ok.all():
        raise RuntimeError(f"{what}: {np.count_nonzero(~cp.ok)} projections failed")
    P = curve.split_points(curve.local_points(cp.seg))
    g, _ = curve.gap(cp.seg, (pts[:, 0], pts[:, 1]), P)
    return np.abs(np.asarray(g) - exact), cp.seg


def gap_errors(smoothing: str, n: int, pts, exact):
    x, seg = polygon(n)
    return _gap_errors(make_curve(smoothing, x, seg), pts, exact, f"{smoothing}, n = {n}")[0]


def open_arc(n: int, start: float = 0.3, span: float = 0.5 * np.pi):
    """An open arc of the circle (a quarter by default) with n segments, clockwise so that
    n = e3 × t points outward; the chain ends at both arc ends."""
    phi = start + span - span * np.arange(n + 1) / n
    x = R * np.c_[np.cos(phi), np.sin(phi)]
    seg = np.stack([np.arange(n), np.arange(1, n + 1)], axis=1)
    return x, seg


def open_arc_errors(smoothing: str, n: int, rng, start: float = 0.3,
                    span: float = 0.5 * np.pi) -> tuple[float, float]:
    """(max gap error of the slave points projecting onto the two end segments, max over
    the interior segments) on :func:`open_arc`: the slave points at ±D from the circle at
    random angles within the arc."""
    x, seg = open_arc(n, start, span)
    pts, exact = slave_points(rng, start, span)
    err, on = _gap_errors(make_curve(smoothing, x, seg), pts, exact,
                          f"{smoothing}, open arc n = {n}")
    end = (on == 0) | (on == n - 1)
    return float(err[end].max()), float(err[~end].max())


def open_arc_table() -> str:
    """Markdown table: end-segment and interior gap errors per smoothing and n, their
    ratio, and the observed orders of both."""
    rng = np.random.default_rng(1)
    h = 0.5 * np.pi * R / np.array(NS)
    rows = ["| smoothing | " + " | ".join(f"n = {n}: end / interior" for n in NS)
            + " | order end, interior |", "|---|" + "---|" * len(NS) + "---|"]
    for s in SMOOTHINGS.names():
        e = np.array([open_arc_errors(s, n, rng) for n in NS])
        order = [np.log(e[:-1, k] / e[1:, k]) / np.log(h[:-1] / h[1:]) for k in (0, 1)]
        rows.append(f"| {s} | " + " | ".join(f"{a:.2e} / {b:.2e} ({a / b:.1f}×)"
                                             for a, b in e)
                    + f" | {order[0].mean():.2f}, {order[1].mean():.2f} |")
    return "\n".join(rows)


def _replace_block(text: str, marker: str, table: str) -> str:
    start, end = f"<!-- {marker} -->", f"<!-- /{marker} -->"
    i, j = text.index(start) + len(start), text.index(end)
    return text[:i] + "\n" + table + "\n" + text[j:]


def main() -> None:
    rng = np.random.default_rng(0)
    pts, exact = slave_points(rng)
    err = {s: np.array([gap_errors(s, n, pts, exact).max() for n in NS])
           for s in SMOOTHINGS.names()}
    h = 2 * R * np.sin(np.pi / np.array(NS))                 # segment length
    orders = {s: np.log(e[:-1] / e[1:]) / np.log(h[:-1] / h[1:]) for s, e in err.items()}

    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import matplotlib.ticker
    fig, ax = plt.subplots(figsize=(6.4, 4.6))
    styles = {"none": "k-o", "averaged-simple": "C0--s", "averaged-weighted": "C1:^",
              "averaged-tangent": "C2-.v", "hermite": "C3-D", "bspline": "C4-P"}
    for s in SMOOTHINGS.names():
        ax.loglog(NS, err[s], styles[s], label=s, ms=5)
    for p, y0 in ((2, err["none"][0]), (4, err["bspline"][0])):
        ax.loglog(NS, y0 * (NS[0] / np.array(NS)) ** p, color="0.6", lw=0.8)
        ax.text(NS[-1] * 1.08, y0 * (NS[0] / NS[-1]) ** p, f"O(h$^{p}$)", color="0.4",
                va="center")
    ax.set_xlabel("nodes on the circle n  (h = 2R sin(π/n))")
    ax.set_ylabel("max |g − g_exact|")
    ax.set_title(f"Gap error against the exact circle (R = {R:g}, |gap| = {D:g})")
    ax.set_xticks(NS, [str(n) for n in NS])
    ax.xaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
    ax.set_xlim(NS[0] / 1.2, NS[-1] * 1.6)
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=8)
    fig.tight_layout()
    png = ROOT / "docs" / "smoothing_gap_error.png"
    fig.savefig(png, dpi=120)
    plt.close(fig)

    rows = ["| smoothing | " + " | ".join(f"n = {n}" for n in NS) + " | observed order |",
            "|---|" + "---|" * len(NS) + "---|"]
    for s in SMOOTHINGS.names():
        rows.append(f"| {s} | " + " | ".join(f"{e:.2e}" for e in err[s])
                    + " | " + ", ".join(f"{o:.2f}" for o in orders[s]) + " |")
    table = "\n".join(rows)
    print(table)
    arc_table = open_arc_table()
    print(arc_table)
    md = ROOT / "docs" / "smoothing.md"
    text = _replace_block(md.read_text(), "gap-table", table)
    md.write_text(_replace_block(text, "open-arc-table", arc_table))


if __name__ == "__main__":
    main()
