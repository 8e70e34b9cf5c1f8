"""Node chains for the contact kernels' tests, and the helpers of their Taylor tests.

A chain is an (n, 2) array of node coordinates and its (m, 2) segments (node pairs in
order; ``closed`` adds the segment back to the first node). The seeded configurations are
shared by the mortar and the NTS tests so that both kernels are checked on the same chains.
"""
import numpy as np


def chain(points, closed=False):
    n = len(points)
    seg = np.stack([np.arange(n - 1), np.arange(1, n)], axis=1)
    if closed:
        seg = np.vstack([seg, [[n - 1, 0]]])
    return np.asarray(points, dtype=float), seg


def jittered(a, b, n, rng, amount=0.3):
    """n nodes from a to b (either direction), spacing randomly non-uniform."""
    t = np.linspace(0.0, 1.0, n)
    t[1:-1] += rng.uniform(-amount, amount, n - 2) / (n - 1)
    return a + (b - a) * t


def curved_open(seed=5):
    """Curved, non-matching, partly overlapping chains: master (lower body's top, +x) on
    x ∈ [0, 3] with convex and concave parts; slave (upper body's bottom, −x) on
    x ∈ [3.6, 0.7], i.e. beyond the master's right end; gaps of both signs."""
    rng = np.random.default_rng(seed)
    xm_ = jittered(0.0, 3.0, 12, rng)
    xs_ = jittered(3.6, 0.7, 15, rng)
    xm, sm = chain(np.c_[xm_, 0.15 * np.sin(1.7 * xm_)])
    xs, ss = chain(np.c_[xs_, 0.15 * np.sin(1.7 * xs_) + 0.01 + 0.03 * np.cos(2.3 * xs_)])
    return xs, ss, xm, sm


def closed_master(seed=6):
    """Closed master (unit disk, clockwise so the normal points outward) under an open
    slave arc facing down; the disk's far side must be ignored (not facing)."""
    rng = np.random.default_rng(seed)
    phi = np.sort(rng.uniform(0, 2 * np.pi, 24))[::-1]            # clockwise
    xm, sm = chain(np.c_[np.cos(phi), np.sin(phi)], closed=True)
    xs_ = jittered(0.8, -0.7, 11, rng)
    xs, ss = chain(np.c_[xs_, 1.0 - 0.2 * xs_**2 + 0.02 * np.sin(3 * xs_)])
    return xs, ss, xm, sm


def assemble(contrib, ns, nm, weights):
    """G = Σ_k w[node_k] value_k with its global gradient and Hessian over
    [slave coords, master coords]."""
    n = 2 * (ns + nm)
    w = weights[contrib.node]
    dofs = contrib.global_indices(ns)
    g = np.zeros(n)
    np.add.at(g, dofs, w[:, None] * contrib.grad)
    H = np.zeros((n, n))
    np.add.at(H, (dofs[:, :, None], dofs[:, None, :]), w[:, None, None] * contrib.hess)
    return float(w @ contrib.value), g, H


def rates(h, r):
    """Observed orders log(r_i/r_{i+1}) / log(h_i/h_{i+1})."""
    return np.log(r[:-1] / r[1:]) / np.log(h[:-1] / h[1:])
