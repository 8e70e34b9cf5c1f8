"""A pair's nodal results as DOLFINx Functions, for XDMF/VTX output and ParaView.

P1 scalar Functions on the mesh, zero off the slave surface, set at the slave nodes from
the pair's last state (each rank its owned nodes, then the ghosts are updated):

* ``contact_pressure``: p_j, the normal contact traction, force per unit *current* length
  of the slave surface (the weighted gaps are integrated over the current slave segments);
* ``contact_gap``: g̃_j/A_j, the average normal gap over the node's supported slave
  length (a length; negative = penetration; 0 where the node sees no master);
* with friction, ``tangential_traction``: t_j, force per unit current length along the
  master's tangent, and ``stick_slip``: 0 not in contact, 1 stick, 2 slip.
"""
from __future__ import annotations

import numpy as np

from .. import _dolfinx as dx
from .friction import INACTIVE, SLIP, STICK

#: the values of the ``stick_slip`` field
STATUS_VALUES = {"inactive": INACTIVE, "stick": STICK, "slip": SLIP}


class PairFields:
    """The Functions of one pair (built once, updated by :meth:`update`).

    Args:
        pair: The :class:`~fenicsx_mortar.ContactPair`.
        V: Its displacement space.
    """

    def __init__(self, pair, V):
        self.pair = pair
        W, parent = dx.scalar_p1_space(V)
        to_w = np.full(int(parent.max(initial=-1)) + 1, -1, dtype=np.int64)
        to_w[parent] = np.arange(len(parent))
        s = pair.slave
        #: W's local dof of every slave node this rank owns, and the node's surface index
        self._dofs = to_w[s.owned_local_dofs[:, 0]] if len(s.owned_nodes) else \
            np.zeros(0, dtype=np.int64)
        self._nodes = s.owned_nodes
        names = ["contact_pressure", "contact_gap"]
        if pair.friction.name != "none":
            names += ["tangential_traction", "stick_slip"]
        prefix = f"{pair.name}_" if pair.name else ""
        self.functions = {n: dx.Function(W, name=prefix + n) for n in names}

    def update(self) -> dict:
        """Set the Functions from the pair's current state; return them by name."""
        st = self.pair.state
        if st is None:
            return self.functions
        A = st.A
        gap = np.where(A > 0, st.g / np.where(A > 0, A, 1.0), 0.0)
        values = {"contact_pressure": st.p, "contact_gap": gap}
        ts = st.tangential
        if ts is not None:
            values["tangential_traction"] = ts.t
            values["stick_slip"] = ts.status.astype(float)
        for name, f in self.functions.items():
            f.x.array[:] = 0.0
            v = values.get(name)
            if v is not None and len(self._dofs):
                f.x.array[self._dofs] = v[self._nodes]
            f.x.scatter_forward()
        return self.functions
