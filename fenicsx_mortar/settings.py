"""Newton settings and the one table of numeric ranges that the library API and the scenes
check their numbers against.

No DOLFINx import: scenes are built and validated without it.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Literal

#: line searches of the Newton solver: PETSc's, and "l2-full" (linesearch.py)
LINE_SEARCHES = ("basic", "bt", "l2", "cp", "l2-full")
#: linear solvers (docs/scenes.md): by size ("auto", system.py resolve_linear_solver), a
#: direct factorization by name, MUMPS on the condensed system of dual multipliers, or
#: GMRES with an algebraic multigrid (PETSc's GAMG, hypre's BoomerAMG) or a geometric one
#: on the meshes the problem's was refined from
LINEAR_SOLVERS = ("auto", "mumps", "superlu_dist", "condensed-mumps", "gmres-gamg",
                  "gmres-hypre", "gmres-gmg")
#: the solvers that take multipliers through the condensed displacement system (dual
#: basis only; docs/condensation.md)
CONDENSED_SOLVERS = ("condensed-mumps", "gmres-gamg", "gmres-hypre", "gmres-gmg")


@dataclass(frozen=True)
class Range:
    """Allowed values of one number: ``low <= v <= high`` (``open_low``: ``low < v``),
    an integer if ``integer``; ``why`` explains the bounds in messages."""
    low: float
    high: float = math.inf
    integer: bool = False
    open_low: bool = False
    why: str = ""

    def rule(self) -> str:
        kind = "an integer" if self.integer else "a finite number"
        if self.high == math.inf:
            bound = f"> {self.low:g}" if self.open_low else f">= {self.low:g}"
        else:
            bound = f"in {'(' if self.open_low else '['}{self.low:g}, {self.high:g}]"
        return f"{kind} {bound}" + (f" ({self.why})" if self.why else "")

    def contains(self, value) -> bool:
        if isinstance(value, (bool, str, bytes)) or getattr(value, "ndim", 0) != 0:
            return False
        try:
            v = float(value)
        except (TypeError, ValueError):
            return False
        if not math.isfinite(v) or (self.integer and v != round(v)):
            return False
        return (v > self.low if self.open_low else v >= self.low) and v <= self.high


#: every bounded number of the API and the scenes, by name
RANGES: dict[str, Range] = {
    "atol": Range(0.0, open_low=True, why="the residual norm below which Newton stops"),
    "rtol": Range(0.0, 1.0, open_low=True, why="a relative decrease; 1: atol alone decides"),
    "max_iterations": Range(1, 1000, integer=True),
    "quadrature_degree": Range(1, 16, integer=True,
                               why="the JIT compile time grows fast with it"),
    "epsilon": Range(0.0, open_low=True, why="a pressure per unit gap"),
    "tolerance": Range(1e-14, 1e-2, why="a KKT residual relative to the pressure scale: "
                       "below 1e-14 it is round-off, above 1e-2 the pressures are not "
                       "converged"),
    "mu": Range(0.0, why="a friction coefficient"),
    "E": Range(0.0, open_low=True, why="Young's modulus"),
    "n_gauss": Range(2, 16, integer=True, why="Gauss points per mortar segment"),
    "search_radius": Range(0.0, open_low=True, why="a distance"),
    "max_augmentations": Range(0, 1000, integer=True),
    "max_cuts": Range(0, 50, integer=True,
                      why="each cut halves the increment: 2^-50 is round-off"),
    "min_increment": Range(0.0, open_low=True, why="the smallest increment a cut may give"),
    "load_steps": Range(1, 100_000, integer=True),
}


def check_number(name: str, value, key: str | None = None) -> None:
    """Raise ValueError unless ``value`` lies in ``RANGES[name]``.

    Args:
        name: The entry of :data:`RANGES`.
        value: The number to check.
        key: How the message names the argument (default: ``name``).

    Raises:
        ValueError: ``"<key> = <value>: must be <rule>"``.
    """
    r = RANGES[name]
    if not r.contains(value):
        raise ValueError(f"{key or name} = {value!r}: must be {r.rule()}")


@dataclass
class SolverSettings:
    """Newton (PETSc SNES) settings. A solve converges when the residual norm is below
    ``atol`` and below ``rtol`` times the first residual of the load step (and, with
    contact, every pair's own criterion holds: the ALM's KKT residual below its tolerance).

    Attributes:
        atol: Absolute tolerance of the residual norm (force units).
        rtol: Relative decrease of the residual norm required as well.
        max_iterations: Newton iterations per solve.
        line_search: ``"l2-full"`` (full step when it divides the residual by 4, else
            PETSc's ``l2`` step), or a PETSc line search (``"basic"``, ``"bt"``, ``"l2"``,
            ``"cp"``).
        linear_solver: ``"auto"`` (default: ``"gmres-gamg"`` from
            :data:`~.system.AUTO_AMG_DOFS` displacement dofs with dual multipliers —
            ``"gmres-gmg"`` on a mesh refined twice or more from given coarse meshes —,
            else ``"mumps"``), ``"mumps"``, ``"superlu_dist"``, ``"condensed-mumps"``,
            ``"gmres-gamg"``, ``"gmres-hypre"`` or ``"gmres-gmg"`` (LINEAR_SOLVERS; with
            multipliers the last four condense the dual ones, docs/condensation.md;
            ``"gmres-gmg"`` needs the coarse meshes, ContactProblem's ``coarse_meshes``).
        quadrature_degree: Of the bulk forms a scene builds, and of the inverted-cell check.
        petsc: More PETSc options (``-snes_*``, ``-ksp_*``, ``-pc_*``, ``-mat_*``).
    """
    atol: float = 1e-9
    rtol: float = 1e-8
    max_iterations: int = 25
    line_search: Literal["basic", "bt", "l2", "cp", "l2-full"] = "l2-full"
    linear_solver: Literal["auto", "mumps", "superlu_dist", "condensed-mumps", "gmres-gamg",
                           "gmres-hypre", "gmres-gmg"] = "auto"
    quadrature_degree: int = 2  # full Gauss integration of P1/Q1 (2x2 on quadrilaterals)
    petsc: dict[str, bool | int | float | str] = field(default_factory=dict)

    def check(self, key: str = "settings") -> SolverSettings:
        """Every field in its range or among its choices.

        Args:
            key: How messages name this object (``"solver"`` in a scene).

        Returns:
            self.

        Raises:
            ValueError: naming the field.
        """
        for name in ("atol", "rtol", "max_iterations", "quadrature_degree"):
            check_number(name, getattr(self, name), f"{key}.{name}")
        for name, choices in (("line_search", LINE_SEARCHES),
                              ("linear_solver", LINEAR_SOLVERS)):
            if getattr(self, name) not in choices:
                raise ValueError(f"{key}.{name} = {getattr(self, name)!r}: must be one of "
                                 f"{', '.join(map(repr, choices))}")
        if not isinstance(self.petsc, dict):
            raise ValueError(f"{key}.petsc = {self.petsc!r}: a dict of PETSc options")
        return self
