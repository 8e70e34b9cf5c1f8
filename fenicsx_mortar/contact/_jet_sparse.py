"""Support bookkeeping for the jets of :mod:`.ad`: interned supports, their unions and
embeddings, and Hessian sums added block by block, memoized per support."""
from __future__ import annotations

import numpy as np


def _lift(d: np.ndarray, nlead: int, nd: int) -> np.ndarray:
    """Give a derivative array (nlead leading axes + batch) a batch of nd axes (numpy rule)."""
    missing = nd - (d.ndim - nlead)
    if missing <= 0:
        return d
    return d.reshape(d.shape[:nlead] + (1,) * missing + d.shape[nlead:])


#: memoized support bookkeeping: the kernels combine the same few small supports over and
#: over (the same expression graph runs for every block of pairs), so the unions, their
#: positions, the contiguous runs and the flat Hessian positions are computed once per
#: distinct support and looked up afterwards. Supports are *interned* (one read-only array
#: per distinct content), so these lookups are keyed by object identity; every cache entry
#: keeps its key arrays alive, so an id is never reused while its entry exists.
_CACHE_MAX = 8192
_interned: dict = {}
_union_cache: dict = {}
_runs_cache: dict = {}
_flat_cache: dict = {}


def _frozen(a):
    if a is not None:
        a.setflags(write=False)
    return a


def _intern(a: np.ndarray) -> np.ndarray:
    """The canonical read-only int64 array with the contents of a."""
    a = np.asarray(a, dtype=np.int64)
    key = a.tobytes()
    hit = _interned.get(key)
    if hit is None:
        if len(_interned) >= _CACHE_MAX:
            _interned.clear()
        hit = _interned[key] = _frozen(a.copy())
    return hit


def _cached(cache: dict, key, make):
    """cache[key] (key: ids of the arrays in entry[0]), made by make() on a miss."""
    hit = cache.get(key)
    if hit is None:
        if len(cache) >= _CACHE_MAX:
            cache.clear()
        hit = cache[key] = make()
    return hit[1]


def _union(ia: np.ndarray, ib: np.ndarray):
    """Union of two supports and the positions of each in it (None: identical to the union)."""
    if ia is ib:
        return ia, None, None

    def make():
        if ia.shape == ib.shape and np.array_equal(ia, ib):
            return (ia, ib), (ia, None, None)
        u = np.union1d(ia, ib)
        pa = None if u.shape == ia.shape else _frozen(np.searchsorted(u, ia))
        pb = None if u.shape == ib.shape else _frozen(np.searchsorted(u, ib))
        return (ia, ib), (_intern(u), pa, pb)

    return _cached(_union_cache, (id(ia), id(ib)), make)


def _eg(g: np.ndarray, p, k: int) -> np.ndarray:
    """Embed a gradient (kp, *batch) at positions p of a support of size k."""
    if p is None:
        return g
    out = np.zeros((k,) + g.shape[1:])
    out[p] = g
    return out


def _runs(p: np.ndarray):
    """Contiguous runs of the positions p as (source slice, destination slice) pairs:
    block copies over contiguous batch rows are several times faster than fancy indexing.
    Memoized per p."""
    def make():
        brk = np.flatnonzero(np.diff(p) != 1) + 1
        starts = np.concatenate([[0], brk])
        ends = np.concatenate([brk, [p.shape[0]]])
        return p, tuple((slice(a, b), slice(p[a], p[a] + b - a))
                        for a, b in zip(starts.tolist(), ends.tolist()))

    return _cached(_runs_cache, id(p), make)


def _flat(pr: np.ndarray, pc: np.ndarray, k: int) -> np.ndarray:
    """Flat positions of the block [pr, pc] in a (k, k) array, row-major (memoized)."""
    return _cached(_flat_cache, (id(pr), id(pc), k),
                   lambda: ((pr, pc), _frozen((pr[:, None] * k + pc[None, :]).ravel())))


_ALL = ((slice(None), slice(None)),)


def _add_block(H: np.ndarray, blk: np.ndarray, pr, pc, coef=None) -> None:
    """H[pr, pc] += coef · blk for a block (kr, kc, *batch) at row positions pr and column
    positions pc of H (None: all rows / all columns)."""
    src = blk if coef is None else coef * blk
    if pr is None and pc is None:
        H += src
        return
    rr = _ALL if pr is None else _runs(pr)
    rc = _ALL if pc is None else _runs(pc)
    if len(rr) * len(rc) > 3 and H.flags.c_contiguous:
        # scattered block: one fancy-indexed update of the flattened (k·k, *batch) rows
        # instead of a Python loop over the runs (positions are distinct: no clash)
        k = H.shape[0]
        pr = _intern(np.arange(k)) if pr is None else pr
        pc = _intern(np.arange(k)) if pc is None else pc
        H2 = H.reshape((k * k,) + H.shape[2:])
        H2[_flat(pr, pc, k)] += src.reshape((pr.shape[0] * pc.shape[0],) + src.shape[2:])
        return
    for si, di in rr:
        for sj, dj in rc:
            H[di, dj] += src[si, sj]


def _eh(h, p, k: int):
    """Embed a Hessian (kp, kp, *batch) at positions p of a support of size k."""
    if h is None or p is None:
        return h
    out = np.zeros((k, k) + h.shape[2:])
    _add_block(out, h, p, p)
    return out


#: coefficient marking a Hessian term that is a fresh array of the caller's: it may become
#: the sum itself
_FRESH = "fresh"


def _hessian(k: int, shape: tuple, terms) -> np.ndarray:
    """Σ of Hessian terms over a support of size k and batch ``shape``: each term
    (block (kr, kc, *batch), row positions, column positions, coefficient or None) adds
    coef · block at [rows, columns]. A full-size term (positions None) starts the sum — a
    ``_FRESH`` one as it is, else coef · block — so no zero array is written and read
    again."""
    full = (k, k) + shape
    start = [n for n, (blk, pr, pc, coef) in enumerate(terms)
             if pr is None and pc is None
             and blk.shape[:2] + np.broadcast_shapes(blk.shape[2:], np.shape(coef)) == full]
    start.sort(key=lambda n: terms[n][3] is not _FRESH)
    if start:
        blk, _, _, coef = terms[start[0]]
        out = blk if coef is _FRESH else blk.copy() if coef is None else coef * blk
        terms = terms[:start[0]] + terms[start[0] + 1:]
    else:
        out = np.zeros(full)
    for blk, pr, pc, coef in terms:
        _add_block(out, blk, pr, pc, None if coef is _FRESH else coef)
    return out


def _sum_axis(a: np.ndarray, axis: int) -> np.ndarray:
    """a.sum(axis); over a short axis (Gauss points, nodes) as a sum of slices, which is
    faster than numpy's reduction over an inner axis."""
    n = a.shape[axis]
    if n == 0 or n > 8:
        return a.sum(axis)
    lead = (slice(None),) * axis
    out = a[lead + (0,)].copy() if n == 1 else a[lead + (0,)] + a[lead + (1,)]
    for i in range(2, n):
        out += a[lead + (i,)]
    return out


def _outer(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    return u[:, None] * v[None, :]
