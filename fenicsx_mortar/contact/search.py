"""Candidate (slave segment, master segment) pairs by bounding boxes (docs/design.md §4).

A pair is a candidate when the axis-aligned bounding boxes of the two segments, each
inflated by ``radius``, overlap: |c_s − c_m| ≤ h_s + h_m + 2·radius on both axes (c box
centre, h half extent). ``radius`` is one number or one per slave segment (r_s: then the
pair's test uses the slave segment's own), so that a graded slave mesh searches locally.
A k-d tree over the box centres finds every pair whose centres are within the Chebyshev
distance 2·max radius + max h_s + max h_m (a necessary condition), then the
exact test above is applied vectorized and the pairs are sorted through one integer key.
Cost ~ N log N + (number of candidates) as long as segment lengths are comparable; one very
long segment widens the tree query for all. While the nodes move little (Newton iterations)
the tree search is reused: see :func:`candidate_pairs`.
"""
from __future__ import annotations

from typing import Tuple

import numpy as np
from scipy.spatial import cKDTree


def segment_boxes(x: np.ndarray, seg: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
    """Centres and half extents, both (n_seg, 2), of the segments' bounding boxes."""
    x = np.asarray(x, dtype=float)
    seg = np.asarray(seg, dtype=np.int64).reshape(-1, 2)
    p, q = x[seg[:, 0]], x[seg[:, 1]]
    return 0.5 * (p + q), 0.5 * np.abs(q - p)


#: candidate supersets of the last few searches (see candidate_pairs)
_supersets: list = []
#: a superset is searched with the radius enlarged by 2·SLACK·radius and serves while no
#: node has moved by more than SLACK·radius (per coordinate) since
SLACK = 0.25


def _overlap(cs, hs, cm, hm, i: np.ndarray, j: np.ndarray, radius) -> np.ndarray:
    """The exact test |c_s − c_m| ≤ h_s + h_m + 2·radius on both axes for the index pairs
    (i, j), on contiguous columns gathered with take (several times faster than fancy
    indexing of the (n, 2) arrays)."""
    r2 = 2.0 * (radius.take(i) if np.ndim(radius) else radius)
    ok = None
    for axis in (0, 1):
        c_s, h_s = np.ascontiguousarray(cs[:, axis]), np.ascontiguousarray(hs[:, axis])
        c_m, h_m = np.ascontiguousarray(cm[:, axis]), np.ascontiguousarray(hm[:, axis])
        test = np.abs(c_s.take(i) - c_m.take(j)) <= h_s.take(i) + h_m.take(j) + r2
        ok = test if ok is None else ok & test
    return ok


def _search(cs, hs, cm, hm, radius) -> Tuple[np.ndarray, np.ndarray]:
    """Candidate pairs from the boxes, sorted by (slave, master): k-d tree, exact test."""
    reach = 2.0 * float(np.max(radius)) + hs.max() + hm.max()
    # relative slack so that touching boxes are not lost to rounding in the tree
    reach *= 1.0 + 1e-12
    found = cKDTree(cs).sparse_distance_matrix(cKDTree(cm), reach, p=np.inf,
                                               output_type="ndarray")
    i = np.ascontiguousarray(found["i"], dtype=np.int64)
    j = np.ascontiguousarray(found["j"], dtype=np.int64)
    ok = _overlap(cs, hs, cm, hm, i, j, radius)
    # sorted by (slave, master) through one integer key
    nm = np.int64(cm.shape[0])
    key = i[ok] * nm + j[ok]
    key.sort()
    return key // nm, key % nm


def _superset(xs, seg_s, xm, seg_m, radius, cs, hs, cm, hm):
    """Sorted pairs containing every candidate of the current coordinates: a kept superset
    while the nodes stay within SLACK·radius of where it was searched, else a new one.

    Why it contains them: moving the nodes by at most δ per coordinate moves each box
    centre and changes each half extent by at most δ, so a pair whose boxes overlap now
    satisfied |c_s − c_m| ≤ h_s + h_m + 2·radius + 4δ there, the test of radius + 2δ."""
    slack = SLACK * float(np.min(radius))
    for entry in _supersets:
        (ss, sm, r, x0s, x0m), pairs = entry
        if (ss is seg_s and sm is seg_m and np.array_equal(r, radius) and x0s.shape == xs.shape
                and x0m.shape == xm.shape
                # a margin of 1 % for the rounding of the box arithmetic
                and np.abs(xs - x0s).max(initial=0.0) <= 0.99 * slack
                and np.abs(xm - x0m).max(initial=0.0) <= 0.99 * slack):
            return pairs
    pairs = _search(cs, hs, cm, hm, radius + 2.0 * slack)
    # the key holds the segment arrays themselves (identity, not a copy: they are the
    # surfaces' fixed topology) and copies of the coordinates
    _supersets.insert(0, ((seg_s, seg_m, np.copy(radius), xs.copy(), xm.copy()), pairs))
    del _supersets[4:]
    return pairs


def search_once(xs: np.ndarray, seg_s: np.ndarray, xm: np.ndarray, seg_m: np.ndarray,
                radius: float | np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
    """The pairs of :func:`candidate_pairs`, searched afresh (no superset kept): for a
    one-off question about a few segments, which must not evict the Newton loop's."""
    cs, hs = segment_boxes(xs, seg_s)
    cm, hm = segment_boxes(xm, seg_m)
    if cs.shape[0] == 0 or cm.shape[0] == 0:
        return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
    return _search(cs, hs, cm, hm, np.asarray(radius, dtype=float) if np.ndim(radius)
                   else radius)


def candidate_pairs(xs: np.ndarray, seg_s: np.ndarray, xm: np.ndarray, seg_m: np.ndarray,
                    radius: float | np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
    """All (slave segment, master segment) index pairs whose inflated boxes overlap
    (``radius``: one, or one per slave segment).

    Returned sorted by slave segment, then master segment.

    Between Newton iterations the nodes move little: the tree search is made for a slightly
    larger radius once (:func:`_superset`), and each call redoes only the exact box test
    on that superset — the same pairs, in the same order, as a search of its own.
    """
    xs = np.asarray(xs, dtype=float)
    xm = np.asarray(xm, dtype=float)
    cs, hs = segment_boxes(xs, seg_s)
    cm, hm = segment_boxes(xm, seg_m)
    empty = np.zeros(0, dtype=np.int64)
    if cs.shape[0] == 0 or cm.shape[0] == 0:
        return empty, empty.copy()
    if np.ndim(radius):
        radius = np.asarray(radius, dtype=float)
    i, j = _superset(xs, seg_s, xm, seg_m, radius, cs, hs, cm, hm)
    ok = _overlap(cs, hs, cm, hm, i, j, radius)
    return i[ok], j[ok]
