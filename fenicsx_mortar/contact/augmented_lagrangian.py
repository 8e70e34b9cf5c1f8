"""The Uzawa augmented Lagrangian (docs/design.md §5): ``"alm"`` with the stick
penalty-regularized, ``"alm-stick"`` with the tangential traction augmented too. Kept
apart from :mod:`.enforcement` (the base and the other laws) as one law per module."""
from __future__ import annotations

import numpy as np

from .enforcement import Enforcement
from .friction import INACTIVE, STICK
from .registry import ENFORCEMENTS

@ENFORCEMENTS.register("alm")
class AugmentedLagrangian(Enforcement):
    """Uzawa: after each Newton solve p̂ ← p (and with friction t̂ ← t), until the KKT
    residual is below ``tolerance``; the converged answer does not depend on ε.

    Each update shrinks node j's constraint error by about k_j/(k_j + ε_j A_j) (k_j: the
    local stiffness of the bodies), so a moderate ε₀ keeps the first, hardest Newton solve
    robust and many updates would follow. Node by node, when an update gains less than a
    factor 100 (``stall``), ε_j grows ×10, up to 100 ε₀ max(1, Ā/A_j) (Ā the median nodal
    area) while the active and stick/slip sets still change between updates, up to
    300 ε₀ max(1, Ā/A_j) once an update left them as they were: a node whose support only
    partly sees the master (a slave sliding past the master's end) has a small A_j and
    needs the larger ε_j for the same rate, while round-off in ε_j g̃_j stays at the level
    of the other nodes. Measured on Cattaneo-Mindlin (docs/friction.md, "Partial slip"):
    the update of the stiffest multiplier mode gains 1/(1 + 0.09 ε_j/ε₀), one decade at
    100 ε₀ (the old cap: 15-25 updates a step), 1.4 at 300 ε₀; with 1000 ε₀ while the sets
    change B5's first step cycled to the step floor, and with 1000 ε₀ once they stay the
    Newton residual of B3 (half-rings) stalled at 2e-9, round-off in ε_j g̃_j over the
    tolerance 1e-9 (300 ε₀: the same Cattaneo-Mindlin cost). The later solves start next
    to the answer, where a stiff ε does no harm. A start stiffer than the bodies makes the
    first Newton solve fragile (Hertz at h = a/4 fails from 10 E/h): ε₀ is at most the
    pair's E/h (``start``).

    Inexact Uzawa (:meth:`update_due`): a solve stops for the update once its residual is
    below the force the update will add; only the last solve of a step, the one whose
    state holds the KKT conditions, converges by Newton's rule. Updates follow the Anderson
    extrapolation of the last ``memory`` ones (:meth:`_accelerate`).

    With friction the stick stays penalty-regularized (elastic slip t/ε_T, the moving cone
    of :mod:`.friction`): the paper's method. :class:`AugmentedLagrangianStick` augments
    the tangential traction too."""
    #: ε_j ×growth where an update gained less than 1/stall; caps in ε₀ while the active
    #: and stick/slip sets change (max_growth) and once they stay (settled_growth)
    growth, stall, max_growth, settled_growth = 10.0, 0.01, 100.0, 300.0
    #: ε_T's caps in ε₀: a node sticking that was in contact at the last step's end gets
    #: the larger (see annotate)
    tangential_growth, settled_tangential_growth = 30.0, 300.0
    #: inexact Uzawa: stop a solve at a residual below forcing × the update's force
    forcing = 1.0
    #: the Anderson extrapolation's depth (0: plain Uzawa updates)
    memory = 2
    #: whether the tangential traction has its own Uzawa multiplier t̂ (exact stick)
    augments_traction = False

    def __init__(self, epsilon: float, n_nodes: int, tolerance: float,
                 gap_resolution: float = 0.0, start: float | None = None):
        if start is not None:
            epsilon = min(epsilon, start)
        super().__init__(epsilon, n_nodes, tolerance, gap_resolution, start)
        self._last = np.full(self.epsilon.shape, np.inf)
        #: t̂, the tangential traction's Uzawa multiplier (friction only)
        self.traction = np.zeros(n_nodes)
        self._converged_traction = self.traction.copy()
        self._held = None
        #: the Anderson history: (multipliers, their update, decisions, KKT residual)
        self._history: list[tuple] = []
        #: the decisions (active, stick/slip) at the last update
        self._decision: np.ndarray | None = None
        #: ε_T's cap per node (in ε₀)
        self._tangential_cap = np.full(n_nodes, self.tangential_growth)
        #: friction statuses at the last solve, and at the last accepted step's end
        self._solve_status = np.zeros(n_nodes, dtype=np.int8)
        self._step_status = self._solve_status

    def annotate(self, st) -> None:
        super().annotate(st)
        if not self.augments_traction:
            return
        # ε_T grows with ε_j, up to tangential_growth ε₀ (30): at 100 ε₀ the semi-smooth
        # Newton of a solve flipped the slip direction of nodes at the edge of B5's stick
        # zone (the press cycled to the step floor); at 3 ε₀ the tangential updates stalled
        # (Cattaneo-Mindlin: KKT not reached in 30 augmentations). At 30 ε₀ an update gains
        # only a factor 3 (Cattaneo-Mindlin), at 300 ε₀ a factor 30: a node that sticks now
        # and was in contact at the end of the last step (no longer the closing contact of
        # B5's first step, where 300 ε₀ cycled) gets 300 ε₀ (augment)
        st.traction_multiplier = self.traction
        st.epsilon_t = np.minimum(self.epsilon, self.epsilon0 * self._tangential_cap)
        # Newton's tolerance leaves the slip uncertain by its force over ε_T,j A_j, not
        # over the normal ε_j A_j (up to 14× smaller): measured with ε_j, a node sticking at
        # 30 ε₀ under 407 ε₀ normal held the friction's KKT at 2-5e-10 over the tolerance
        # 1e-10 for 22 updates whose forces Newton could not resolve (solves of 0
        # iterations; Cattaneo-Mindlin a/10, B-spline master, dual basis: 30 updates)
        st.gap_noise = self.gap_noise(st.A, st.epsilon_t)
        # the friction statuses the last solve converged to, for the next solve's first
        # iterate only (friction.Coulomb.update)
        st.held_status, self._held = self._held, None

    def _tangential(self, p: np.ndarray, tangential) -> np.ndarray | None:
        """The friction's complementarity per node relative to the pressure scale, as
        :meth:`complementarity` (None without friction)."""
        if tangential is None or tangential.kkt is None:
            return None
        scale = p.max(initial=0.0)
        return tangential.kkt / scale if scale > 0 else tangential.kkt

    def _kkt(self, g: np.ndarray, A: np.ndarray, p: np.ndarray, tangential) -> np.ndarray:
        """Per node: the larger of the normal and the friction's complementarity."""
        c = self.complementarity(g, A, p, 0.0 if tangential is None else self.gap_noise(A))
        ct = self._tangential(p, tangential)
        return c if ct is None else np.maximum(c, ct)

    def kkt_residual(self, g: np.ndarray, A: np.ndarray, p: np.ndarray,
                     tangential=None) -> float:
        return float(self._kkt(g, A, p, tangential).max(initial=0.0))

    def update_due(self, g: np.ndarray, A: np.ndarray, p: np.ndarray, tangential,
                   fnorm: float, first: float) -> bool:
        """Inexact Uzawa: an update changes the nodal forces by (p_j − p̂_j) A_j (and
        (t_j − t̂_j) A_j), so the next solve starts with a residual of about their norm;
        converging the present solve far below it is wasted. Stop once the residual is
        below ``forcing`` times it and the KKT conditions do not hold: the update follows.
        (The step ends only after a solve converged by Newton's own rule.) The solve must
        have halved its residual: where Newton crawls (line search, an edge node's
        active flag), an update at a state no better than the last stalled the KKT
        residual (Cattaneo-Mindlin a/20, Hermite master, 'alm': 33 Newton iterations and
        22 updates in a step; with the halving 23 and 12, 17.9 → 14.6 a step)."""
        if fnorm > 0.5 * first:
            return False
        seen = A > 0
        jump = np.where(seen, (p - self.multiplier) * A, 0.0)
        if tangential is not None and self.augments_traction:
            jump = np.hypot(jump, np.where(seen, (tangential.t - self.traction) * A, 0.0))
        if fnorm > self.forcing * float(np.linalg.norm(jump)):
            return False
        return self.kkt_residual(g, A, p, tangential) > self.tolerance

    def augment(self, g: np.ndarray, A: np.ndarray, p: np.ndarray, tangential=None) -> bool:
        if tangential is not None:
            self._solve_status = tangential.status.astype(np.int8)
        c = self._kkt(g, A, p, tangential)
        if c.max(initial=0.0) <= self.tolerance:
            return False
        stick = tangential is not None and self.augments_traction
        decision = (p > 0).astype(np.int8)
        if tangential is not None:
            decision = decision + 2 * self._solve_status
        settled = self._decision is not None and np.array_equal(decision, self._decision)
        self._decision = decision
        x = np.concatenate([self.multiplier, self.traction]) if stick else self.multiplier
        gx = np.concatenate([p, tangential.t]) if stick else p
        new = self._accelerate(x, gx, decision, float(c.max()))
        n = self.multiplier.size
        self.multiplier = np.maximum(new[:n], 0.0)
        if stick:
            self.traction = new[n:].copy()
            self._held = tangential.status.copy()
            firm = (self._solve_status == STICK) & (self._step_status != INACTIVE)
            self._tangential_cap = np.where(firm, self.settled_tangential_growth,
                                            self.tangential_growth)
        seen = A > 0
        if seen.any():
            cap = (self.settled_growth if settled else self.max_growth) * self.epsilon0 \
                * np.maximum(1.0, np.median(A[seen]) / np.where(seen, A, np.inf))
            stall = (c > self.tolerance) & (c > self.stall * self._last)
            # never lowered: a cap back at 100 ε₀ when a set changed again cut ε_j ten times
            # and the KKT residual rose (plain alm, Cattaneo-Mindlin at a/20)
            grown = np.where(stall, np.maximum(np.minimum(self.epsilon * self.growth, cap),
                                               self.epsilon), self.epsilon)
            if np.any(grown > 1.5 * self.epsilon):
                self._history = []       # another map: its history does not extrapolate
            self.epsilon = grown
        self._last = c
        return True

    def _accelerate(self, x: np.ndarray, gx: np.ndarray, decision: np.ndarray,
                    kkt: float) -> np.ndarray:
        """The next multipliers from the plain update gx = G(x) (Anderson, type II, over
        the last ``memory`` updates): once the sets stay, G is an affine contraction whose
        slowest modes a few secants remove (Cattaneo-Mindlin at a/20, 30 ε₀ on the
        tangential traction: 0.9 decade an update instead of 0.6). The history restarts
        where it cannot extrapolate: a set changed, the KKT residual rose, ε jumped.

        Args:
            x: The multipliers the last solve used (p̂, with exact stick also t̂).
            gx: What the solve gave (p, t).
            decision: Per node, active and stick/slip.
            kkt: The KKT residual of the solve.

        Returns:
            The multipliers of the next solve.
        """
        h = self._history
        if (not self.memory or not h or not np.array_equal(decision, h[-1][2])
                or kkt > h[-1][3]):
            self._history = [(x.copy(), gx - x, decision, kkt)]
            return gx.copy()
        f = gx - x
        h = h[-int(self.memory):]
        dX = np.stack([x - hx for hx, _, _, _ in h], axis=1)
        dF = np.stack([f - hf for _, hf, _, _ in h], axis=1)
        gamma = np.linalg.lstsq(dF, f, rcond=None)[0]
        self._history = h + [(x.copy(), f, decision, kkt)]
        return gx - (dX + dF) @ gamma

    def begin_step(self) -> None:
        super().begin_step()
        self._last[:] = np.inf
        self._held = None
        self._history = []
        self._decision = None
        self._tangential_cap[:] = self.tangential_growth

    def accept(self) -> None:
        super().accept()
        self._converged_traction = self.traction.copy()
        self._step_status = self._solve_status.copy()

    def reject(self) -> None:
        super().reject()
        self.traction = self._converged_traction.copy()

    def state_dict(self) -> dict[str, np.ndarray]:
        # (n, 2) [p̂, t̂] like the multipliers' λ; a 1D p̂ (older checkpoints) loads too
        return {"multiplier": np.stack([self.multiplier, self.traction], axis=1)}

    def load_state_dict(self, d: dict[str, np.ndarray]) -> None:
        m = np.array(d["multiplier"], dtype=float)
        if m.ndim == 2:
            m, self.traction = m[:, 0].copy(), m[:, 1].copy()
        else:
            self.traction = np.zeros_like(m)
        super().load_state_dict({"multiplier": m})
        self._converged_traction = self.traction.copy()


@ENFORCEMENTS.register("alm-stick")
class AugmentedLagrangianStick(AugmentedLagrangian):
    """The Uzawa augmented Lagrangian with the tangential traction augmented too
    (docs/design.md §5): the friction law sees the trial t̂_j + ε_T,j g_T,j with g_T,j the
    slip of the load step, as with the multipliers of :class:`LagrangeMultipliers`, and
    t̂ ← t with p̂ ← p after each solve, so stick converges to zero slip instead of the
    elastic slip t/ε_T; the KKT residual includes the friction's. It reaches the
    multipliers' answer (with the dual basis, the same discrete one), at ~8 augmentations
    and 11-15 Newton iterations a step (docs/friction.md, "Partial slip")."""
    augments_traction = True
