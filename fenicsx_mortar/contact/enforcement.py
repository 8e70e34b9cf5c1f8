"""Normal-contact enforcement on nodal weighted gaps (docs/design.md §5). One class per method.

An enforcement turns the nodal weighted gaps g̃_j and areas A_j of a pair (A_j > 0 only
where the node's support sees the master) into contact pressures p_j, and contributes the
contact residual and tangent. The built-in methods are nodal laws

    p_j = ⟨p̂_j − ε g̃_j / A_j⟩₊ ,

p̂ = 0 for penalty, the Uzawa multiplier for the augmented Lagrangian; for them the generic
terms of :mod:`.assembly` apply, R = −Σ_j p_j ∇g̃_j with the tangent through ∂p/∂g̃, ∂p/∂A
(:class:`NodalPressure`). A node is active when its trial pressure p̂_j − ε g̃_j/A_j is
≥ 0: a closed gap (g̃ = 0) counts as active, so a body held only by contact is not singular
in the first iteration — and so does a gap within round-off of closed (|g̃/A| below the
pair's ``gap_resolution``, 32 ulp of the coordinates): on a curved master a touching node's
gap is ±1e-17, and its sign must not decide (B-spline patch test: an active set by the
noise's sign took one Newton iteration more, and which one depended on the BLAS library).
A method with other unknowns (Lagrange multipliers) overrides
:meth:`Enforcement.residual` and :meth:`Enforcement.tangent`.

A new enforcement is one subclass registered under its scene name::

    @ENFORCEMENTS.register("my-law")
    class MyLaw(Enforcement):
        def pressure(self, g, A): ...   # → NodalPressure
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np
import scipy.sparse as sp

from . import assembly
from .registry import ENFORCEMENTS


class NodalPressure(NamedTuple):
    """p_j per slave node, the active mask, and ∂p_j/∂g̃_j, ∂p_j/∂A_j at every node that
    sees the master (the tangent uses them on the active nodes, and at the first iterate of
    a step on the touching ones too: :meth:`Enforcement.tangent`)."""

    p: np.ndarray
    active: np.ndarray
    dp_dg: np.ndarray
    dp_dA: np.ndarray


class Enforcement:
    """Base: ε per node (a start value per load step), the multiplier history p̂, the
    Alart–Curnier KKT residual, and the generic nodal-law residual and tangent."""

    name = ""

    def __init__(self, epsilon: float, n_nodes: int, tolerance: float,
                 gap_resolution: float = 0.0, start: float | None = None):
        self.epsilon0 = float(epsilon)
        #: ε at the start of every load step: min(ε, ``start``) (the pair passes E/h)
        self.start = self.epsilon0 if start is None else min(float(start), self.epsilon0)
        #: the smallest average gap g̃/A that round-off in the coordinates can resolve
        self.gap_resolution = float(gap_resolution)
        self.epsilon = np.full(n_nodes, self.start)  # per node (ALM may raise some)
        self.tolerance = tolerance
        #: the Newton solve's residual tolerance (a force; set by the problem): a node's
        #: force is known to it, its average gap to it over its stiffness ε_j A_j
        self.force_resolution = 0.0
        self.multiplier = np.zeros(n_nodes)      # p̂ (zero for penalty)
        self._converged_multiplier = self.multiplier.copy()

    # -- the nodal law --------------------------------------------------------------
    def trial(self, g: np.ndarray, A: np.ndarray) -> np.ndarray:
        """p̂ − ε g̃/A where the node sees the master, −inf elsewhere."""
        out = np.full(g.shape, -np.inf)
        seen = A > 0
        out[seen] = self.multiplier[seen] - self.epsilon[seen] * g[seen] / A[seen]
        return out

    def pressure(self, g: np.ndarray, A: np.ndarray) -> NodalPressure:
        t = self.trial(g, A)
        # a gap within round-off of closed is closed: the sign of noise must not decide
        active = t >= -self.epsilon * self.gap_resolution
        As = np.where(A > 0, A, 1.0)
        eps = self.epsilon
        return NodalPressure(np.where(active, t, 0.0), active, -(eps / As), eps * g / As**2)

    def complementarity(self, g: np.ndarray, A: np.ndarray, p: np.ndarray,
                        noise: np.ndarray | float = 0.0) -> np.ndarray:
        """|p_j − ⟨p_j − ε₀ g̃_j/A_j⟩₊| / max(p) per node (0 where the node sees no master):
        the Alart–Curnier function, relative to the pressure scale; zero iff g ≥ 0, p ≥ 0
        and p g = 0. Measured with the fixed ε₀, so raising ε does not hide a gap. A gap
        within ``gap_resolution`` (round-off of the coordinates) counts as closed: no update
        can close it further (seen: NTS on the patch test stalled at |g̃/A| = 2e-16 × 3 with
        a KKT residual of 3e-10 at the first load increment, where p is small); so does one
        within ``noise`` (:meth:`gap_noise`) where given."""
        seen = A > 0
        c = np.zeros_like(g)
        c[seen] = np.abs(p[seen] - np.maximum(p[seen] - self.epsilon0 * g[seen] / A[seen], 0.0))
        c = np.maximum(c - self.epsilon0 * (self.gap_resolution + noise), 0.0)
        return c / p.max() if p.max(initial=0.0) > 0 else c

    def gap_noise(self, A: np.ndarray, epsilon: np.ndarray | None = None
                  ) -> np.ndarray | float:
        """Per node, how far Newton's answer may put the average gap g̃_j/A_j off for its
        residual tolerance: force_resolution/(ε_j A_j) (0 where A_j = 0; ``epsilon``: the
        stiffness that turns the gap into force, default the normal ε). The KKT test asks
        no more (the finer Cattaneo-Mindlin ALM stagnated at 1.02e-10 over a tolerance of
        1e-10, the gaps set by the Newton tolerance, not by the augmentations). Applied
        with friction only: frictionless runs stay as they were (the frictionless c06a
        would stop one augmentation earlier, 7 instead of 8)."""
        if not self.force_resolution:
            return 0.0
        eps = self.epsilon if epsilon is None else epsilon
        seen = A > 0
        return np.where(seen, self.force_resolution / (eps * np.where(seen, A, 1.0)), 0.0)

    def kkt_residual(self, g: np.ndarray, A: np.ndarray, p: np.ndarray,
                     tangential=None) -> float:
        """The largest complementarity (:meth:`complementarity`) over the nodes.

        Args:
            g, A, p: the nodal weighted gaps, areas and pressures.
            tangential: the friction's :class:`~.friction.TangentialState`, or None; its
                ``kkt`` enters where this method augments the traction (ALM).

        Returns:
            max_j c_j, relative to the pressure scale.
        """
        return float(self.complementarity(g, A, p).max(initial=0.0))

    def annotate(self, st) -> None:
        """Tell the friction law of the state ``st`` how the tangential traction is enforced
        (``st.traction_multiplier``, ``st.epsilon_t``): here not at all, a penalty-regularized
        stick (the moving cone of :mod:`.friction`)."""
        st.gap_resolution = self.gap_resolution
        st.gap_noise = self.gap_noise(st.A)

    # -- contributions to the system --------------------------------------------------
    def residual(self, st, weight: np.ndarray) -> np.ndarray:
        """−Σ_j w_j p_j ∇g̃_j (or −Σ_j w_j p_j T_j with Petrov–Galerkin test vectors) over
        the pair's stacked coordinates."""
        return assembly.normal_force(st, st.p * weight)

    def tangent(self, st, weight: np.ndarray, first: bool) -> sp.spmatrix:
        """∂(residual)/∂x. At the first iterate of a load step the nodes whose average gap is
        closed to within 1 % of their support length also get the penalty stiffness: a body
        held only by contact then has a non-singular tangent even where a curved surface
        touches a flat one at a single point (its nodes' weighted gaps are small but
        positive)."""
        law = st.law
        on = law.active
        if first:
            on = on | ((st.A > 0) & (st.g <= 0.01 * st.A**2))
        act = on * weight
        return assembly.normal_tangent(st, -law.dp_dg * act, law.dp_dA * act, law.p * weight)

    # -- between Newton solves and steps ----------------------------------------------
    def update_due(self, g: np.ndarray, A: np.ndarray, p: np.ndarray, tangential,
                   fnorm: float, first: float) -> bool:
        """Within a Newton solve, at an iterate with residual norm ``fnorm`` (``first`` at
        the solve's start): True to stop the solve there and :meth:`augment` (an inexact
        Uzawa step). Never here: a method without multiplier updates needs the converged
        solve."""
        return False

    def augment(self, g: np.ndarray, A: np.ndarray, p: np.ndarray, tangential=None) -> bool:
        """Between converged Newton solves; True when another solve is needed.

        Args:
            g, A, p: the nodal weighted gaps, areas and pressures of the converged solve.
            tangential: the friction's :class:`~.friction.TangentialState`, or None.

        Returns:
            Whether to solve again (the multipliers or ε changed).
        """
        return False

    def begin_step(self) -> None:
        """Before the first Newton solve of a load step (or of its retry)."""
        self.epsilon[:] = self.start

    def accept(self) -> None:
        self._converged_multiplier = self.multiplier.copy()

    def reject(self) -> None:
        self.multiplier = self._converged_multiplier.copy()

    def state_dict(self) -> dict[str, np.ndarray]:
        return {"multiplier": self.multiplier.copy()}

    def load_state_dict(self, d: dict[str, np.ndarray]) -> None:
        self.multiplier = np.array(d["multiplier"], dtype=float)
        self.accept()


@ENFORCEMENTS.register("penalty")
class Penalty(Enforcement):
    """p_j = ε ⟨−g̃_j/A_j⟩₊ : the answer depends on ε (penetration ~ p/ε).

    Continuation for a stiff ε: each load step is solved first with ε_start = min(ε,
    ``start``), then again with ε raised ×10 per converged solve until it is ε. Only the
    last solve defines the answer; the others give it a start next to it. From a touching
    state a penalty far stiffer than the bodies makes the active set jump between Newton
    iterates (Hertz at a/4 with 100 E/h: 25 iterations, then every cut down to the floor,
    failed; with continuation 3 solves)."""
    growth = 10.0

    def augment(self, g: np.ndarray, A: np.ndarray, p: np.ndarray, tangential=None) -> bool:
        if self.epsilon[0] >= self.epsilon0:
            return False
        self.epsilon[:] = min(self.epsilon[0] * self.growth, self.epsilon0)
        return True


@ENFORCEMENTS.register("lagrange")
class LagrangeMultipliers(Enforcement):
    """The nodal pressures as unknowns λ_j of the Newton system, solved with the
    displacements by a semi-smooth (generalized) Newton method on the Alart–Curnier
    complementarity function (docs/design.md §5a):

        R_u = R_bulk − Σ_j p_j ∇g̃_j,            p_j = ⟨λ_j − ε g̃_j/A_j⟩₊
        C_j = s_j (λ_j − p_j) = 0               (s_j: node j's slave support length)

    C_j = 0 is g̃_j ≥ 0, λ_j ≥ 0, λ_j g̃_j = 0: on the active nodes (λ_j − ε g̃_j/A_j > 0)
    it is s_j ε g̃_j/A_j = 0, elsewhere s_j λ_j = 0. The solution does not depend on ε: it
    only decides which nodes the next iterate treats as active, re-decided at every
    iterate (the active set lives in the SNES callbacks; no Uzawa loop, no continuation).
    The rows are scaled by s_j to force units, like the displacement rows, so that one
    residual norm measures both. The u-rows are the augmented-Lagrangian law of
    :class:`AugmentedLagrangian` with p̂ = λ (its tangent through ∂p/∂g̃, ∂p/∂A), so the
    active nodes keep an ε-stiffness there and a body held only by contact is not singular.

    Unknowns: two per slave node, (λ_n, λ_t) — the tangential one is Coulomb friction's
    (:class:`~.friction.Coulomb`), s_j λ_t = 0 without friction — one 2×2 block per node,
    owned by the rank that owns the node (:class:`fenicsx_mortar.system.MultiplierSystem`).
    """
    unknowns = 2

    def __init__(self, epsilon: float, n_nodes: int, tolerance: float,
                 gap_resolution: float = 0.0, start: float | None = None):
        self.lam = np.zeros((n_nodes, 2))
        # ε only steers the active set: no continuation from a softer start
        super().__init__(epsilon, n_nodes, tolerance, gap_resolution)
        self._converged_lam = self.lam.copy()
        #: s_j, the rows' scale (set by the pair: each node's support length)
        self.scale = np.ones(n_nodes)

    @property
    def multiplier(self) -> np.ndarray:
        return self.lam[:, 0]

    @multiplier.setter
    def multiplier(self, value) -> None:
        self.lam[:, 0] = value

    def annotate(self, st) -> None:
        super().annotate(st)
        st.multipliers, st.multiplier_scale = self.lam, self.scale
        st.traction_multiplier = self.lam[:, 1]

    def accept(self) -> None:
        self._converged_lam = self.lam.copy()

    def reject(self) -> None:
        self.lam = self._converged_lam.copy()

    def state_dict(self) -> dict[str, np.ndarray]:
        return {"multiplier": self.lam.copy()}

    def load_state_dict(self, d: dict[str, np.ndarray]) -> None:
        self.lam = np.array(d["multiplier"], dtype=float).reshape(-1, 2)
        self.accept()

    # -- the multiplier rows ----------------------------------------------------------
    def multiplier_residual(self, st, weight: np.ndarray) -> np.ndarray:
        """(n, 2): C_n = s (λ_n − p) and C_t = s (λ_t − t) (t = 0 without friction), times
        the 0/1 ``weight`` of the nodes this rank owns."""
        t = st.tangential.t if st.tangential is not None else 0.0
        out = np.empty_like(self.lam)
        out[:, 0] = self.scale * (self.lam[:, 0] - st.p)
        out[:, 1] = self.scale * (self.lam[:, 1] - t)
        return out * weight[:, None]

    def tangent(self, st, weight: np.ndarray, first: bool) -> sp.spmatrix:
        """Over the pair's local unknowns [node coordinates (n_test), λ (2 n)]:

            ∂R_u/∂u  the nodal-law tangent (base class), ∂R_u/∂λ_n,j = −a_j T_j,
            ∂C_n,j/∂u = −s_j a_j ∇p_j,   ∂C_n,j/∂λ_n,j = s_j (1 − a_j),
            ∂C_t,j/∂λ_t,j = s_j           (the friction law adds its own terms)

        with a_j = 1 on the active nodes (∂p_j/∂λ_j), 0 elsewhere, T_j = ∇g̃_j (or the
        Petrov–Galerkin test vector) and ∇p_j = ∂p/∂g̃ ∇g̃_j + ∂p/∂A ∇A_j."""
        n = st.n_slave
        K_uu = super().tangent(st, weight, first)
        law = st.law
        act = law.active * weight
        T = assembly.test_rows(st)                                   # (n, n_test)
        Gp = assembly.pressure_rows(st, law.dp_dg * act, law.dp_dA * act)   # (n, n_test)
        s = self.scale * weight
        lam_n = 2 * np.arange(n)
        K_ul = sp.csr_matrix(-(T.T @ sp.diags(act)))                 # (n_test, n) → λ_n cols
        E = sp.csr_matrix((np.ones(n), (lam_n, np.arange(n))), shape=(2 * n, n))
        K_lu = E @ sp.csr_matrix(sp.diags(-s) @ Gp)
        K_ll = sp.diags(np.stack([s * (1.0 - law.active), s], axis=1).ravel())
        return sp.bmat([[K_uu, K_ul @ E.T], [K_lu, K_ll]], format="coo")

    def kkt_residual(self, g: np.ndarray, A: np.ndarray, p: np.ndarray,
                     tangential=None) -> float:
        # the normal part: the friction rows C_t are solved with the rest by Newton
        return super().kkt_residual(g, A, p)


# registers "alm" and "alm-stick" (after Enforcement exists: it imports it)
from .augmented_lagrangian import AugmentedLagrangian, AugmentedLagrangianStick  # noqa: E402,F401
