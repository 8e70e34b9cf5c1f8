"""Friction laws (docs/design.md §3, §5): a frictionless null object and Coulomb friction with a
moving friction cone. One class per law, registered under its scene name.

Per slave node j with its closest-point projection ξ̄_j on master segment s_j (current
configuration) and a reference point — a material point (segment r_j, ξ_j^ref) of the
master, carried between load steps:

    g_T,j = (x_j − x_m(r_j, ξ_j^ref)) · t̂(s_j, ξ̄_j)      (tangential slip since the
                                                             reference, along the master)
    trial  t*_j = ε_T g_T,j ;   Φ_j = |t*_j| − μ p_j
    stick (Φ ≤ 0): t_j = t*_j ;   slip (Φ > 0): t_j = μ p_j sign(t*_j)

(p_j ≥ 0 the normal contact pressure). The tangential nodal forces are the variation of
Σ_j W_j t_j g_T,j at fixed t (W_j the load area of node j's pressure, :func:`load_areas`),
R_T = Σ_j W_j t_j ∇g_T,j, with the consistent, unsymmetric tangent through ∇g_T, ∇²g_T,
∇W and (slip) ∇p, ∇p from the enforcement's own ∂p/∂g̃, ∂p/∂A.

Where the enforcement carries a tangential multiplier (λ_t with Lagrange multipliers, the
Uzawa t̂ with ``alm-stick``) the trial is that multiplier + ε_T g_T with g_T the slip of
the step (every node re-anchored at the step's end), and stick is exact; a node that
closes during the step has a penalty-regularized stick in that step (:meth:`Coulomb.update`).

Moving cone (penalty, ``alm``): after a converged step, a sticking node keeps its reference
point; a slipping node's reference moves to the point that leaves exactly the elastic part
t_j/ε_T of the slip, x_ref = x_m(ξ̄_j) − (t_j/ε_T) t̂; a node out of contact re-anchors at
its current projection, so a node that lifts off and comes back starts from rest.

A new law with the same kinematics is a subclass of :class:`Coulomb` with its own
:meth:`~Coulomb.traction` (the return map), registered under its name.
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np
import scipy.sparse as sp

from . import ad, assembly
from .ad import Jet2
from .kernel import NodalContributions, nodal_sum
from .projection import closest_segments
from .registry import FRICTION_LAWS

#: node status; CLOSING: closed during the step, not slipping: penalty stick (update)
STICK, SLIP, INACTIVE, CLOSING = 1, 2, 0, 3


def slip_contributions(xs: np.ndarray, xm: np.ndarray, curve, nodes: np.ndarray,
                       cur_seg: np.ndarray, ref_seg: np.ndarray, ref_xi: np.ndarray
                       ) -> NodalContributions:
    """g_T,j with exact gradient and Hessian over [x_j, current stencil, reference stencil]
    (S = 1 slave node, 2L curve points), for the given slave ``nodes``."""
    K = len(nodes)
    L = curve.stencil_size
    if K == 0:
        return NodalContributions.empty(1, 2 * L)
    Pc = curve.local_points(cur_seg, xm)
    Pr = curve.local_points(ref_seg, xm)
    X = np.concatenate([xs[nodes], Pc.reshape(K, 2 * L), Pr.reshape(K, 2 * L)], axis=1)
    v = Jet2.variables(X)
    xj = (v[0], v[1])
    P_cur = [(v[2 + 2 * i], v[3 + 2 * i]) for i in range(L)]
    P_ref = [(v[2 + 2 * L + 2 * i], v[3 + 2 * L + 2 * i]) for i in range(L)]
    xi = curve.project(cur_seg, xj, P_cur)
    _, a = curve.evaluate(cur_seg, xi, P_cur)
    x_ref, _ = curve.evaluate(ref_seg, ref_xi, P_ref)
    gT = ad.dot(ad.sub(xj, x_ref), slip_direction(curve, cur_seg, xi, P_cur, a))
    masters = np.concatenate([curve.stencil(cur_seg), curve.stencil(ref_seg)], axis=1)
    return NodalContributions(nodes, nodes[:, None], masters, gT.val, gT.grad, gT.hess)


def slip_direction(curve, seg, xi, P, a):
    """Unit direction t̂ along which the slip is measured at ξ̄ on segment ``seg``.

    On the faceted curves (polyline, averaged normals) the segment tangent a jumps at every
    master node, and with it the direction of a slipping node's friction force μ p A t̂: a
    slave node sliding across a master node sees its nodal force turn by the kink angle at
    once. When the equilibrium of a load step puts the node on the kink, neither side has a
    solution (ironing B4: Newton stalls at |R| ≈ 1.75 ≈ μ p A × kink angle, and every cut
    step that ends inside that window fails). There t̂ is the linear interpolation of the
    unit averaged nodal tangents t̄_c, t̄_d (eq. 3.4; the directions the mortar
    segmentation uses), continuous across master nodes; on the smooth curves (Hermite,
    B-spline) a is continuous already and t̂ = a/|a|."""
    if not curve.c1_gap:
        tc, td = curve.node_tangents(seg, P)
        tc, td = ad.unit(tc), ad.unit(td)
        return ad.unit(ad.add(tc, ad.scale(ad.sub(td, tc), xi)))
    return ad.unit(a)


def load_areas(st, surface) -> tuple[np.ndarray, object]:
    """W_j = ∫ψ_j dΓ over the part of node j's support that sees the master (ψ_j the
    weight of its pressure: its normal force is p_j W_j) and a callable for the rows ∇W_j.
    W = A but for the dual basis where a segment is only partly supported: there the
    friction force weighted by A_j made T ≠ μN at the master's end with every node slipping
    (B3: 0.297–0.303). Where W_j ≤ 0 (a weak node no neighbour took) A_j stands in: a
    friction force against the slip would push."""
    area = st.area
    if area.psi is None:     # standard basis (or no contribution on this rank): W = A
        W, contrib = surface.owned_sum(nodal_sum(area, surface.n)), area
    else:
        # the dual basis' ψ are fixed combinations of the hats on a segment (node-a and
        # node-b rows in halves), their gradients the same combinations
        K = area.size // 2
        g = area.grad.reshape(2, K, -1)
        contrib = NodalContributions(area.node, area.slave_nodes, area.master_nodes,
                                     area.psi, np.concatenate([2 * g[0] - g[1], 2 * g[1] - g[0]]),
                                     None, area.tail_nodes)
        W = surface.owned_sum(nodal_sum(contrib, surface.n))
    ok = (W > 0) | (st.A <= 0)
    if not ok.all():
        W = np.where(ok, W, st.A)

    def rows() -> sp.csr_matrix:
        G = assembly.gradient_matrix(contrib, st.n_slave, st.n_coords, st.layouts)
        if contrib is area:
            return G
        return sp.csr_matrix(sp.diags(ok * 1.0) @ G + sp.diags(~ok * 1.0) @ st.G_area)
    return W, rows


class TangentialState(NamedTuple):
    """The friction part of a :class:`~.state.ContactState`."""

    slip: NodalContributions   # g_T,j per slave node in contact range, with derivatives
    gT: np.ndarray             # (n_slave,) nodal slips
    t: np.ndarray              # (n_slave,) tangential tractions
    status: np.ndarray         # (n_slave,) STICK / SLIP / INACTIVE
    dt_dg: np.ndarray          # ∂t/∂g_T
    dt_dp: np.ndarray          # ∂t/∂p
    proj: tuple                # (nodes, segments, ξ̄, |a|) of the slave nodes' projections
    dt_dtrial: np.ndarray      # ∂t/∂(trial traction): ∂t/∂λ_t with multipliers
    #: W_j, the load area of node j's pressure (∫ψ_j over the supported part: its normal
    #: force is p_j W_j), which weighs its tangential force W_j t_j; and a callable giving
    #: the rows ∇W_j over the kernels' coordinates
    load: np.ndarray | None = None
    load_rows: object = None
    #: |t − T(t + ε_T g_T)| per node (T the return map, ε_T the law's fixed one), beyond
    #: round-off: zero iff the law holds (stick: no slip; slip: on the cone, along the
    #: slip). None where the traction is not augmented (penalty: the moving cone)
    kkt: np.ndarray | None = None


@FRICTION_LAWS.register("none")
class Frictionless:
    """No tangential traction: contributes nothing, keeps no history."""

    path_dependent = False

    def __init__(self, mu: float = 0.0, epsilon_t: float = 0.0, n_slave: int = 0):
        self.mu = float(mu)

    def update(self, st, surface) -> None:
        """Tangential kinematics and tractions of the iterate (sets ``st.tangential``)."""

    def residual(self, st, weight: np.ndarray):
        return None

    def tangent(self, st, weight: np.ndarray):
        return None

    def decision(self, st) -> np.ndarray | int:
        """This law's part of the per-node decision that the cycling monitor watches."""
        return 0

    def interface(self, st) -> dict[str, np.ndarray]:
        return {}

    def record(self, st, force_on_slave) -> dict:
        return {}

    def begin_step(self) -> None:
        pass

    def accept(self, st) -> None:
        pass

    def reject(self) -> None:
        pass

    def state_dict(self) -> dict[str, np.ndarray]:
        return {}

    def load_state_dict(self, d: dict[str, np.ndarray]) -> None:
        pass


@FRICTION_LAWS.register("coulomb")
class Coulomb(Frictionless):
    """Coulomb's law with the return map of the module docstring; history: each slave
    node's reference point (segment, ξ) on the master."""

    path_dependent = True

    def __init__(self, mu: float, epsilon_t: float, n_slave: int):
        self.mu, self.epsilon_t = float(mu), float(epsilon_t)
        self.ref_seg = np.full(n_slave, -1, dtype=np.int64)
        self.ref_xi = np.zeros(n_slave)
        self._committed = (self.ref_seg.copy(), self.ref_xi.copy())
        self._segment = np.full(n_slave, -1, dtype=np.int64)  # last projection segment
        self._status = np.full(n_slave, INACTIVE)   # each node's status at the last step
        self._g0 = np.zeros(n_slave)                 # g_T at the anchor (multipliers)
        self._open: np.ndarray | None = None         # out of contact at the step's start

    # -- kinematics ---------------------------------------------------------------------
    def update(self, st, surface) -> None:
        """Projections of the slave nodes, slips since their reference points, return map."""
        xs, xm, curve = st.xs, st.xm, st.curve
        ps, pm = st.pairs
        n_ms = max(len(curve.seg), 1)
        key = np.unique(np.concatenate([surface.seg[ps, 0], surface.seg[ps, 1]]) * n_ms
                        + np.concatenate([pm, pm]))
        nodes, segs = closest_segments(xs, xm, key // n_ms, key % n_ms, curve, self._segment)
        self._segment[:] = -1
        self._segment[nodes] = segs
        P = curve.split_points(curve.local_points(segs, xm))
        xi = np.asarray(curve.project(segs, (xs[nodes, 0], xs[nodes, 1]), P), dtype=float)
        self.anchor_missing(nodes, segs, xi)
        slip = slip_contributions(xs, xm, curve, nodes, segs, self.ref_seg[nodes],
                                  self.ref_xi[nodes])
        gT = surface.owned_sum(nodal_sum(slip, surface.n))
        self._surface = surface
        eps = self.epsilon_t if st.epsilon_t is None else st.epsilon_t
        # a trial traction within round-off of the cone's tip is no slip (traction)
        self.resolution = eps * st.gap_resolution
        hat = st.traction_multiplier
        if hat is not None:
            # λ_t (or the Uzawa t̂) carries the traction; g_T is the slip since the last
            # step's end (from where the anchoring left it: see accept)
            gT = gT - self._g0
        first = self._open is None   # the first iterate of the step: its start
        if first:
            self._open = ~st.active
        trial = eps * gT if hat is None else hat + eps * gT
        t, status, dt_dtrial, dt_dp = self.traction(trial, st.p, st.active)
        if first and not st.active.any():
            # with no node in contact at the step's start, nodes that nearly touch stick at
            # its first iterate (t = trial, zero there), as they get the normal stiffness in
            # its Jacobian (enforcement.Enforcement.tangent): an exactly touching start on a
            # curved master may have no node within round-off of closed (g̃/A = h²/3R with
            # the standard basis), and then nothing held a body along x that friction alone
            # holds: the first Newton step moved it sideways, every node then slipped as it
            # closed, and the body was thrown out of contact (CM at a/40, 'alm-stick'). (With
            # nodes in contact it cost iterations: B3 with a finer master 4 → 5-7 a step)
            held = (st.A > 0) & (st.g <= 0.01 * st.A**2)
            t = np.where(held, trial, t)
            dt_dtrial = np.where(held, 1.0, dt_dtrial)
            status = np.where(held, STICK, status)
        if hat is not None:
            t, status, dt_dtrial, dt_dp = self._on_the_cone(trial, st.p, t, status,
                                                            dt_dtrial, dt_dp)
        if st.held_status is not None:
            # the Uzawa update t̂ ← t doubles a sticking node's trial at the next solve's
            # first iterate (its elastic slip is still there): taken for a slip there, a
            # stick zone near the cone slid away whole (Cattaneo-Mindlin at Q = 0.9 mu P
            # ended in a sliding state). The status it converged to decides that iterate
            held = (st.held_status == STICK) & (status == SLIP)
            t = np.where(held, trial, t)
            dt_dtrial = np.where(held, 1.0, dt_dtrial)
            dt_dp = np.where(held, 0.0, dt_dp)
            status = np.where(held, STICK, status)
        dt_dg = eps * dt_dtrial
        # a node that closes during the step was anchored at the step's start, its gap
        # open: the relative motion of its approach is no slip (on a curved master its
        # closest point also drifts as the gap shrinks). Held by exact stick to that anchor
        # (multipliers, Uzawa) it kept a tangential traction of up to 0.25 mu p0 after a
        # press where the continuum has none. In its closing step its stick is
        # penalty-regularized (t = ε_T g_T, the law's ε_T, no multiplier: the approach
        # becomes elastic slip); from the next step it sticks exactly to where it closed
        # (accept re-anchors it). A node that slides into contact slips as before. (The
        # penalty law's stick is regularized anyway.)
        closing = self._open & st.active & (hat is not None)
        if closing.any():
            tc, sc, dc, pc = self.traction(self.epsilon_t * gT, st.p, st.active)
            t = np.where(closing, tc, t)
            status = np.where(closing & (sc == STICK), CLOSING, np.where(closing, sc, status))
            dt_dg = np.where(closing, self.epsilon_t * dc, dt_dg)
            dt_dtrial = np.where(closing, 0.0, dt_dtrial)
            dt_dp = np.where(closing, pc, dt_dp)
        kkt = None
        if hat is not None:
            e0 = self.epsilon_t
            kkt = np.abs(t - self.traction(t + e0 * gT, st.p, st.active)[0])
            # round-off and the Newton tolerance as for the normal part (a slip's force is
            # A ε_T g_T where the gap's is ε g̃: the same noise, ε_T = ε)
            kkt = np.where(closing, 0.0, np.maximum(
                kkt - e0 * (st.gap_resolution + st.gap_noise), 0.0))
        _, a = curve.evaluate(segs, xi, P)
        W, rows = load_areas(st, surface)
        st.tangential = TangentialState(slip, gT, t, status, dt_dg,
                                        dt_dp, (nodes, segs, xi, np.hypot(*a)), dt_dtrial,
                                        W, rows, kkt)

    def anchor_missing(self, nodes: np.ndarray, seg: np.ndarray, xi: np.ndarray) -> None:
        """Nodes without a reference (first contact) take their current projection."""
        new = self.ref_seg[nodes] < 0
        self.ref_seg[nodes[new]] = seg[new]
        self.ref_xi[nodes[new]] = xi[new]

    def traction(self, trial: np.ndarray, p: np.ndarray, active: np.ndarray):
        """The return map of the trial traction (ε_T g_T, plus λ_t with multipliers):
        (t, status, ∂t/∂trial, ∂t/∂p) per node."""
        # Φ ≤ 0 sticks, so a node at rest (g_T = 0, p = 0: the first iterate of a body held
        # only by contact) gets the tangential stiffness instead of none; so does a node
        # whose p and trial are zero to round-off (an exactly touching start: p = −7e-18
        # and a round-off slip made it slip without stiffness, the Newton matrix singular
        # along the slip, and the body was thrown out of contact)
        # a node the moving cone left exactly on the cone (every slipping node at the start
        # of a step) sticks: deciding that tie by round-off made the first Newton direction
        # (and the iteration count) differ between serial and MPI runs
        # with mu = 0 there is no cone to stick in: every active node slips with t = 0
        r = self.mu * np.maximum(p, 0.0)
        noise = getattr(self, "resolution", 0.0)
        slip = active & ((np.abs(trial) - r > 1e-9 * r + noise) | (self.mu == 0.0))
        stick = active & ~slip
        sign = np.sign(trial)
        t = np.where(stick, trial, np.where(slip, r * sign, 0.0))
        dt_dtrial = np.where(stick, 1.0, 0.0)
        dt_dp = np.where(slip & (p > 0), self.mu * sign, 0.0)
        status = np.where(stick, STICK, np.where(slip, SLIP, INACTIVE))
        return t, status, dt_dtrial, dt_dp

    def _on_the_cone(self, trial, p, t, status, dt_dtrial, dt_dp):
        """A node exactly on the cone (to 1e-9 μp) keeps the status it converged to in the
        last step. With multipliers every node that slipped starts the next step there
        (λ_t = μ p, no slip yet): taking it for sticking makes the first Newton step hold
        the whole increment as elastic drag; the history, not round-off, decides."""
        tie = (status != INACTIVE) & (np.abs(np.abs(trial) - self.mu * p) <= 1e-9 * self.mu * p)
        keep = tie & (self._status == SLIP) & (status == STICK)
        if keep.any():
            sign = np.sign(trial)
            t = np.where(keep, self.mu * p * sign, t)
            dt_dtrial = np.where(keep, 0.0, dt_dtrial)
            dt_dp = np.where(keep, self.mu * sign, dt_dp)
            status = np.where(keep, SLIP, status)
        return t, status, dt_dtrial, dt_dp

    # -- contributions --------------------------------------------------------------------
    def _terms(self, st, weight: np.ndarray, tangent: bool):
        ts = st.tangential
        return assembly.friction_terms(st, ts.slip, ts.t, ts.dt_dg, ts.dt_dp, weight, tangent)

    def residual(self, st, weight: np.ndarray) -> np.ndarray:
        return st.to_nodes(self._terms(st, weight, tangent=False)[0])

    def tangent(self, st, weight: np.ndarray) -> sp.spmatrix:
        K = st.to_nodes(K=self._terms(st, weight, tangent=True)[1])
        if st.multipliers is None:
            return K
        # with multipliers (docs/design.md §5a): C_t = s (λ_t − t), t(λ_t + ε_T g_T, p(λ_n))
        ts, n = st.tangential, st.n_slave
        act = st.active * weight
        A = ts.load
        GT = sp.csr_matrix(st.to_nodes(K=assembly.gradient_matrix(
            ts.slip, n, st.n_coords, st.layouts), rows_in_nodes=True))       # (n, n_test)
        Gp = assembly.pressure_rows(st, st.law.dp_dg * act, st.law.dp_dA * act)
        s = st.multiplier_scale * weight
        K_ul = sp.hstack([GT.T @ sp.diags(A * ts.dt_dp * act),          # λ_n columns
                          GT.T @ sp.diags(A * ts.dt_dtrial * weight)])  # λ_t columns
        even, odd = 2 * np.arange(n), 2 * np.arange(n) + 1
        order = np.argsort(np.concatenate([even, odd]))
        K_ul = sp.csr_matrix(K_ul)[:, order]
        K_tu = -(sp.diags(s * ts.dt_dg) @ GT + sp.diags(s * ts.dt_dp) @ Gp)   # λ_t rows
        E_t = sp.csr_matrix((np.ones(n), (odd, np.arange(n))), shape=(2 * n, n))
        K_ll = sp.csr_matrix((np.concatenate([-s * ts.dt_dp * st.active, -s * ts.dt_dtrial]),
                              (np.concatenate([odd, odd]), np.concatenate([even, odd]))),
                             shape=(2 * n, 2 * n))
        return sp.bmat([[K, K_ul], [E_t @ K_tu, K_ll]], format="coo")

    def decision(self, st) -> np.ndarray:
        ts = st.tangential
        return 2 * ts.status.astype(np.int8) + 8 * (ts.t < 0)

    # -- outputs ------------------------------------------------------------------------
    def interface(self, st) -> dict[str, np.ndarray]:
        ts = st.tangential
        # a node closing in the step sticks (penalty-regularized): reported as sticking
        names = {STICK: "stick", SLIP: "slip", INACTIVE: "inactive", CLOSING: "stick"}
        return dict(t_tangential=ts.t, slip=ts.gT,
                    status=np.array([names[int(k)] for k in ts.status]))

    def record(self, st, tangential_on_slave) -> dict:
        ts = st.tangential
        return {"tangential_force_on_slave": [float(-tangential_on_slave[0]),
                                              float(-tangential_on_slave[1])],
                "tangential_force": float(np.sum(ts.t * ts.load)),
                "stick_nodes": int(np.sum((ts.status == STICK) | (ts.status == CLOSING))),
                "slip_nodes": int(np.sum(ts.status == SLIP))}

    # -- history --------------------------------------------------------------------------
    def accept(self, st) -> None:
        """Moving cone after a converged step (see module docstring); with multipliers
        (the traction is λ_t) every node re-anchors at its projection: g_T is the slip of
        the step."""
        ts = st.tangential
        nodes, segs, xi, length = ts.proj
        if st.traction_multiplier is not None:
            self.ref_seg[nodes], self.ref_xi[nodes] = segs, xi
            self._committed = (self.ref_seg.copy(), self.ref_xi.copy())
            self._status = ts.status.copy()
            # g_T measured from the new anchor is not exactly 0 where the slip direction is
            # not the segment's tangent (faceted curves, slip_direction): remember it, so
            # that the next step starts at g_T = 0 and a node on the cone stays on it
            P = st.curve.split_points(st.curve.local_points(segs, st.xm))
            x_ref, a = st.curve.evaluate(segs, xi, P)
            t_hat = slip_direction(st.curve, segs, xi, P, a)
            g0 = np.zeros(st.n_slave)
            g0[nodes] = ((st.xs[nodes, 0] - x_ref[0]) * t_hat[0]
                         + (st.xs[nodes, 1] - x_ref[1]) * t_hat[1])
            self._g0 = self._surface.owned_sum(g0)
            return
        t, status = ts.t[nodes], ts.status[nodes]
        ref_seg, ref_xi = self.ref_seg.copy(), self.ref_xi.copy()
        # a node that closed in the step keeps only its elastic slip t/ε_T, as a slipping
        # one: its anchor moves to where it closed (_step_start)
        slipping = status == SLIP
        off = status == INACTIVE
        n = nodes[slipping | off]
        ref_seg[n] = segs[slipping | off]
        # |a| of the current segment turns the elastic slip t/ε_T into a parameter offset
        ref_xi[n] = xi[slipping | off] - np.where(
            slipping, t / (self.epsilon_t * length), 0.0)[slipping | off]
        self.ref_seg, self.ref_xi = ref_seg, ref_xi
        self._committed = (ref_seg.copy(), ref_xi.copy())

    def begin_step(self) -> None:
        self._open = None   # taken from the step's first iterate: its start

    def reject(self) -> None:
        self.ref_seg, self.ref_xi = (a.copy() for a in self._committed)

    def state_dict(self) -> dict[str, np.ndarray]:
        return {"ref_seg": self.ref_seg, "ref_xi": self.ref_xi, "g0": self._g0,
                "status": self._status}

    def load_state_dict(self, d: dict[str, np.ndarray]) -> None:
        self.ref_seg = np.array(d["ref_seg"], dtype=np.int64)
        self.ref_xi = np.array(d["ref_xi"], dtype=float)
        # (checkpoints before these were kept start the step from g_T = 0 and no status)
        self._g0 = np.array(d.get("g0", np.zeros_like(self.ref_xi)), dtype=float)
        self._status = np.array(d.get("status", np.full(self.ref_seg.shape, INACTIVE)),
                                dtype=self._status.dtype)
        # the loaded history becomes the committed one (reject() restores from it)
        self._committed = (self.ref_seg.copy(), self.ref_xi.copy())
        self.reject()
