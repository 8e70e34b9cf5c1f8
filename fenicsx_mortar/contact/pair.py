"""A contact pair as a Newton-loop hook: surfaces → search → curve → weighted gaps →
enforcement → assembly, plus its per-step record and interface outputs.

Every rank holds both (1D) surfaces and evaluates the kernels; each slave node's terms are
inserted by the rank that owns its dofs, so every term enters the global system once.
"""
from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import scipy.sparse as sp
from scipy.spatial import cKDTree
from mpi4py import MPI

from .. import _dolfinx as dx
from ..output import write_atomic
from ..scene import ContactPair, Scene, SceneError
from . import assembly, boundary, friction, mortar, nts
from .curves import make_curve
from .enforcement import ENFORCEMENTS
from .kernel import nodal_sum
from .search import candidate_pairs
from .surface import Surface, build_surface


class PairHook:
    def __init__(self, pair: ContactPair, slave: Surface, master: Surface, E_slave: float,
                 V, timings):
        self.pair, self.slave, self.master, self.timings = pair, slave, master, timings
        self.comm = slave.comm
        self.h = h = _mean_length(slave)
        nominal = E_slave / h  # pressure per gap of a surface layer one element deep
        eps = pair.enforcement.epsilon or nominal
        if pair.enforcement.type == "alm":
            # the ALM answer does not depend on ε; a start stiffer than the bodies makes the
            # first Newton solve fragile (Hertz at h = a/4 fails from 10 E/h), so start at
            # most at E/h and let the augmentations raise it (enforcement.py)
            eps = min(eps, nominal)
        if pair.enforcement.type == "penalty" and eps > 1e3 * nominal:
            warnings.warn(f"contact {pair.name}: penalty epsilon = {eps:.3g} is "
                          f"{eps / nominal:.0e} x E/h = {nominal:.3g}: round-off in epsilon*gap "
                          "may keep Newton from converging; prefer enforcement type 'alm'",
                          stacklevel=2)
        # gaps are differences of coordinates: below ~32 ulp of the largest one they are noise
        scale = max(np.abs(slave.X).max(initial=0.0), np.abs(master.X).max(initial=0.0), h)
        self.enforcement = ENFORCEMENTS[pair.enforcement.type](
            eps, slave.n, pair.enforcement.tolerance, 32 * np.finfo(float).eps * scale,
            start=nominal)
        self.radius = pair.search_radius or 2.0 * h
        self.dofs = np.concatenate([slave.dofs.ravel(), master.dofs.ravel()])
        # the master curve: rebuilt from the converged nodes at each load step (the B-spline
        # freezes its parametrization there, DESIGN.md §6), moved with the nodes in between
        self._curve = make_curve(pair.smoothing, master.X, master.seg)
        self.n_global = V.dofmap.index_map.size_global * V.dofmap.index_map_bs
        self.mine = np.zeros(slave.n, dtype=bool)
        self.mine[slave._mine] = True
        # this rank integrates the slave segments touching the nodes whose dofs it owns: the
        # weighted gaps of those nodes are then complete here (one segment of overlap at
        # each partition boundary), and their terms are inserted by this rank only
        self.my_segments = self.mine[slave.seg[:, 0]] | self.mine[slave.seg[:, 1]]
        self._skip = None
        self.augmentations = 0
        self._first_jacobian = True
        self._decisions: list[tuple[np.ndarray, float]] = []
        self._nts_segment = np.full(slave.n, -1, dtype=np.int64)
        self.friction = None
        if pair.friction.law == "coulomb":
            self.friction = friction.CoulombFriction(pair.friction.mu, self.enforcement.epsilon0,
                                                     slave.n)
            self._fric_seg = np.full(slave.n, -1, dtype=np.int64)
        self.state = None

    @property
    def path_dependent(self) -> bool:
        return self.friction is not None

    # -- kinematics ---------------------------------------------------------------------
    def update(self, u) -> None:
        with self.timings("contact"):
            xs = self.slave.X + self.slave.displacement(u)
            xm = self.master.X + self.master.displacement(u)
            self.state = self._evaluate(xs, xm)

    def _evaluate(self, xs, xm) -> dict:
        s, m = self.slave, self.master
        with self.timings("contact_search"):
            pairs = candidate_pairs(xs, s.seg, xm, m.seg, self.radius)
            if not self.my_segments.all():
                keep = self.my_segments[pairs[0]]
                pairs = (pairs[0][keep], pairs[1][keep])
        # projection and integration are one vectorized pass (kernel = both)
        with self.timings("contact_kernel"):
            curve = self._curve.with_nodes(xm)
            if self.pair.method == "mortar":
                gap, area, _, _ = mortar.weighted_gaps(xs, s.seg, xm, m.seg, curve, pairs,
                                                       self.pair.n_gauss or curve.gauss_points)
            else:
                gap, area = nts.node_gaps(xs, s.seg, xm, m.seg, curve, pairs,
                                          self._nts_segment)
        A = self._owned_sum(nodal_sum(area, s.n))
        if self.pair.method == "mortar":
            # slave nodes barely supported by the master (sliding off its end) hand their
            # terms to their supported neighbour (boundary.py)
            weak = boundary.unsupported(A, boundary.full_areas(xs, s.seg, s.n))
            if weak.any():
                gap, area = boundary.hand_over(gap, weak), boundary.hand_over(area, weak)
                A = self._owned_sum(nodal_sum(area, s.n))
        g = self._owned_sum(nodal_sum(gap, s.n))
        p, active = self.enforcement.pressure(g, A)
        st = dict(xs=xs, xm=xm, gap=gap, area=area, g=g, A=A, p=p, active=active,
                  **self._coordinates(curve))
        if self.friction is not None:
            st.update(self._tangential(xs, xm, curve, pairs, p, active))
        return st

    def _coordinates(self, curve) -> dict:
        """The kernels differentiate with respect to [slave nodes, curve points]; T maps
        master node coordinates to the curve's points (the B-spline's control points)."""
        ns = self.slave.n
        if curve.point_map is None:
            return dict(n_coords=2 * (ns + self.master.n), T=None)
        T = sp.block_diag([sp.identity(2 * ns), sp.kron(curve.point_map, sp.identity(2))],
                          format="csr")
        return dict(n_coords=T.shape[0], T=T)

    def _to_nodes(self, f=None, K=None, rows_in_nodes: bool = False):
        """Vectors and matrices over [slave, curve points] → over [slave, master nodes]
        (``rows_in_nodes``: K's rows already are, as with test vectors)."""
        T = self.state["T"]
        if T is None:
            return f if K is None else K
        if K is None:
            return T.T @ f
        return K @ T if rows_in_nodes else T.T @ K @ T

    def _normal_force(self, weight: np.ndarray) -> np.ndarray:
        """−Σ_j weight_j p_j ∇g̃_j (or −Σ_j weight_j p_j T_j with test vectors) over the
        stacked node coordinates."""
        st = self.state
        if st["gap"].test is not None:
            T = assembly.test_matrix(st["gap"], self.slave.n, self.dofs.shape[0])
            return -(T.T @ (st["p"] * weight))
        return self._to_nodes(-(self._G().T @ (st["p"] * weight)))

    def _tangential(self, xs, xm, curve, pairs, p, active) -> dict:
        """Projections of the slave nodes, slips since their reference points, return map."""
        s, fr = self.slave, self.friction
        ps, pm = pairs
        key = np.unique(np.concatenate([s.seg[ps, 0], s.seg[ps, 1]]) * max(len(self.master.seg), 1)
                        + np.concatenate([pm, pm]))
        nodes, segs = nts._closest_segments(xs, xm, key // max(len(self.master.seg), 1),
                                            key % max(len(self.master.seg), 1), curve,
                                            self._fric_seg)
        self._fric_seg[:] = -1
        self._fric_seg[nodes] = segs
        P = curve.split_points(curve.local_points(segs, xm))
        xi = np.asarray(curve.project(segs, (xs[nodes, 0], xs[nodes, 1]), P), dtype=float)
        fr.anchor_missing(nodes, segs, xi)
        slip = friction.slip_contributions(xs, xm, curve, nodes, segs, fr.ref_seg[nodes],
                                           fr.ref_xi[nodes])
        gT = self._owned_sum(nodal_sum(slip, s.n))
        t, status, dt_dg, dt_dp = fr.traction(gT, p, active)
        _, a = curve.evaluate(segs, xi, P)
        return dict(slip=slip, gT=gT, t=t, status=status, dt_dg=dt_dg, dt_dp=dt_dp,
                    proj=(nodes, segs, xi, np.hypot(*a)))

    def _owned_sum(self, values: np.ndarray) -> np.ndarray:
        """Every rank gets each node's value from the rank that owns the node."""
        if self.comm.size == 1:
            return values
        return self.comm.allreduce(np.where(self.mine, values, 0.0), op=MPI.SUM)

    # -- residual and tangent -------------------------------------------------------------
    def _G(self):
        st = self.state
        if "G" not in st:
            st["G"] = assembly.gradient_matrix(st["gap"], self.slave.n, st["n_coords"])
        return st["G"]

    def _friction_terms(self, tangent: bool):
        st = self.state
        return assembly.friction_terms(
            st["slip"], st["t"], st["dt_dg"], st["dt_dp"], st["A"], st["g"], st["active"],
            self._G(), assembly.gradient_matrix(st["area"], self.slave.n, st["n_coords"]),
            self.enforcement.epsilon, self.slave.n, st["n_coords"], self.mine.astype(float),
            tangent)

    def add_residual(self, b, bc_dofs) -> None:
        f = self._normal_force(self.mine)
        if self.friction is not None:
            f = f + self._to_nodes(self._friction_terms(tangent=False)[0])
        with self.timings("contact_insertion"):
            assembly.add_to_vector(b, self.dofs, f)

    def add_jacobian(self, A, bc_dofs) -> None:
        st = self.state
        touching = None
        if self._first_jacobian:
            # First iteration of a load step: nodes whose average gap is closed to within 1 %
            # of their support length also get the penalty stiffness. A body held only by
            # contact then has a non-singular tangent even where a curved surface touches a
            # flat one at a single point (its nodes' weighted gaps are small but positive).
            A_ = st["A"]
            touching = (A_ > 0) & (st["g"] <= 0.01 * A_**2)
            self._first_jacobian = False
        *_, K = assembly.contact_terms(st["gap"], st["area"], self.enforcement, self.slave.n,
                                       st["n_coords"], self.mine.astype(float),
                                       touching=touching, n_test=self.dofs.shape[0])
        K = self._to_nodes(K=K, rows_in_nodes=st["gap"].test is not None)
        if self.friction is not None:
            K = K + self._to_nodes(K=self._friction_terms(tangent=True)[1])
        with self.timings("contact_insertion"):
            assembly.add_to_matrix(A, K, self.dofs, self._skip_dofs(bc_dofs), self.n_global)

    def _skip_dofs(self, bc_dofs) -> np.ndarray:
        if self._skip is None:
            local = np.asarray(bc_dofs)
            g = self._l2g[local] if len(local) else np.zeros(0, dtype=np.int64)
            self._skip = np.unique(np.concatenate(self.comm.allgather(g)))
        return self._skip

    # -- step logic -------------------------------------------------------------------
    def newton_ok(self) -> bool:
        return True

    def begin_solve(self) -> None:
        self._decisions = []

    def _decision(self) -> np.ndarray:
        """What the semi-smooth Newton decides per slave node: 0 inactive, 1 active (or, with
        friction, the stick/slip status with the slip direction)."""
        st = self.state
        d = st["active"].astype(np.int8)
        if self.friction is not None:
            d = d + 2 * st["status"].astype(np.int8) + 8 * (st["t"] < 0)
        return d

    def cycling(self, fnorm: float) -> str | None:
        """A decision vector that reappears after a different one (period ≥ 2) while the
        residual has not even halved since its first appearance: Newton is going round in
        circles (a repeat with progress, e.g. an edge node opening and closing again on the
        way to the answer, is no cycle)."""
        if self.state is None:
            return None
        d = self._decision()
        seen = self._decisions
        seen.append((d, fnorm))
        if len(seen) >= 3 and not np.array_equal(d, seen[-2][0]):
            for k, (old, r_old) in enumerate(seen[:-2]):
                if np.array_equal(d, old) and fnorm >= 0.5 * r_old:
                    flip = np.flatnonzero(d != seen[-2][0])
                    return (f"contact {self.pair.name}: the active/stick-slip set of iteration "
                            f"{len(seen) - 1} repeats iteration {k} (period "
                            f"{len(seen) - 1 - k}) with the residual at {fnorm:.3e} (was "
                            f"{r_old:.3e}); slave nodes {flip[:10].tolist()} flip")
        return None

    def augment(self) -> bool:
        st = self.state
        again = self.enforcement.augment(st["g"], st["A"])
        if again:
            self.augmentations += 1
        return again

    def begin_step(self) -> None:
        self.enforcement.begin_step()
        self.augmentations = 0
        self._first_jacobian = True
        if self.state is not None:
            self._curve = make_curve(self.pair.smoothing, self.state["xm"], self.master.seg)

    def accept_step(self) -> None:
        self.enforcement.accept()
        if self.friction is not None:
            st = self.state
            nodes, segs, xi, length = st["proj"]
            self.friction.commit(nodes, segs, xi, st["t"][nodes], st["status"][nodes], length)

    def reject_step(self) -> None:
        self.enforcement.reject()
        if self.friction is not None:
            self.friction.reject()

    def state_dict(self) -> dict[str, np.ndarray]:
        """History carried between steps (for checkpoints)."""
        seg = self._nts_segment
        if self.comm.size > 1:
            seg = self.comm.allreduce(np.where(self.mine, seg + 1, 0), op=MPI.SUM) - 1
        d = {"multiplier": self.enforcement.multiplier.copy(), "nts_segment": seg}
        if self.friction is not None:
            ref_seg, ref_xi = self.friction.ref_seg, self.friction.ref_xi
            if self.comm.size > 1:
                ref_seg = self.comm.allreduce(np.where(self.mine, ref_seg + 1, 0), op=MPI.SUM) - 1
                ref_xi = self.comm.allreduce(np.where(self.mine, ref_xi, 0.0), op=MPI.SUM)
            d.update(ref_seg=ref_seg, ref_xi=ref_xi)
        return d

    def load_state_dict(self, d: dict[str, np.ndarray]) -> None:
        self.enforcement.multiplier = np.array(d["multiplier"], dtype=float)
        self.enforcement.accept()
        self._nts_segment = np.array(d["nts_segment"], dtype=np.int64)
        if self.friction is not None:
            self.friction.ref_seg = np.array(d["ref_seg"], dtype=np.int64)
            self.friction.ref_xi = np.array(d["ref_xi"], dtype=float)
            # the loaded history becomes the committed one (reject() restores from it)
            self.friction._committed = (self.friction.ref_seg.copy(), self.friction.ref_xi.copy())
            self.friction.reject()

    # -- outputs ------------------------------------------------------------------------
    def interface(self) -> dict[str, np.ndarray]:
        st = self.state
        xs = st["xs"]
        A = st["A"]
        gap = np.where(A > 0, st["g"] / np.where(A > 0, A, 1.0), np.nan)
        d = dict(s=self.slave.arc_length(xs), x=xs[:, 0], y=xs[:, 1], gap=gap,
                 pressure=st["p"], active=(st["p"] > 0).astype(int))
        if self.friction is not None:
            names = {friction.STICK: "stick", friction.SLIP: "slip", friction.INACTIVE: "inactive"}
            d.update(t_tangential=st["t"], slip=st["gT"],
                     status=np.array([names[int(k)] for k in st["status"]]))
        return d

    def record(self) -> dict:
        st = self.state
        # force the master exerts on the slave body = −(contact residual on slave dofs)
        f = -self._normal_force(self.mine)[: 2 * self.slave.n].reshape(-1, 2).sum(axis=0)
        f = self.comm.allreduce(f, op=MPI.SUM) if self.comm.size > 1 else f
        on = st["p"] > 0
        extra = {}
        if self.friction is not None:
            ft = self._friction_terms(tangent=False)[0][: 2 * self.slave.n].reshape(-1, 2).sum(axis=0)
            ft = self.comm.allreduce(ft, op=MPI.SUM) if self.comm.size > 1 else ft
            extra = {"tangential_force_on_slave": [float(-ft[0]), float(-ft[1])],
                     "tangential_force": float(np.sum(st["t"] * st["A"])),
                     "stick_nodes": int(np.sum(st["status"] == friction.STICK)),
                     "slip_nodes": int(np.sum(st["status"] == friction.SLIP))}
        return {self.pair.name: {**extra,
            "normal_force": float(np.sum(st["p"] * st["A"])),
            "force_on_slave": [float(f[0]), float(f[1])],
            "max_pressure": float(st["p"].max(initial=0.0)),
            "active_nodes": int(on.sum()),
            "active_length": float(st["A"][on].sum()),
            "kkt_residual": self.enforcement.kkt_residual(st["g"], st["A"]),
            "augmentations": self.augmentations,
            "epsilon": self.enforcement.epsilon0,
            "epsilon_max": float(self.enforcement.epsilon.max(initial=0.0)),
        }}

    def write_interface(self, out: Path, step: int) -> None:
        d = self.interface()
        cols = ("s", "x", "y", "gap", "pressure", "active")
        if self.friction is not None:
            cols += ("t_tangential", "slip", "status")
        lines = [",".join(cols)]
        for row in zip(*(d[c] for c in cols)):
            lines.append(",".join(f"{v:.12g}" if isinstance(v, float) else str(v) for v in row))
        write_atomic(out / "interface" / f"{self.pair.name}_{step:04d}.csv", "\n".join(lines) + "\n")

    def plot(self, out: Path, steps: list[dict]) -> None:
        if self.state is None:
            return
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        d = self.interface()
        fig, ax = plt.subplots(figsize=(6, 3.5))
        order = np.argsort(d["x"])
        ax.plot(d["x"][order], d["pressure"][order], "o-", ms=3)
        on = d["pressure"] > 0
        if on.any():  # zoom on the contact zone
            lo, hi = d["x"][on].min(), d["x"][on].max()
            pad = max(0.5 * (hi - lo), 1e-12)
            ax.set_xlim(lo - pad, hi + pad)
        ax.set_xlabel("x (current configuration)")
        ax.set_ylabel("contact pressure")
        ax.set_title(f"{self.pair.name}: pressure at the last converged step")
        ax.grid(alpha=0.3)
        fig.tight_layout()
        (out / "interface").mkdir(parents=True, exist_ok=True)
        fig.savefig(out / "interface" / f"{self.pair.name}_pressure.png", dpi=120)
        plt.close(fig)


def build_contact(scene: Scene, dom, bulk, timings):
    """One hook per contact pair, and the matrix with their couplings preallocated."""
    V = bulk.V
    l2g = dx.local_to_global_dofs(V)
    hooks, blocks = [], []
    for c in scene.contacts:
        slave = build_surface(dom, c.slave, f"{c.name}:slave")
        master = build_surface(dom, c.master, f"{c.name}:master")
        _check_facing(scene.contacts.index(c), slave, master)
        E = _modulus(scene, dom, slave)
        _check_roles(c.name, slave, master, E, _modulus(scene, dom, master))
        hook = PairHook(c, slave, master, E, V, timings)
        hook._l2g = l2g
        blocks.extend(_coupling_blocks(hook))
        hooks.append(hook)
    with timings("contact"):
        A = assembly.create_matrix(bulk.jacobian, blocks, V)
    return hooks, A


def _check_facing(i: int, slave: Surface, master: Surface) -> None:
    """Some slave segment must face its nearest master segment (outward normals within 60°
    of opposite): a pair that never faces is a mistake in the scene, not a contact."""
    def mids_normals(s: Surface):
        a, b = s.X[s.seg[:, 0]], s.X[s.seg[:, 1]]
        t = (b - a) / np.linalg.norm(b - a, axis=1)[:, None]
        return 0.5 * (a + b), np.column_stack([-t[:, 1], t[:, 0]])
    ms, ns = mids_normals(slave)
    mm, nm = mids_normals(master)
    _, j = cKDTree(mm).query(ms)
    if not np.any(np.einsum("ij,ij->i", ns, nm[j]) < -0.5):
        raise SceneError(f"contacts[{i}]: the slave and master surfaces do not face each "
                         "other (their outward normals never oppose): check the group names")


def _modulus(scene: Scene, dom, surface: Surface) -> float:
    """Young's modulus of the body a surface belongs to."""
    tag = surface.body_tag
    return next(b.material.E for b in scene.bodies if dom.cell_groups[b.group] == tag)


def _mean_length(s: Surface) -> float:
    return float(np.mean(np.linalg.norm(s.X[s.seg[:, 1]] - s.X[s.seg[:, 0]], axis=1)))


def _check_roles(name: str, slave: Surface, master: Surface, E_s: float, E_m: float) -> None:
    """Warn when the slave is the stiffer body with the finer segments. The multipliers live
    on the slave nodes; the soft master must then meet more weighted-gap conditions than it
    has nodes in the contact zone, and the pressure dips or zig-zags (docs/stability.md,
    cases 1 and 5: a 60 % dip at the centre of a Hertz-like zone)."""
    h_s, h_m = _mean_length(slave), _mean_length(master)
    if E_s >= 2.0 * E_m and h_s < h_m:
        warnings.warn(f"contact {name}: the slave body is {E_s / E_m:.3g} x stiffer than the "
                      f"master's and its segments are finer ({h_s:.3g} < {h_m:.3g}): the "
                      "master cannot follow the slave's multipliers and the pressure may "
                      "oscillate; make the softer body the slave, or refine the master",
                      stacklevel=3)


def _coupling_blocks(hook: PairHook) -> list[np.ndarray]:
    """Per slave node: the node blocks its weighted gap can depend on (its neighbours and the
    stencils of the master candidates of its segments, found with a generous radius)."""
    s, m = hook.slave, hook.master
    ps, pm = candidate_pairs(s.X, s.seg, m.X, m.seg, 3.0 * hook.radius)
    curve = hook._curve
    stencil = curve.stencil(pm) if len(pm) else np.zeros((0, curve.stencil_size), dtype=np.int64)
    if curve.point_map is not None:  # points → the master nodes they are made of
        pm_csr = curve.point_map.tocsr()
        reach = [pm_csr.indices[pm_csr.indptr[i]:pm_csr.indptr[i + 1]] for i in range(pm_csr.shape[0])]
        stencil = [np.unique(np.concatenate([reach[i] for i in row])) for row in stencil]
    per_node: dict[int, set[int]] = {}
    for (a, b) in s.seg:
        for j in (a, b):
            per_node.setdefault(int(j), set()).update((int(a), int(b)))
    for k, seg_i in enumerate(ps):
        a, b = s.seg[seg_i]
        for j in (a, b):
            per_node[int(j)].update(int(i) + s.n for i in stencil[k])
    bs = 2
    node_block = np.concatenate([s.dofs[:, 0], m.dofs[:, 0]]) // bs
    out = []
    for nodes in per_node.values():
        out.append(np.unique(node_block[np.fromiter(nodes, dtype=np.int64)]))
    return out
