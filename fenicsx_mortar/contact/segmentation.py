"""Segmentation of a slave segment by the master segments it faces (docs/design.md §4,
:mod:`.mortar` step 1): the shadow of each master segment on the slave segment, its ends
clamped to [0, 1], the Gauss rule on [0, 1], and the index layout of a candidate set. The
float pass over all candidates (:func:`prepass`) finds the contributing pairs and which
shadow end each integration bound is; only those ends get jets (:class:`Ends`,
:class:`Bounds`).
"""
from __future__ import annotations

import functools
from typing import NamedTuple, Tuple

import numpy as np

from . import ad
from .ad import Jet2, Vec2
from .curves import MasterCurve


@functools.lru_cache(maxsize=None)
def gauss_legendre_01(n: int) -> Tuple[np.ndarray, np.ndarray]:
    """Gauss–Legendre points and weights on [0, 1] (weights sum to 1; cached, read-only)."""
    s, w = np.polynomial.legendre.leggauss(int(n))
    s, w = 0.5 * (s + 1.0), 0.5 * w
    s.setflags(write=False)
    w.setflags(write=False)
    return s, w


def interval(xa: Vec2, xb: Vec2, nodes):
    """The ends ζ_c, ζ_d of the master segment's shadow on the slave segment (unclamped)
    and the boolean 'slave faces master' per pair; ``nodes`` = (x_c, x_d, t̄_c, t̄_d) per
    pair."""
    xc, xd, tc, td = nodes
    e = ad.sub(xb, xa)
    den_c = ad.dot(e, tc)
    den_d = ad.dot(e, td)
    facing = (ad.value(den_c) < 0.0) & (ad.value(den_d) < 0.0)
    if not np.all(facing):
        # keep the discarded entries finite; they are dropped by the caller
        den_c = ad.where(facing, den_c, -1.0)
        den_d = ad.where(facing, den_d, -1.0)
    zc = ad.div(ad.dot(ad.sub(xc, xa), tc), den_c)
    zd = ad.div(ad.dot(ad.sub(xd, xa), td), den_d)
    return zc, zd, facing


def clamp(zc: np.ndarray, zd: np.ndarray):
    """Integration bounds ζ_lo = max(min(ζ_c, ζ_d), 0), ζ_hi = min(max(ζ_c, ζ_d), 1) from
    the values of the shadow's ends, and which end each bound is: ``mix`` (2 × 2 boolean
    arrays) with ζ_lo = mix[0][0] ζ_c + mix[0][1] ζ_d (+ 0 where clamped) and ζ_hi =
    mix[1][0] ζ_c + mix[1][1] ζ_d (+ 1 where clamped), the form :func:`.ad.substitute`
    takes (the bounds' derivatives are those of the chosen end: no jets of their own)."""
    first = zc <= zd
    zmin = np.where(first, zc, zd)
    zmax = np.where(first, zd, zc)
    lo_in, hi_in = zmin > 0.0, zmax < 1.0
    lo = np.where(lo_in, zmin, 0.0)
    hi = np.where(hi_in, zmax, 1.0)
    mix = ((lo_in & first, lo_in & ~first), (hi_in & ~first, hi_in & first))
    return lo, hi, mix


class Ends(NamedTuple):
    """The bounds ζ_lo, ζ_hi of the pairs' integration intervals from the float pass, and
    which end of the shadow (:func:`interval`) each one is: the clamp's ``mix``
    (:func:`clamp`). Only these ends get jets (:meth:`entries`)."""

    lo: np.ndarray
    hi: np.ndarray
    mix: tuple

    def subset(self, pairs) -> "Ends":
        """The bounds of the pairs ``pairs`` (slice or index array)."""
        return Ends(self.lo[pairs], self.hi[pairs],
                     tuple(tuple(c[pairs] for c in row) for row in self.mix))

    def entries(self):
        """The ends in use as entries (pair, at_d: False for the start node c, True for the
        end node d), and per pair the entry each bound is (any entry where the bound is
        clamped) and whether it is that entry (1.0) or clamped (0.0)."""
        (lc, ld), (hc, hd) = self.mix
        ic, id_ = np.flatnonzero(lc | hc), np.flatnonzero(ld | hd)
        if ic.shape[0] + id_.shape[0] == 0:
            ic = np.zeros(1, dtype=np.int64)     # no bound moves: one entry to keep shapes
        pos_c = np.zeros(self.lo.shape[0], dtype=np.int64)
        pos_d = np.zeros(self.lo.shape[0], dtype=np.int64)
        pos_c[ic] = np.arange(ic.shape[0])
        pos_d[id_] = ic.shape[0] + np.arange(id_.shape[0])
        pair = np.concatenate([ic, id_])
        at_d = np.arange(pair.shape[0]) >= ic.shape[0]
        return (pair, at_d, (np.where(lc, pos_c, pos_d), np.where(hc, pos_c, pos_d)),
                ((lc | ld) * 1.0, (hc | hd) * 1.0))


class Bounds(NamedTuple):
    """ζ_lo, ζ_hi of a block of pairs: values, and for their derivatives the jet of ζ at
    the shadow's ends in use (batch: entries), the entry each bound is per pair, and
    whether it is that entry (1.0) or clamped (0.0)."""

    lo: np.ndarray
    hi: np.ndarray
    z_end: Jet2
    entry: tuple
    on: tuple

    def inner(self, pairs=None):
        """The bounds of the pairs (all, or a slice / index array) as :func:`.ad.substitute`
        takes them: the jets of the ends they are, and the mix."""
        (e_lo, e_hi), (a, b) = self.entry, self.on
        if pairs is not None:
            e_lo, e_hi, a, b = e_lo[pairs], e_hi[pairs], a[pairs], b[pairs]
        return (self.z_end[e_lo], self.z_end[e_hi]), ((a, None), (None, b))

    def grads(self, m: int) -> Tuple[np.ndarray, np.ndarray]:
        """Dense gradients (K, m) of ζ_lo and ζ_hi over the first m variables."""
        g = self.z_end.grad[:, :m]
        return tuple(on[:, None] * g[entry] for entry, on in zip(self.entry, self.on))

    def jets(self, m: int) -> Tuple[Jet2, Jet2]:
        """ζ_lo, ζ_hi as jets over the first m variables."""
        out = []
        for entry, on, clamp in zip(self.entry, self.on, (0.0, 1.0)):
            q = ad.where(on > 0.0, self.z_end[entry], clamp)
            out.append(q if q.m == m else Jet2(q.val, q.grad[:, :m], q.hess[:, :m, :m]))
        return out[0], out[1]


def columns(x: np.ndarray, rows: np.ndarray) -> Vec2:
    """(x[rows, 0], x[rows, 1]) by take on contiguous columns (much faster than fancy
    indexing of the (n, 2) array)."""
    return (np.ascontiguousarray(x[:, 0]).take(rows), np.ascontiguousarray(x[:, 1]).take(rows))


#: index layouts of the last few candidate sets (see layout)
_layouts: list = []


class _Layout(NamedTuple):
    """Index data of a candidate set that depends only on the pairs and the chains."""

    ps: np.ndarray        # candidate pairs
    pm: np.ndarray
    na: np.ndarray        # slave end nodes a, b of each pair
    nb: np.ndarray
    seg_used: np.ndarray  # master segments in use, and each pair's position among them
    inv: np.ndarray


def layout(ps: np.ndarray, pm: np.ndarray, slave_seg, master_seg, n_master_seg: int
            ) -> _Layout:
    """The index layout of the candidates, kept while the same candidates come again for
    the same chains (``slave_seg``, ``master_seg``: the caller's arrays, compared by
    identity; the search returns the same pairs at most Newton iterations)."""
    for lay, ss, ms in _layouts:
        if (ss is slave_seg and ms is master_seg and lay.ps.shape == ps.shape
                and np.array_equal(lay.ps, ps) and np.array_equal(lay.pm, pm)):
            return lay
    seg_s = np.asarray(slave_seg, dtype=np.int64).reshape(-1, 2)
    used = np.zeros(n_master_seg, dtype=bool)
    used[pm] = True
    lay = _Layout(ps.copy(), pm.copy(), *columns(seg_s, ps), np.flatnonzero(used),
                  (np.cumsum(used) - 1).take(pm))
    # the key holds the chains themselves (identity; they are the surfaces' topology)
    _layouts.insert(0, (lay, slave_seg, master_seg))
    del _layouts[4:]
    return lay


def _node_values(curve: MasterCurve, master_x, lay: _Layout):
    """(x_c, x_d, t̄_c, t̄_d) values per pair, evaluated once per master segment in use
    (the candidate pairs repeat each master segment many times) and gathered."""
    P = curve.split_points(curve.local_points(lay.seg_used, master_x))
    xc, xd = curve.node_points(lay.seg_used, P)
    tc, td = curve.node_tangents(lay.seg_used, P)
    return tuple((np.asarray(v[0], dtype=float).take(lay.inv),
                  np.asarray(v[1], dtype=float).take(lay.inv)) for v in (xc, xd, tc, td))


def prepass(xa: Vec2, xb: Vec2, curve: MasterCurve, master_x, lay: _Layout):
    """Values (ζ_lo, ζ_hi, keep, mix of :func:`clamp`) of the candidate pairs (slave end
    points xa, xb)."""
    nodes = _node_values(curve, master_x, lay)
    zc, zd, facing = interval(xa, xb, nodes)
    lo, hi, mix = clamp(np.asarray(zc, dtype=float), np.asarray(zd, dtype=float))
    return lo, hi, facing & (hi > lo), mix


def segmentation(slave_x: np.ndarray, slave_seg: np.ndarray, curve: MasterCurve,
                 pairs: Tuple[np.ndarray, np.ndarray], master_x: np.ndarray | None = None
                 ) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Integration intervals of the candidate pairs (values only).

    Returns ``(zeta_lo, zeta_hi, keep)``, each (n_pairs,): the interval [ζ_lo, ζ_hi] ⊂ [0, 1]
    of the slave segment served by the master segment and whether the pair contributes
    (faces the master and ζ_hi > ζ_lo). Master coordinates from ``master_x`` (default: the
    curve's own).
    """
    ps = np.asarray(pairs[0], dtype=np.int64)
    pm = np.asarray(pairs[1], dtype=np.int64)
    lay = layout(ps, pm, slave_seg, curve.seg, curve.seg.shape[0])
    xs = np.asarray(slave_x, dtype=float)
    return prepass(columns(xs, lay.na), columns(xs, lay.nb), curve, master_x, lay)[:3]
