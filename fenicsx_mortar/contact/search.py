"""Candidate (slave segment, master segment) pairs by bounding boxes (DESIGN.md §10, search).

A pair is a candidate when the axis-aligned bounding boxes of the two segments, each
inflated by ``radius``, overlap: |c_s − c_m| ≤ h_s + h_m + 2·radius on both axes (c box
centre, h half extent). A k-d tree over the box centres finds every pair whose centres are
within the Chebyshev distance 2·radius + max h_s + max h_m (a necessary condition), then the
exact test above is applied vectorized and the pairs are sorted through one integer key.
Cost ~ N log N + (number of candidates) as long as segment lengths are comparable; one very
long segment widens the tree query for all.
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


def candidate_pairs(xs: np.ndarray, seg_s: np.ndarray, xm: np.ndarray, seg_m: np.ndarray,
                    radius: float) -> Tuple[np.ndarray, np.ndarray]:
    """All (slave segment, master segment) index pairs whose inflated boxes overlap.

    Returned sorted by slave segment, then master segment.
    """
    cs, hs = segment_boxes(xs, seg_s)
    cm, hm = segment_boxes(xm, seg_m)
    empty = np.zeros(0, dtype=np.int64)
    if cs.shape[0] == 0 or cm.shape[0] == 0:
        return empty, empty.copy()
    reach = 2.0 * float(radius) + hs.max() + hm.max()
    # relative slack so that touching boxes are not lost to rounding in the tree
    reach *= 1.0 + 1e-12
    found = cKDTree(cs).sparse_distance_matrix(cKDTree(cm), reach, p=np.inf,
                                               output_type="ndarray")
    i = found["i"]
    j = found["j"]
    # exact box test per axis on contiguous columns (cheaper than a (n, 2) all())
    r2 = 2.0 * radius
    ok = np.abs(cs[i, 0] - cm[j, 0]) <= hs[i, 0] + hm[j, 0] + r2
    ok &= np.abs(cs[i, 1] - cm[j, 1]) <= hs[i, 1] + hm[j, 1] + r2
    # sorted by (slave, master) through one integer key
    nm = np.int64(cm.shape[0])
    key = i[ok].astype(np.int64) * nm + j[ok]
    key.sort()
    return key // nm, key % nm
