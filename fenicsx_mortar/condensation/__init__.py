"""Condensed dual-mortar multipliers: the Newton system over [u, λ] solved through a
displacement-only matrix (docs/condensation.md has the derivation).

The SNES still iterates on [u, λ] with the residual [R_u; C] of the saddle point's
:class:`~fenicsx_mortar.system.MultiplierSystem` — same function, same norms, same line
search — so the iterates are those of the saddle-point solve to round-off. Only the linear
solve differs: the SNES's KSP is a Python KSP (:class:`~.ksp.CondensedKSP`) that, per
Newton iteration,

1. eliminates the multipliers whose own rows are invertible (inactive nodes, the tangential
   multiplier of sliding or frictionless nodes): their columns in the u-rows are zero;
2. eliminates the others, ``H`` (active normal multipliers, sticking tangential ones: rows
   with ∂C/∂λ = 0), through one displacement row of each node, ``P`` (the node's own rows,
   where the dual basis makes the multipliers' forces nearly diagonal): with
   M = P B_H and W = M⁻¹ the condensed matrix is

       J_c = (I − B_H W P) K    on the rows outside P,   J_c = G_H on the rows P,

   G_H = ∂C_H/∂u; M is block-tridiagonal along the slave chain and W its inverse by a
   Neumann series truncated where the terms fall below round-off of the kept ones;
3. solves J_c Δu = f_c with the inner KSP (MUMPS, or a Krylov method with AMG) and
   recovers Δλ_H = W (b_P − P K Δu) and the eliminated ones from their rows.

Every rank holds the multiplier data of all slave nodes (the surfaces are 1D and gathered
anyway); each rank inserts the condensation's entries of the rows it owns.

Modules: ``elimination`` (the per-iteration algebra), ``inverses`` (the truncated
inverses and the pruning at round-off), ``pattern`` (Kc's preallocated pattern),
``system`` (the system the SNES solves: assembly, solve, recovery), ``ksp`` (the PETSc
KSP and matrix wrappers, the Eisenstat–Walker forcing).
"""
from .elimination import Elimination
from .inverses import CondensationError
from .system import CondensedSystem, condensable

__all__ = ["CondensationError", "CondensedSystem", "Elimination", "condensable"]
