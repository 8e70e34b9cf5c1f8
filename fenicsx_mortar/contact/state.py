"""The state of a contact pair at one Newton iterate: kinematics, nodal weighted gaps and
areas, the enforcement's pressures, and (with friction) the tangential state.

Built once per iterate by :meth:`.pair.ContactPair.update`; the residual, the tangent,
the records and the outputs all read it, so nothing is computed twice per iterate.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property
from typing import TYPE_CHECKING

import numpy as np
import scipy.sparse as sp

from . import assembly
from .curves import MasterCurve
from .kernel import NodalContributions

if TYPE_CHECKING:
    from .enforcement import NodalPressure
    from .friction import TangentialState


@dataclass
class ContactState:
    xs: np.ndarray                 # (n_slave, 2) current slave node coordinates
    xm: np.ndarray                 # (n_master, 2) current master node coordinates
    curve: MasterCurve             # the master curve through xm
    pairs: tuple                   # candidate (slave segment, master segment) pairs
    gap: NodalContributions        # weighted gaps g̃_j, per contribution
    area: NodalContributions       # nodal areas A_j, per contribution
    g: np.ndarray                  # (n_slave,) g̃_j (the owning rank's sums, on every rank)
    A: np.ndarray                  # (n_slave,) A_j
    layouts: assembly.Layouts = field(repr=False)
    law: "NodalPressure | None" = None           # p_j and its derivatives (enforcement)
    multipliers: np.ndarray | None = None        # (n_slave, 2) λ_n, λ_t when unknowns
    multiplier_scale: np.ndarray | None = None   # s_j of the multiplier rows
    tangential: "TangentialState | None" = None  # friction
    #: how the enforcement holds the tangential traction (:meth:`.enforcement.Enforcement.
    #: annotate`): the multiplier in the friction law's trial (λ_t, or the Uzawa t̂), None
    #: for a penalty-regularized stick; ``epsilon_t`` per node, None: the law's own
    traction_multiplier: np.ndarray | None = None
    epsilon_t: np.ndarray | None = None
    #: the smallest average gap round-off in the coordinates can resolve (the enforcement's)
    gap_resolution: float = 0.0
    #: the friction statuses of the last Uzawa solve, at the next solve's first iterate
    held_status: np.ndarray | None = None
    #: per node, the gap Newton's residual tolerance leaves unresolved (the enforcement's)
    gap_noise: np.ndarray | float = 0.0

    @property
    def n_slave(self) -> int:
        return self.xs.shape[0]

    @property
    def n_test(self) -> int:
        """Stacked node coordinates [slave, master]: rows of the nodal forces."""
        return 2 * (self.xs.shape[0] + self.xm.shape[0])

    @property
    def p(self) -> np.ndarray:
        return self.law.p

    @property
    def active(self) -> np.ndarray:
        return self.law.active

    @cached_property
    def T(self) -> sp.csr_matrix | None:
        """Map from the stacked [slave nodes, master nodes] coordinates to [slave nodes,
        curve points] (None when the curve points are the master nodes): the kernels
        differentiate with respect to the curve points (the B-spline's control points)."""
        if self.curve.point_map is None:
            return None
        return sp.block_diag([sp.identity(2 * self.n_slave),
                              sp.kron(self.curve.point_map, sp.identity(2))], format="csr")

    @property
    def n_coords(self) -> int:
        """The kernels' stacked coordinates [slave nodes, curve points]."""
        return self.n_test if self.T is None else self.T.shape[0]

    @cached_property
    def G(self) -> sp.csr_matrix:
        """Rows ∇g̃_j over the kernels' coordinates."""
        return assembly.gradient_matrix(self.gap, self.n_slave, self.n_coords, self.layouts)

    @cached_property
    def G_area(self) -> sp.csr_matrix:
        """Rows ∇A_j over the kernels' coordinates."""
        return assembly.gradient_matrix(self.area, self.n_slave, self.n_coords, self.layouts)

    def to_nodes(self, f=None, K=None, rows_in_nodes: bool = False):
        """Vectors and matrices over [slave, curve points] → over [slave, master nodes]
        (``rows_in_nodes``: K's rows already are, as with test vectors)."""
        T = self.T
        if T is None:
            return f if K is None else K
        if K is None:
            return T.T @ f
        return K @ T if rows_in_nodes else T.T @ K @ T
