"""Contact discretizations: from the current slave and master coordinates to the nodal
weighted gaps g̃_j and areas A_j of the slave nodes, with exact derivatives (docs/design.md §4).
One class per method, registered under its scene name.

* :class:`Mortar`: segment-to-segment integrals (:mod:`.mortar`), with the boundary
  hand-over of slave nodes sliding off the master's end (:mod:`.boundary`);
* :class:`NodeToSegment`: the classical baseline (:mod:`.nts`), which remembers each slave
  node's master segment between iterates.

Both return per-contribution values (:class:`~.kernel.NodalContributions`) and the nodal
sums, taken from the rank that owns each node (``surface.owned_sum``).
"""
from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from . import boundary, mortar, nts
from .curves import MasterCurve, make_curve
from .kernel import NodalContributions, nodal_sum
from .registry import METHODS

if TYPE_CHECKING:
    from .surface import Surface


class Discretization:
    """Base: one pair's slave and master surfaces and the method's own settings: Gauss
    points, and the multiplier basis that weights the gaps (``bases``: those it offers)."""

    name = ""
    bases: tuple[str, ...] = ("standard",)
    #: whether the slave's geometry may be smoothed too (two-sided smoothing)
    two_sided = False

    def __init__(self, slave: Surface, master: Surface, n_gauss: int | None = None,
                 basis: str = "standard", slave_smoothing: str = "none"):
        if basis not in self.bases:
            raise ValueError(f"method {self.name!r} has no {basis!r} multiplier basis "
                             f"(it offers: {', '.join(self.bases)})")
        if slave_smoothing != "none" and not self.two_sided:
            raise ValueError(f"method {self.name!r} has no smoothing of the slave surface")
        self.slave, self.master = slave, master
        self.n_gauss, self.basis, self.slave_smoothing = n_gauss, basis, slave_smoothing

    def weighted_gaps(self, xs: np.ndarray, xm: np.ndarray, curve: MasterCurve, pairs
                      ) -> tuple[NodalContributions, NodalContributions, np.ndarray, np.ndarray]:
        """(gap contributions, area contributions, g̃, A) at the current coordinates for
        the candidate ``pairs`` (slave segment, master segment) of this rank."""
        raise NotImplementedError

    def state_dict(self) -> dict[str, np.ndarray]:
        """Per-node history (merged from the owning ranks by the pair)."""
        return {}

    def load_state_dict(self, d: dict[str, np.ndarray]) -> None:
        pass


@METHODS.register("mortar")
class Mortar(Discretization):
    """g̃_j = ∫ ψ_j g dΓ, A_j = ∫ N_j dΓ over the slave segments (docs/design.md §4, §5a),
    ψ = N (standard basis) or the dual basis Φ."""

    bases = ("standard", "dual")
    two_sided = True

    def __init__(self, slave: Surface, master: Surface, n_gauss: int | None = None,
                 basis: str = "standard", slave_smoothing: str = "none"):
        super().__init__(slave, master, n_gauss, basis, slave_smoothing)
        if slave_smoothing != "none":
            probe = make_curve(slave_smoothing, slave.X, slave.seg)
            if probe.point_map is not None:
                raise ValueError(f"slave smoothing {slave_smoothing!r}: the slave curve must be "
                                 "local (its points the slave nodes): e.g. 'hermite'")

    def slave_curve(self, xs: np.ndarray) -> MasterCurve | None:
        """The slave's own smoothed curve through its current nodes (two-sided smoothing)."""
        if self.slave_smoothing == "none":
            return None
        return make_curve(self.slave_smoothing, xs, self.slave.seg)

    def weighted_gaps(self, xs, xm, curve, pairs):
        s, m = self.slave, self.master
        slave_curve = self.slave_curve(xs)
        n_gauss = self.n_gauss or max(curve.gauss_points,
                                      slave_curve.gauss_points if slave_curve else 0)
        gap, area = mortar.weighted_gaps(xs, s.seg, xm, m.seg, curve, pairs, n_gauss,
                                         basis=self.basis, slave_curve=slave_curve)
        A = s.owned_sum(nodal_sum(area, s.n))
        # slave nodes barely supported by the master (sliding off its end) hand their
        # terms to their supported neighbour (boundary.py)
        weak, supported = boundary.classify(A, boundary.full_areas(xs, s.seg, s.n))
        if weak.any():      # the same on every rank (A is): owned_sum is collective
            gap, area = boundary.hand_over((gap, area), A, weak, supported, s.neighbours)
            A = s.owned_sum(nodal_sum(area, s.n))
        return gap, area, s.owned_sum(nodal_sum(gap, s.n)), A


@METHODS.register("nts")
class NodeToSegment(Discretization):
    """g̃_j = A_j g_j at the slave node's projection (docs/design.md §1, §3)."""

    def __init__(self, slave: Surface, master: Surface, n_gauss: int | None = None,
                 basis: str = "standard", slave_smoothing: str = "none"):
        super().__init__(slave, master, n_gauss, basis, slave_smoothing)
        #: the master segment each slave node projected onto last (−1: none)
        self.segment = np.full(slave.n, -1, dtype=np.int64)

    def weighted_gaps(self, xs, xm, curve, pairs):
        s, m = self.slave, self.master
        gap, area = nts.node_gaps(xs, s.seg, xm, m.seg, curve, pairs, self.segment)
        return gap, area, s.owned_sum(nodal_sum(gap, s.n)), s.owned_sum(nodal_sum(area, s.n))

    def state_dict(self):
        return {"nts_segment": self.segment}

    def load_state_dict(self, d):
        self.segment = np.array(d["nts_segment"], dtype=np.int64)
