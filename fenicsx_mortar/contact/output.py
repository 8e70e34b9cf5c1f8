"""What a contact pair reports: the nodal table along the slave surface and the step record
(forces, active set, KKT residual). The files made of them are the scene layer's
(interface_files.py)."""
from __future__ import annotations

import numpy as np
from mpi4py import MPI


def interface_table(pair) -> dict[str, np.ndarray]:
    """Per slave node: its global vertex number, arc length s, current x, y, average gap
    g̃/A (nan where the node sees no master), pressure (per unit current length), active
    (0/1), and the friction law's columns."""
    st = pair.state
    xs, A = st.xs, st.A
    gap = np.where(A > 0, st.g / np.where(A > 0, A, 1.0), np.nan)
    d = dict(vertex=pair.slave.vertices, s=pair.slave.arc_length(xs), x=xs[:, 0],
             y=xs[:, 1], gap=gap,
             pressure=st.p, active=(st.p > 0).astype(int))
    d.update(pair.friction.interface(st))
    return d


def _slave_total(pair, f: np.ndarray) -> np.ndarray:
    total = f[: 2 * pair.slave.n].reshape(-1, 2).sum(axis=0)
    comm = pair.slave.comm
    return comm.allreduce(total, op=MPI.SUM) if comm.size > 1 else total


def _load_areas(pair) -> np.ndarray:
    """Per slave node, ∫ψ_j dΓ over the part of its support that sees the master (ψ_j the
    weight of its pressure): p_j times it is the normal force node j carries. It is the
    nodal area A_j except for the dual basis where a segment is only partly over the
    master and no neighbour took the node's terms: there ∫Φ_j can be near zero or negative
    while A_j > 0, and Σ p A reported 1e4 × the force (a block sliding off a slab)."""
    if getattr(pair.discretization, "basis", "standard") != "dual":
        return pair.state.A
    # decided by the basis, the same on every rank (owned_sum is collective): a rank
    # without candidate pairs has empty contributions and no psi
    area = pair.state.area
    psi = area.value if area.psi is None else area.psi
    s = pair.slave
    return s.owned_sum(np.bincount(area.node, weights=psi, minlength=s.n))


def pair_record(pair) -> dict:
    """{pair name: the step's contact record} (collective)."""
    st = pair.state
    # force the master exerts on the slave body = −(contact residual on slave dofs)
    f = -_slave_total(pair, pair.enforcement.residual(st, pair.weight))
    extra = {}
    tangential = pair.friction.residual(st, pair.weight)
    if tangential is not None:
        extra = pair.friction.record(st, _slave_total(pair, tangential))
    on = st.p > 0
    enf = pair.enforcement
    return {pair.name: {**extra,
        "normal_force": float(np.sum(st.p * _load_areas(pair))),
        "force_on_slave": [float(f[0]), float(f[1])],
        "max_pressure": float(st.p.max(initial=0.0)),
        "active_nodes": int(on.sum()),
        "active_length": float(st.A[on].sum()),
        "kkt_residual": pair.kkt_residual(),
        "augmentations": pair.augmentations,
        "epsilon": enf.epsilon0,
        "epsilon_max": float(enf.epsilon.max(initial=0.0)),
    }}
