"""Normal-contact enforcement on nodal weighted gaps (DESIGN.md §5). One class per method.

With g̃_j the weighted gap and A_j the nodal area of slave node j (A_j > 0 only where the
node's support sees the master), the nodal pressure is

    p_j = ⟨p̂_j − ε g̃_j / A_j⟩₊ ,

p̂ = 0 for penalty, the Uzawa multiplier for the augmented Lagrangian. A node is active when
its trial pressure p̂_j − ε g̃_j/A_j is ≥ 0: a closed gap (g̃ = 0) counts as active, so a body
held only by contact is not singular in the first iteration.
"""
from __future__ import annotations

import numpy as np


class Enforcement:
    name = ""

    def __init__(self, epsilon: float, n_nodes: int, tolerance: float):
        self.epsilon = float(epsilon)
        self.tolerance = tolerance
        self.multiplier = np.zeros(n_nodes)      # p̂ (zero for penalty)
        self._converged_multiplier = self.multiplier.copy()

    def trial(self, g: np.ndarray, A: np.ndarray) -> np.ndarray:
        """p̂ − ε g̃/A where the node sees the master, −inf elsewhere."""
        out = np.full(g.shape, -np.inf)
        seen = A > 0
        out[seen] = self.multiplier[seen] - self.epsilon * g[seen] / A[seen]
        return out

    def pressure(self, g: np.ndarray, A: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(p, active mask)."""
        t = self.trial(g, A)
        active = t >= 0.0
        return np.where(active, t, 0.0), active

    def kkt_residual(self, g: np.ndarray, A: np.ndarray) -> float:
        """max_j |p_j − ⟨p_j − ε g̃_j/A_j⟩₊| / max(p): the Alart–Curnier complementarity
        function at the current state, relative to the pressure scale; zero iff g ≥ 0,
        p ≥ 0 and p g = 0 hold at every node that sees the master."""
        p, _ = self.pressure(g, A)
        seen = A > 0
        if not seen.any():
            return 0.0
        c = p[seen] - np.maximum(p[seen] - self.epsilon * g[seen] / A[seen], 0.0)
        scale = max(p.max(), 1e-300)
        return float(np.abs(c).max() / scale) if p.max() > 0 else float(np.abs(c).max())

    def augment(self, g: np.ndarray, A: np.ndarray) -> bool:
        """Between converged Newton solves; True when another solve is needed."""
        return False

    def accept(self) -> None:
        self._converged_multiplier = self.multiplier.copy()

    def reject(self) -> None:
        self.multiplier = self._converged_multiplier.copy()


class Penalty(Enforcement):
    """p_j = ε ⟨−g̃_j/A_j⟩₊ : the answer depends on ε (penetration ~ p/ε)."""
    name = "penalty"


class AugmentedLagrangian(Enforcement):
    """Uzawa: after each converged Newton solve p̂ ← p, until the KKT residual is below
    ``tolerance``; the converged answer does not depend on ε.

    Each update shrinks the constraint error by about k/(k + ε) (k: the local stiffness of
    the bodies), so a moderate ε keeps the first, hardest Newton solve robust and many
    updates would follow; when an update gains less than a factor 10, ε grows ×10 (up to
    100 ε₀, where round-off in the gaps starts to show in the residual): the later solves
    start next to the answer, where a stiff ε does no harm."""
    name = "alm"
    growth, max_growth = 10.0, 100.0

    def __init__(self, epsilon: float, n_nodes: int, tolerance: float):
        super().__init__(epsilon, n_nodes, tolerance)
        self.epsilon0 = self.epsilon
        self._last_kkt = np.inf

    def augment(self, g: np.ndarray, A: np.ndarray) -> bool:
        kkt = self.kkt_residual(g, A)
        if kkt <= self.tolerance:
            return False
        self.multiplier, _ = self.pressure(g, A)
        if kkt > 0.1 * self._last_kkt:
            self.epsilon = min(self.epsilon * self.growth, self.max_growth * self.epsilon0)
        self._last_kkt = kkt
        return True

    def accept(self) -> None:
        super().accept()
        self.epsilon, self._last_kkt = self.epsilon0, np.inf

    def reject(self) -> None:
        super().reject()
        self.epsilon, self._last_kkt = self.epsilon0, np.inf


ENFORCEMENTS = {c.name: c for c in (Penalty, AugmentedLagrangian)}
