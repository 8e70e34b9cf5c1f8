"""Candidate pairs by inflated bounding boxes (fenicsx_mortar.contact.search)."""
import numpy as np
import pytest

from _chains import chain
from fenicsx_mortar.contact.search import candidate_pairs


def _brute_force(xs, ss, xm, sm, radius):
    # radius: one, or one per slave segment (both boxes of a pair inflated by it)
    r = np.broadcast_to(np.asarray(radius, dtype=float), (len(ss),))[:, None, None]
    lo_s = np.minimum(xs[ss[:, 0]], xs[ss[:, 1]])[:, None]
    hi_s = np.maximum(xs[ss[:, 0]], xs[ss[:, 1]])[:, None]
    lo_m = np.minimum(xm[sm[:, 0]], xm[sm[:, 1]])[None]
    hi_m = np.maximum(xm[sm[:, 0]], xm[sm[:, 1]])[None]
    ok = np.all((lo_s - 2 * r <= hi_m) & (lo_m <= hi_s + 2 * r), axis=2)
    return set(zip(*np.nonzero(ok)))


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_matches_brute_force_on_random_chains(seed):
    rng = np.random.default_rng(seed)
    # random walks with varying step lengths, some segments long
    xs, ss = chain(np.cumsum(rng.normal(scale=0.3, size=(60, 2)), axis=0))
    xm, sm = chain(np.cumsum(rng.normal(scale=0.2, size=(80, 2)), axis=0), closed=True)
    for radius in (0.0, 0.05, 0.4):
        ps, pm = candidate_pairs(xs, ss, xm, sm, radius)
        got = set(zip(ps.tolist(), pm.tolist()))
        assert len(got) == len(ps)                       # no duplicates
        assert got == _brute_force(xs, ss, xm, sm, radius)
        assert np.all(np.diff(ps) >= 0)                  # sorted by slave segment
    # one radius per slave segment (a graded mesh: twice each segment's own length)
    radius = 2.0 * np.linalg.norm(xs[ss[:, 1]] - xs[ss[:, 0]], axis=1)
    for moved in (0.0, 0.01, 1.0):           # the kept superset, then a new search
        x = xs + moved * rng.normal(size=xs.shape)
        ps, pm = candidate_pairs(x, ss, xm, sm, radius)
        got = set(zip(ps.tolist(), pm.tolist()))
        assert len(got) == len(ps) and got == _brute_force(x, ss, xm, sm, radius)


def test_hand_case():
    # master: flat line y = 0 from x = 0 to 3 in unit segments
    xm, sm = chain([[0, 0], [1, 0], [2, 0], [3, 0]])
    # slave: two segments at height 0.1 over x ∈ [2.5, 1.5] and [1.5, 0.5] (traversed −x),
    # then one rising steeply from (0.5, 0.1) to (−2, 5)
    xs, ss = chain([[2.5, 0.1], [1.5, 0.1], [0.5, 0.1], [-2.0, 5.0]])
    # radius 0.06: the vertical gap 0.1 is bridged (2 × 0.06); horizontally slave [1.5, 2.5]
    # reaches [1.44, 2.56], missing master [0, 1] (up to 1.06)
    ps, pm = candidate_pairs(xs, ss, xm, sm, 0.06)
    assert list(zip(ps.tolist(), pm.tolist())) == [(0, 1), (0, 2), (1, 0), (1, 1), (2, 0)]
    # boxes touching exactly: gap 0.1 closed by 2 × 0.05
    ps, pm = candidate_pairs(xs, ss, xm, sm, 0.05)
    assert (0, 1) in set(zip(ps.tolist(), pm.tolist()))
    # a radius too small to bridge the 0.1 vertical gap finds nothing
    ps, pm = candidate_pairs(xs, ss, xm, sm, 0.04)
    assert ps.size == 0 and pm.size == 0
