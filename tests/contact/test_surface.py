"""Contact surfaces from facet tags (contact/surface.py)."""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
from mpi4py import MPI

from fenicsx_mortar import _dolfinx as dx
from fenicsx_mortar.contact.surface import build_surface


def _top_facets(branch: bool):
    """The unit square's top edge (2 x 2 cells), with ``branch`` also the interior facet
    from (0.5, 1) down to (0.5, 0.5): three facets at one node."""
    msh = dx.unit_square(MPI.COMM_SELF, 2, 2)
    V = dx.vector_space(msh)
    dx.facet_vertices(msh)
    n = dx.num_owned_facets(msh)
    mid = dx.midpoints(msh, 1, np.arange(n, dtype=np.int32))
    top = np.isclose(mid[:, 1], 1.0)
    if branch:
        top |= np.isclose(mid[:, 0], 0.5) & np.isclose(mid[:, 1], 0.75)
    facets = np.flatnonzero(top).astype(np.int32)
    return V, SimpleNamespace(indices=facets, values=np.ones(len(facets), dtype=np.int32))


def test_the_top_edge_is_one_oriented_chain():
    V, tags = _top_facets(branch=False)
    s = build_surface(V, tags, 1, "top")
    assert s.n == 3 and len(s.seg) == 2
    t = s.X[s.seg[:, 1]] - s.X[s.seg[:, 0]]
    assert np.allclose(np.c_[-t[:, 1], t[:, 0]] / np.linalg.norm(t, axis=1)[:, None], [0, 1])
    assert (s.seg[1:, 0] == s.seg[:-1, 1]).all()             # ordered along the chain


def test_a_branching_surface_is_refused_by_name():
    V, tags = _top_facets(branch=True)
    with pytest.raises(ValueError, match=r"top: the node at \(0.5, 1\) is in 3 segments: not a"):
        build_surface(V, tags, 1, "top")
