"""Plane-strain constitutive laws in UFL (docs/design.md §2). One class per law.

Total Lagrangian: each law gives the first Piola–Kirchhoff stress P(F) for the residual
∫ P : ∇δu dX and the Cauchy stress σ = J⁻¹ P Fᵀ for output. The out-of-plane stretch is 1.
"""
from __future__ import annotations

import ufl


def lame(E: float, nu: float) -> tuple[float, float]:
    """(μ, λ) from Young's modulus and Poisson's ratio."""
    return E / (2.0 * (1.0 + nu)), E * nu / ((1.0 + nu) * (1.0 - 2.0 * nu))


class Law:
    name = ""

    def __init__(self, mu, lmbda):
        self.mu, self.lmbda = mu, lmbda

    def piola(self, F):
        raise NotImplementedError

    def cauchy(self, F):
        return ufl.dot(self.piola(F), F.T) / ufl.det(F)


class NeoHooke(Law):
    """ψ = μ/2 (tr C − 2) − μ ln J + λ/2 (ln J)²  →  P = μ (F − F⁻ᵀ) + λ ln J F⁻ᵀ."""
    name = "neo-hooke"

    def piola(self, F):
        Finv_T = ufl.inv(F).T
        return self.mu * (F - Finv_T) + self.lmbda * ufl.ln(ufl.det(F)) * Finv_T


class SaintVenantKirchhoff(Law):
    """S = λ tr(E) I + 2μ E, E = ½(FᵀF − I)  →  P = F S."""
    name = "svk"

    def piola(self, F):
        I = ufl.Identity(2)
        E = 0.5 * (F.T * F - I)
        return F * (self.lmbda * ufl.tr(E) * I + 2.0 * self.mu * E)


class LinearElastic(Law):
    """Small strain: σ = λ tr(ε) I + 2μ ε, ε = sym(∇u); P ≡ σ and the output is σ itself."""
    name = "linear"

    def piola(self, F):
        I = ufl.Identity(2)
        eps = ufl.sym(F - I)
        return self.lmbda * ufl.tr(eps) * I + 2.0 * self.mu * eps

    def cauchy(self, F):
        return self.piola(F)


LAWS: dict[str, type[Law]] = {c.name: c for c in (NeoHooke, SaintVenantKirchhoff, LinearElastic)}
